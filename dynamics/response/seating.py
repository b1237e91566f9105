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

Where rigid seating does not hold, the verdict names the model that should run instead: seating
through a tooth contact stiffness (dynamics.models.machine.MachineOnWheels.tooth_stiffness_N_per_m,
each seated link held to its wheel's seat by a spring). That model is built and verified between seat
changes (tests/test_tooth_stiffness.py) but its seat change and the compiled step are not, so the run
does not switch to it: it says so (`instead`) and the report shows the verdict as a warning.
"""

from __future__ import annotations

from dataclasses import dataclass

RIGID_SEATING_AT_REST = 1e-3

RIGID = "rigid seating"
TOOTH_STIFFNESS = (
    "seating through a tooth contact stiffness (a spring from each seated link to its seat, so the arriving "
    "link seats where it is); built as a model, not yet run by the pipeline"
)


@dataclass(frozen=True)
class SeatingValidity:
    """Whether the seating model holds for one scenario, and the numbers it was decided on (SI)."""

    model: str  # the seating model that ran
    valid: bool
    reason: str  # words for the report; no numbers, so equal reasons group
    snap_J: float  # the seat change's change of stored energy not taken by the seating impacts, per index
    cam_speed_fraction: float  # |z'| at the seat change over the window's max |z'|
    cam_acceleration_fraction: float  # |z''| at the seat change over the window's max |z''|
    instead: str | None  # the model the run should use where this one does not hold (None: it holds)
    threshold: float = RIGID_SEATING_AT_REST


def seat_snap_J(seating) -> float:
    """The transfer's change of stored energy plus the impacts' losses: what rigid seating's move of
    the arriving link (and, on a held sprocket, the cam's impulse) adds."""
    return float(seating.transfer_energy_change_J + sum(seating.impact_energy_J))


def rigid_seating_validity(seating, peak_speed_m_s: float, peak_acceleration_m_s2: float) -> SeatingValidity:
    """`seating`: a dynamics.solvers.machine_verlet.Seating (the cam's speed and acceleration at the
    seat change included); the peaks of the cam over the window."""
    speed = abs(seating.cam_speed_m_s) / peak_speed_m_s if peak_speed_m_s > 0 else 0.0
    accel = abs(seating.cam_acceleration_m_s2) / peak_acceleration_m_s2 if peak_acceleration_m_s2 > 0 else 0.0
    valid = max(speed, accel) <= RIGID_SEATING_AT_REST
    reason = (
        "the seats change with the cam at rest (the dwell): the arriving link is moved by the residual vibration's stretch only"
        if valid
        else "the seats change inside the index, with the cam moving: rigid seating moves the arriving link "
        "against the strands' inertial stretch, which a real sprocket does not (a tooth contact stiffness would "
        "let it seat where it is)"
    )
    instead = None if valid else TOOTH_STIFFNESS
    return SeatingValidity(RIGID, valid, reason, seat_snap_J(seating), float(speed), float(accel), instead)
