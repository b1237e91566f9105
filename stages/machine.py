"""The machine a run's chain runs on (issue #22): the run's drive and wheel settings as the dynamics'
`MachineLayout`, and what the outputs say about it (which parts ran, the stations as places on the
machine, the seat changes of an index).

The wheels need the chain's pitch, which is the link's and comes from the FEA stage
(`MaterialFea.pitch_m`, measured on the part). The settings therefore hold only what does not depend
on the part (teeth, seated links, drive stiffness, inertias or None for the default of the wheel's
own size), and the layout is built where the chain is simulated, from the settings and that pitch
(`machine_layout`, called by `stages.chain.chain_scene`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol

from settings import RunConfig

if TYPE_CHECKING:
    from dynamics.models.chain import ChainModel
    from dynamics.models.layout import MachineLayout
    from dynamics.models.machine import MachineOnWheels
    from dynamics.models.wheels import Wheel
    from dynamics.response.seating import SeatingValidity
    from dynamics.scene import Scene

WHEEL_NAMES = ("sprocket", "idler")  # in dynamics.models.machine.MachineOnWheels.wheel_ends order


def machine_layout(cfg: RunConfig, pitch_m: float) -> MachineLayout:
    """The run's drive and wheels on a chain of pitch `pitch_m` (the settings are checked already)."""
    from dynamics.models.layout import LINK_DRIVE, MachineLayout

    if cfg.machine_drive == "link":
        return LINK_DRIVE
    phase = cfg.tooth_phase
    sprocket = _wheel(cfg.sprocket_teeth, pitch_m, cfg.sprocket_wrap_links, cfg.sprocket_inertia_kg_m2, phase)
    idler = None
    if cfg.idler_wrap_links_used > 0:
        idler = _wheel(cfg.idler_teeth_used, pitch_m, cfg.idler_wrap_links_used, cfg.idler_inertia_kg_m2, phase)
    k_t = cfg.tooth_stiffness_N_per_m  # None (auto): rigid where it holds (`seating_that_runs` else)
    return MachineLayout(
        "wheels",
        sprocket,
        idler,
        cfg.drive_stiffness_N_m_per_rad,
        cfg.polygonal_action,
        float("inf") if k_t is None else float(k_t),
    )


def switches_to_tooth_model(cfg: RunConfig, scene: Scene, validity: SeatingValidity) -> bool:
    """Whether the run leaves rigid seating for the tooth contact stiffness (--tooth-stiffness auto, the
    default): where rigid seating does not hold for it and the tooth model carries the scene (wheels
    with inertia; dynamics.models.machine), at any length (above DENSE_LINK_LIMIT links on the O(N)
    damping with the wheels in its block, dynamics.models.machine_damping)."""
    if cfg.tooth_stiffness_N_per_m is not None or validity.valid or not scene.layout.on_wheels:
        return False
    wheels = (scene.layout.sprocket, scene.layout.idler)
    return all(w is None or w.inertia_kg_m2 > 0 for w in wheels)


def seating_that_runs(
    cfg: RunConfig, scene: Scene, model: ChainModel, cam, t_s
) -> tuple[Scene, SeatingValidity | None]:
    """(the scene to simulate, rigid seating's verdict where the run leaves it for the tooth model, else
    None), decided before simulating: rigid seating's verdict depends only on the cam's state at the
    seat change's instant against its peaks over the window `t_s` (`rigid_seating_before_run`), so a
    scenario that switches (--tooth-stiffness auto) is simulated once, with the teeth."""
    if cfg.tooth_stiffness_N_per_m is not None or not scene.layout.on_wheels:
        return scene, None
    rigid = rigid_seating_before_run(scene_machine(scene, model), cam, t_s)
    if not switches_to_tooth_model(cfg, scene, rigid):
        return scene, None
    return tooth_model_scene(scene), rigid


def rigid_seating_before_run(machine: MachineOnWheels, cam, t_s) -> SeatingValidity:
    """Rigid seating's verdict on `machine` from its layout and the cam alone (dynamics.response.seating):
    the cam's speed and acceleration where its lift since the dwell reaches the seat change's
    (MachineOnWheels.seat_change_lift_m, located as the compiled step locates it:
    dynamics.solvers.machine_ivp.cam_seat_change_s; 0 at the dwell) against their peaks at the
    output times `t_s`. The run records the same two fractions; the snap needs the rigid run, which
    this verdict avoids: its snap_J is None."""
    import numpy as np

    from dynamics.response.seating import rigid_seating_verdict
    from dynamics.solvers.machine_ivp import cam_seat_change_s

    _, speeds, accelerations, _ = cam.svaj(np.asarray(t_s, dtype=float))
    peaks = float(np.max(np.abs(speeds))), float(np.max(np.abs(accelerations)))
    lift = machine.seat_change_lift_m
    if lift is None:  # at the dwell, where every cam law is at rest
        return rigid_seating_verdict(0.0, 0.0, *peaks, None)
    t_seat = cam_seat_change_s(cam, cam.period_s, lift)
    _, speed, acceleration, _ = (float(x[0]) for x in cam.svaj(np.array([t_seat])))
    return rigid_seating_verdict(speed, acceleration, *peaks, None)


def tooth_model_scene(scene: Scene) -> Scene:
    """The scene with its wheels seating through the default tooth contact stiffness
    (dynamics.models.wheels.DEFAULT_TOOTH_STIFFNESS_N_PER_M)."""
    from dynamics.models.wheels import DEFAULT_TOOTH_STIFFNESS_N_PER_M

    return replace(scene, layout=replace(scene.layout, tooth_stiffness_N_per_m=DEFAULT_TOOTH_STIFFNESS_N_PER_M))


def _wheel(teeth: int, pitch_m: float, wrap: int, inertia_kg_m2: float | None, tooth_phase: float) -> Wheel:
    """A wheel on the chain's pitch; no inertia given: the default wheel of its own pitch radius."""
    from dynamics.models.wheels import Wheel, default_wheel_inertia_kg_m2

    inertia = default_wheel_inertia_kg_m2(pitch_m, teeth) if inertia_kg_m2 is None else inertia_kg_m2
    return Wheel(int(teeth), pitch_m, int(wrap), inertia, tooth_phase)


def scene_machine(scene: Scene, model: ChainModel) -> MachineOnWheels:
    """The machine of one material's chain in a scene. Its places, matrices and wheels do not depend
    on the guide's friction, which the linear machine model refuses: it is built without it."""
    return scene.layout.machine(replace(model, friction_coefficient=0.0), scene.tensioner)


@dataclass(frozen=True)
class WheelParts:
    """One wheel as it ran (SI)."""

    teeth: int
    pitch_radius_m: float  # R = p / (2 sin(pi / z))
    feed_radius_m: float  # R_m = p z / (2 pi)
    wrap_links: int
    inertia_kg_m2: float


@dataclass(frozen=True)
class MachineParts:
    """Which parts of the machine ran for one material's chain, and where its stations are."""

    drive: str  # "link" (link 1 driven through k_d) or "wheels"
    wheels: dict[str, WheelParts]  # "sprocket", "idler" (no idler wheel: today's idler point)
    drive_stiffness_N_m_per_rad: float | None  # k_theta, inf: the sprocket held to the cam; None: link drive
    polygonal_action: bool  # the chordal feed ran
    idler_carriage: bool  # the idler sits on the tensioner's carriage (else a fixed axle)
    stations: dict[str, int]  # 1-based link at each station (the link at that place at the start of an index)


def machine_parts(scene: Scene, model: ChainModel) -> MachineParts:
    from dynamics.response.metrics import station_links

    carriage = scene.tensioner is not None
    if not scene.layout.on_wheels:
        return MachineParts("link", {}, None, False, carriage, station_links(model.n_links))
    machine = scene_machine(scene, model)
    wheels = {
        name: WheelParts(w.teeth, w.pitch_radius_m, w.feed_radius_m, w.wrap_links, w.inertia_kg_m2)
        for name, w in zip(WHEEL_NAMES, (end.wheel for end in machine.wheel_ends))
    }
    return MachineParts(
        "wheels",
        wheels,
        machine.drive_stiffness_N_m_per_rad,
        machine.polygonal,
        carriage,
        {name: link + 1 for name, link in machine.stations().items()},
    )


class SeatChanges(Protocol):
    """What the dynamics report of the seat changes of an index (at its end; inside it at a tooth phase
    other than 0), per wheel in `wheel_ends` order (dynamics.solvers.machine_verlet.Seating, in
    `ContactSummary.seating`)."""

    speed_m_s: tuple[float, ...]
    impact_energy_J: tuple[float, ...]
    transfer_energy_change_J: float
    cam_speed_m_s: float  # the cam at the seat change (0 at the dwell)
    cam_acceleration_m_s2: float


@dataclass(frozen=True)
class WheelSeating:
    """The link that seats on a wheel in an index (at its end at tooth phase 0)."""

    speed_m_s: float  # |(y'_in + z') - c (u' + z')|: its speed along the strand relative to its tooth
    impact_energy_J: float  # the kinetic energy its plastic seating impact takes


@dataclass(frozen=True)
class MachineCycle:
    """The seat changes at the end of a scenario's last index on the wheels, and whether the seating
    model holds for them (dynamics.response.seating)."""

    frame: str | None  # "relabelled": the periodic steady state as the machine runs; None: from rest
    seating: dict[str, WheelSeating]  # per wheel, as in MachineParts.wheels
    transfer_energy_change_J: float  # stored energy after the seat changes minus before (all wheels)
    seating_validity: SeatingValidity


def machine_cycle(
    changes: SeatChanges,
    steady_state: bool,
    peak_speed_m_s: float,
    peak_acceleration_m_s2: float,
    layout: MachineLayout | None = None,
    switched_from: SeatingValidity | None = None,
) -> MachineCycle:
    """`peak_*`: the cam's over the scenario's window (the scale of the cam's state at the seat change);
    `layout` the one that ran (its seating; None: rigid seating), `switched_from` rigid seating's
    verdict where the run left it for the tooth model."""
    from dynamics.response.seating import rigid_seating_validity, tooth_seating_validity

    seating = {
        name: WheelSeating(float(speed), float(energy))
        for name, speed, energy in zip(WHEEL_NAMES, changes.speed_m_s, changes.impact_energy_J)
    }
    return MachineCycle(
        "relabelled" if steady_state else None,
        seating,
        float(changes.transfer_energy_change_J),
        rigid_seating_validity(changes, peak_speed_m_s, peak_acceleration_m_s2)
        if layout is None or layout.rigid_seating
        else tooth_seating_validity(
            changes, peak_speed_m_s, peak_acceleration_m_s2, layout.tooth_stiffness_N_per_m, switched_from
        ),
    )
