"""The settings of one design run: every default, the unit conversions and the checks.

`RunConfig()` is the default run; `pipeline.py` maps its flags onto these fields, `python -m study`
starts each design point from `RunConfig()`, and both check values against `LIMITS` (one table of
allowed ranges, SI). Fields are SI; the command line takes some lengths in mm (`mm_to_m`).
Defaults that belong to a physical model stay with it and are read from there (the pin clearance,
the damping ratio and the preload from dynamics.options, the hardware and nest masses from geometry.dimensions), through
`default_factory`, so that reading the settings does not import numpy or gmsh.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from settings.registries import DEFAULT_DRIVE, DEFAULT_MATERIALS, DEFAULT_STATION, cam_ids

if TYPE_CHECKING:  # importing geometry pulls in gmsh, which reading settings does not need
    from geometry.assembly import LinkSource
    from geometry.dimensions import LinkDimensions

MM_PER_M = 1000.0


class SettingsError(ValueError):
    """A setting that cannot be used; the one-line message names the option, what was expected
    and what was given."""


def mm_to_m(value_mm: float) -> float:
    return value_mm / MM_PER_M


def m_to_mm(value_m: float) -> float:
    return value_m * MM_PER_M


def _model_default(module: str, name: str):
    """A default_factory reading the constant `name` from `module` when a RunConfig is made, not when
    the settings are imported (so that reading them does not import numpy or gmsh): the default
    stays written once, with its model."""

    def read():
        return getattr(importlib.import_module(module), name)

    return read


def _default_cache_dir() -> Path:
    from fem.cache import default_cache_dir

    return default_cache_dir()


@dataclass(frozen=True)
class RunConfig:
    """One run's settings (SI). `RunConfig()` is the default run."""

    geometry: Path | None = None  # STEP file of one link; None: the built-in parametric link
    materials: tuple[str, ...] = DEFAULT_MATERIALS
    materials_file: Path | None = None  # extra user materials (TOML)
    links: int = 85
    rpm: float = 180.0
    cams: tuple[str, ...] = field(default_factory=cam_ids)  # every registered law without a dwell jump
    friction: float = 0.35  # Coulomb coefficient between links and guide
    damping: float = field(
        default_factory=_model_default("dynamics.options", "DEFAULT_DAMPING_RATIO")
    )  # modal ratio of every chain mode
    preload_N: float = field(
        default_factory=_model_default("dynamics.options", "DEFAULT_PRELOAD_N")
    )  # the idler tensioner's static tension
    solver: str = "exact"
    preset: str | None = None
    out: Path = Path("results")
    images: bool = True
    stress_beside: bool = True  # FEA stress study and images in a process beside the dynamics (pipeline.py)
    # a long chain's scenarios (material x cam law) in worker processes, one per core (stages.chain)
    scenario_workers: bool = True
    quiet: bool = False
    mesh_size_m: float | None = None  # finest FEA level; None: chosen for < 1 % error in k
    order: int = 2
    max_memory_gb: float = field(
        default_factory=_model_default("fem.budget", "DEFAULT_MAX_MEMORY_GB")
    )  # the FEA solves' memory budget
    # --tolerance: the finest FEA level's size (fem.adaptive.DEFAULT_MAX_DOFS, which imports the solvers)
    max_fea_dofs: int = 400_000
    hardware_mass_kg: float = field(default_factory=_model_default("geometry.dimensions", "DEFAULT_HARDWARE_MASS_KG"))
    nest_mass_kg: float = field(default_factory=_model_default("geometry.dimensions", "NEST_MASS_KG"))
    cache_dir: Path = field(default_factory=_default_cache_dir)
    steady_state: bool = True  # periodic steady state of continuous indexing (False: from rest)
    samples_per_degree: int = 4
    tolerance: float | None = None  # relative tolerance on the metrics (None: fixed settings)
    rpm_sweep: str | None = None  # "FROM:TO:STEP" rev/min
    settling_band_m: float = 0.0005
    station: str | None = None  # one accelerometer station only (None: every link)
    link_source: LinkSource | None = None  # --geometry with --bores/--pitch/--bore-radius/--body
    hardware_material: str | None = None  # --hardware-material: ids for the STEP file's hardware solids
    hardware_from_step: bool = False  # --hardware-from-step: hardware mass from those solids
    # the chain model (issue #11): see dynamics.scene
    model: str = "auto"
    pin_clearance_m: float = field(
        default_factory=_model_default("dynamics.options", "DEFAULT_PIN_CLEARANCE_M")
    )  # inf: a chain that only pulls
    span_damping: str = "global"
    rayleigh: tuple[float, float] | None = None  # (alpha 1/s, beta s) instead of the modal damping
    tensioner_rate_N_per_m: float | None = None
    tensioner_mass_kg: float | None = None
    tensioner_damping_N_s_per_m: float | None = None
    # the built-in link's dimensions when `geometry` is None (None: DEFAULT_LINK); a study varies them
    link: LinkDimensions | None = None
    # how the chain is driven and carried (issue #22): see dynamics.models.layout and stages.machine
    drive: str | None = None  # "wheels" or "link"; None: `machine_drive`
    sprocket_teeth: int = 12
    sprocket_wrap_links: int = 6  # the report's six links seated on the drive sprocket
    drive_stiffness_N_m_per_rad: float | None = None  # None: the report's k_d at the feed radius; inf: held
    sprocket_inertia_kg_m2: float | None = None  # None: dynamics.models.wheels.default_wheel_inertia_kg_m2
    idler_teeth: int | None = None  # None: the sprocket's
    idler_wrap_links: int | None = None  # None: the sprocket's; 0: today's idler, a point inside a span
    idler_inertia_kg_m2: float | None = None  # None: the default wheel inertia at the idler's pitch radius
    polygonal_action: bool = True
    tooth_phase: float = 0.0  # fraction of a tooth at the dwell; 0: a pin seats at the dwell
    # seating: None: rigid seating where it holds for the run, else (dynamics.response.seating) the tooth
    # contact stiffness dynamics.models.wheels.DEFAULT_TOOTH_STIFFNESS_N_PER_M; inf: rigid seating always;
    # a value: seating through that tooth contact stiffness always
    tooth_stiffness_N_per_m: float | None = None

    @property
    def focus_station(self) -> str:
        """Where tables, rankings, plots and the speed sweep look: --station, else the tight side."""
        return self.station or DEFAULT_STATION

    @property
    def machine_drive(self) -> str:
        """--drive, else the link drive for the mqp2012 preset (the report's model), else DEFAULT_DRIVE."""
        if self.drive is not None:
            return self.drive
        return "link" if self.preset == "mqp2012" else DEFAULT_DRIVE

    @property
    def idler_teeth_used(self) -> int:
        return self.sprocket_teeth if self.idler_teeth is None else self.idler_teeth

    @property
    def idler_wrap_links_used(self) -> int:
        return self.sprocket_wrap_links if self.idler_wrap_links is None else self.idler_wrap_links


@dataclass(frozen=True)
class Bounds:
    """An allowed range: above `lower` (or at it when lower_included), below `upper` (or at it)."""

    lower: float = 0.0
    lower_included: bool = False
    upper: float = math.inf
    upper_included: bool = True

    def accepts(self, value: float) -> bool:
        above = value >= self.lower if self.lower_included else value > self.lower
        below = value <= self.upper if self.upper_included else value < self.upper
        return above and below

    def expected(self, per_si: float = 1.0) -> str:
        low = f"{'>=' if self.lower_included else '>'} {self.lower * per_si:g}"
        if self.upper == math.inf:
            return low
        return f"{low} and {'<=' if self.upper_included else '<'} {self.upper * per_si:g}"


MAX_LINKS = 10_000  # chains above dynamics.models.reduction.DENSE_LINK_LIMIT links are solved in their lowest modes


@dataclass(frozen=True)
class Limit:
    """The allowed values of one numeric RunConfig field and the option that sets it."""

    option: str  # the command-line option, named in the error
    what: str  # what the value is, for the error: "a cam speed"
    bounds: Bounds
    unit: str = ""  # the option's unit
    per_si: float = 1.0  # option units per SI unit (MM_PER_M for an option in mm)
    whole: bool = False  # a whole number
    finite: bool = True  # inf is refused (the pin clearance takes it: a chain that can only pull)

    def problem(self, value) -> str | None:
        """Why `value` (SI) is refused, one line naming the option; None when it is allowed."""
        shown = value * self.per_si
        ok = (
            isinstance(value, (int, float))
            and not isinstance(value, bool)
            and not math.isnan(value)
            and self.bounds.accepts(value)
            and (math.isfinite(value) or not self.finite)
            and (not self.whole or float(value).is_integer())
        )
        if ok:
            return None
        unit = f" {self.unit}" if self.unit else ""
        inf = "" if self.finite else " or inf"
        return f"{self.option}: expected {self.what} {self.bounds.expected(self.per_si)}{unit}{inf}, got {shown:g}"


AT_LEAST_ZERO = Bounds(0.0, lower_included=True)
ABOVE_ZERO = Bounds(0.0)
# The smallest memory budget: the FEA memory model's fixed base (fem.budget.BASE_BYTES is this),
# what a stiffness study takes before its first unknown.
MIN_MAX_MEMORY_GB = 0.55

#: The numeric fields' allowed values (a field set to None, where allowed, is not checked).
LIMITS: dict[str, Limit] = {
    "links": Limit("--links", "a whole number of links", Bounds(2, True, MAX_LINKS), whole=True),
    "rpm": Limit("--rpm", "a cam speed", ABOVE_ZERO, "rev/min"),
    "friction": Limit("--friction", "a friction coefficient", Bounds(0.0, True, 1.0)),
    "damping": Limit("--damping", "a damping ratio", Bounds(0.0, True, 1.0, upper_included=False)),
    "preload_N": Limit("--preload", "a tension", AT_LEAST_ZERO, "N"),
    "hardware_mass_kg": Limit("--hardware-mass", "a mass", AT_LEAST_ZERO, "kg"),
    "nest_mass_kg": Limit("--nest-mass", "a mass", AT_LEAST_ZERO, "kg"),
    "max_memory_gb": Limit("--max-memory", "a memory budget", Bounds(MIN_MAX_MEMORY_GB), "GB"),
    "max_fea_dofs": Limit("--max-fea-dofs", "a whole number of DOFs", Bounds(1, True), whole=True),
    "mesh_size_m": Limit("--mesh-size", "an element size", ABOVE_ZERO, "mm", MM_PER_M),
    "samples_per_degree": Limit("--samples-per-degree", "a whole number", Bounds(1, True), whole=True),
    "tolerance": Limit("--tolerance", "a relative tolerance (e.g. 0.01)", Bounds(0.0, False, 1.0, False)),
    "settling_band_m": Limit("--settling-band", "a band", ABOVE_ZERO, "mm", MM_PER_M),
    "pin_clearance_m": Limit("--pin-clearance", "a free play", AT_LEAST_ZERO, "mm", MM_PER_M, finite=False),
    "tensioner_rate_N_per_m": Limit("--tensioner-rate", "a finite spring rate", AT_LEAST_ZERO, "N/m"),
    "tensioner_mass_kg": Limit("--tensioner-mass", "a finite mass", ABOVE_ZERO, "kg"),
    "tensioner_damping_N_s_per_m": Limit("--tensioner-damping", "a finite damping", AT_LEAST_ZERO, "N*s/m"),
    "sprocket_teeth": Limit("--sprocket-teeth", "a whole number of teeth", Bounds(3, True), whole=True),
    "sprocket_wrap_links": Limit(
        "--sprocket-wrap-links", "a whole number of seated links", Bounds(1, True), whole=True
    ),
    "drive_stiffness_N_m_per_rad": Limit(
        "--drive-stiffness", "a torsional stiffness", ABOVE_ZERO, "N*m/rad", finite=False
    ),
    "sprocket_inertia_kg_m2": Limit("--sprocket-inertia", "a finite inertia", AT_LEAST_ZERO, "kg*m^2"),
    "idler_teeth": Limit("--idler-teeth", "a whole number of teeth", Bounds(3, True), whole=True),
    "idler_wrap_links": Limit("--idler-wrap-links", "a whole number of seated links", AT_LEAST_ZERO, whole=True),
    "idler_inertia_kg_m2": Limit("--idler-inertia", "a finite inertia", AT_LEAST_ZERO, "kg*m^2"),
    "tooth_phase": Limit("--tooth-phase", "a fraction of a tooth", Bounds(0.0, True, 1.0, False)),
    "tooth_stiffness_N_per_m": Limit(
        "--tooth-stiffness", "a tooth contact stiffness (or rigid, auto)", ABOVE_ZERO, "N/m", finite=False
    ),
}
