"""Whether rigid seating holds for a run on the wheels (issue #22), as data.

Rigid seating (dynamics.models.machine) puts the link that seats exactly at its seat: it moves it by
its span's stretch e2, which hands that stretch to the span behind it and changes the spans' elastic
energy by k e1 e2 (the "snap", dynamics.solvers.machine_steady.transfer). A real sprocket does not
move the roller: it seats where it is and the tooth flank takes the tension over. The snap is small
where the seat change meets the chain at rest, at the dwell (tooth phase 0), where the stretches are
the residual vibration's; inside the index they carry the strands' inertial tension and the snap
is the run's largest effect of the tooth phase (docs/physics.md, "The tooth phase on the default
scene": 3-17 J per index against 0.3 J at phase 0, peaks up to x2).

The criterion is computed from the run: the cam's speed and acceleration at the seat change's
instant, as fractions of their peaks over the window. Rigid seating holds where both are at most
RIGID_SEATING_AT_REST (the seat change meets the cam at rest to the project's default accuracy,
1e-3): at the dwell both are exactly 0; at any tooth phase in (0, 1) other than within 1e-3 of a
dwell they are not (tooth phase 0.25: the cam at 0.75 of a pitch, decelerating, speed ~0.5 of its
peak). The snap itself is recorded beside it (J per index), so the report shows its size.

Where rigid seating does not hold, the verdict names the model that holds there: seating through a
tooth contact stiffness (dynamics.models.machine.MachineOnWheels.tooth_stiffness_N_per_m, each seated
link held to its wheel's seat by a spring, the arriving link seating where it is and settling into its
gap over one index: dynamics.solvers.tooth_transfer). The run switches to it with the default k_t
(stages.machine.switches_to_tooth_model, `--tooth-stiffness auto`, the default) and says so: the
verdict of the model that ran is `tooth_seating_validity`'s, with rigid seating's verdict it left
(`switched_from`); `--tooth-stiffness rigid` keeps rigid seating and its warning.
"""

from __future__ import annotations

from dataclasses import dataclass

RIGID_SEATING_AT_REST = 1e-3

RIGID = "rigid seating"
TOOTH_STIFFNESS_MODEL = "seating through a tooth contact stiffness"
TOOTH_STIFFNESS = (
    "seating through a tooth contact stiffness (a spring from each seated link to its seat, so the arriving "
    "link seats where it is)"
)


@dataclass(frozen=True)
class SeatingValidity:
    """Whether the seating model holds for one scenario, and the numbers it was decided on (SI)."""

    model: str  # the seating model that ran
    valid: bool
    reason: str  # words for the report; no numbers, so equal reasons group
    # the seat change's change of stored energy not taken by the seating impacts, per index (None: the
    # verdict was decided before the run, which did not run this model: stages.machine.rigid_seating_before_run)
    snap_J: float | None
    cam_speed_fraction: float  # |z'| at the seat change over the window's max |z'|
    cam_acceleration_fraction: float  # |z''| at the seat change over the window's max |z''|
    instead: str | None  # the model the run should use where this one does not hold (None: it holds)
    threshold: float = RIGID_SEATING_AT_REST
    tooth_stiffness_N_per_m: float | None = None  # the tooth model's k_t (None: rigid seating ran)
    switched_from: SeatingValidity | None = None  # rigid seating's verdict where the run left it for this model


def seat_snap_J(seating) -> float:
    """The transfer's change of stored energy plus the impacts' losses: what rigid seating's move of
    the arriving link (and, on a held sprocket, the cam's impulse) adds."""
    return float(seating.transfer_energy_change_J + sum(seating.impact_energy_J))


def rigid_seating_validity(seating, peak_speed_m_s: float, peak_acceleration_m_s2: float) -> SeatingValidity:
    """`seating`: a dynamics.solvers.machine_verlet.Seating (the cam's speed and acceleration at the
    seat change included); the peaks of the cam over the window."""
    return rigid_seating_verdict(
        seating.cam_speed_m_s,
        seating.cam_acceleration_m_s2,
        peak_speed_m_s,
        peak_acceleration_m_s2,
        seat_snap_J(seating),
    )


def rigid_seating_verdict(
    cam_speed_m_s: float,
    cam_acceleration_m_s2: float,
    peak_speed_m_s: float,
    peak_acceleration_m_s2: float,
    snap_J: float | None,
) -> SeatingValidity:
    """Rigid seating's verdict from the cam's speed and acceleration at the seat change and their peaks
    over the window; `snap_J` as SeatingValidity's."""
    speed = abs(cam_speed_m_s) / peak_speed_m_s if peak_speed_m_s > 0 else 0.0
    accel = abs(cam_acceleration_m_s2) / peak_acceleration_m_s2 if peak_acceleration_m_s2 > 0 else 0.0
    valid = max(speed, accel) <= RIGID_SEATING_AT_REST
    reason = (
        "the seats change with the cam at rest (the dwell): the arriving link is moved by the residual vibration's stretch only"
        if valid
        else "the seats change inside the index, with the cam moving: rigid seating moves the arriving link "
        "against the strands' inertial stretch, which a real sprocket does not (a tooth contact stiffness would "
        "let it seat where it is)"
    )
    instead = None if valid else TOOTH_STIFFNESS
    return SeatingValidity(RIGID, valid, reason, snap_J, float(speed), float(accel), instead)


def tooth_seating_validity(
    seating,
    peak_speed_m_s: float,
    peak_acceleration_m_s2: float,
    tooth_stiffness_N_per_m: float,
    switched_from: SeatingValidity | None = None,
) -> SeatingValidity:
    """The verdict on seating through a tooth contact stiffness: it holds at any instant of the seat
    change (the arriving link seats where it is, no snap); the cam's state there recorded as for rigid
    seating. `switched_from`: rigid seating's verdict where the run left it for this model."""
    speed = abs(seating.cam_speed_m_s) / peak_speed_m_s if peak_speed_m_s > 0 else 0.0
    accel = abs(seating.cam_acceleration_m_s2) / peak_acceleration_m_s2 if peak_acceleration_m_s2 > 0 else 0.0
    reason = (
        "the arriving link seats where it is and settles into its tooth gap over one index through the tooth spring"
    )
    if switched_from is not None:
        reason += "; the run switched to it from rigid seating, which does not hold here: " + switched_from.reason
    return SeatingValidity(
        TOOTH_STIFFNESS_MODEL,
        True,
        reason,
        seat_snap_J(seating),
        float(speed),
        float(accel),
        None,
        tooth_stiffness_N_per_m=float(tooth_stiffness_N_per_m),
        switched_from=switched_from,
    )
