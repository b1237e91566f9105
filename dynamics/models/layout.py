"""How a run's chain is driven and carried: the report's single-point drive or the machine on its
wheels (issue #22). The run's settings map onto a `MachineLayout`; dynamics builds the machine of one
material's chain from it (`machine`), so the wheels are described once for every chain model."""

from __future__ import annotations

from dataclasses import dataclass

from dynamics.models.chain import ChainModel
from dynamics.models.clearance import Tensioner
from dynamics.models.machine import DRIVES, MachineOnWheels
from dynamics.models.wheels import Wheel


@dataclass(frozen=True)
class MachineLayout:
    """drive "link": link 1 driven through k_d (the report's model); "wheels": the drive sprocket's
    seated links, its compliance and inertia, the idler wheel and the polygonal feed, each switchable
    (dynamics.models.machine). The wheels' pitch is the chain's, so a layout is built per run and the
    machine per material (`machine`)."""

    drive: str = "link"
    sprocket: Wheel | None = None
    idler: Wheel | None = None  # None: the idler is a point inside a span (today's)
    drive_torsional_stiffness_N_m_per_rad: float | None = None  # None: the report's k_d at R_m; inf: held
    polygonal: bool = True
    tooth_stiffness_N_per_m: float = float("inf")  # inf: rigid seating (dynamics.models.machine)

    def __post_init__(self) -> None:
        if self.drive not in DRIVES:
            from dynamics.errors import DynamicsError

            raise DynamicsError(f"drive: expected one of {', '.join(DRIVES)}, got {self.drive!r} (option --drive)")

    @property
    def on_wheels(self) -> bool:
        return self.drive == "wheels"

    @property
    def rigid_seating(self) -> bool:
        """Seated links and their wheel one body (no tooth contact stiffness: inf, today's model)."""
        return self.tooth_stiffness_N_per_m == float("inf")

    def machine(self, chain: ChainModel, tensioner: Tensioner | None) -> MachineOnWheels:
        """The machine of one material's chain (checked by MachineOnWheels)."""
        return MachineOnWheels(
            chain,
            drive=self.drive,
            sprocket=self.sprocket,
            drive_torsional_stiffness_N_m_per_rad=self.drive_torsional_stiffness_N_m_per_rad,
            idler=self.idler,
            tensioner=tensioner,
            polygonal=self.polygonal,
            tooth_stiffness_N_per_m=self.tooth_stiffness_N_per_m,
        )


LINK_DRIVE = MachineLayout()
