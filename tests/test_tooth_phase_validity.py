"""Rigid seating's validity as data (issue #22; dynamics.response.seating): computed from the run (the
cam's speed and acceleration at the seat change against their peaks), carried in the Seating the
dynamics return, the stage's MachineCycle, summary.json and the report. On the default scene (85
aluminium links on two 12-tooth wheels with six seated links each, modified sine, 180 rpm, free play
94 um) phase 0 holds and phases 0.25 and 0.75 are flagged, with their snaps."""

import json

import pytest

from benchmarks.seating_table import PHASES, seat_change_run
from dynamics.response.seating import RIGID_SEATING_AT_REST, rigid_seating_validity, seat_snap_J
from dynamics.solvers.machine_verlet import Seating
from stages.machine import machine_cycle


@pytest.fixture(scope="module")
def default_scene_runs():
    """The default scene (benchmarks/seating_table.py's, docs/physics.md's table) at phases 0, 0.25
    and 0.75 over 180 cam degrees at 4 samples per degree: (seat change, peak cam speed, acceleration)."""
    assert PHASES == (0.0, 0.25, 0.75)
    return {phase: seat_change_run(phase) for phase in PHASES}


def test_phase_zero_holds_on_the_default_scene(default_scene_runs):
    seating, speed, accel = default_scene_runs[0.0]
    assert seating.cam_speed_m_s == 0.0 and seating.cam_acceleration_m_s2 == 0.0  # at the dwell
    validity = rigid_seating_validity(seating, speed, accel)
    assert validity.valid and validity.model == "rigid seating"
    assert 0.0 < abs(validity.snap_J) < 2.0  # docs/physics.md: 0.91 J with the free play


@pytest.mark.parametrize("phase", [0.25, 0.75])
def test_phases_inside_the_index_are_flagged_on_the_default_scene(default_scene_runs, phase):
    """The cam at the seat change: phase 0.25 at 0.75 p (decelerating), 0.75 at 0.25 p (accelerating):
    far above the threshold; the snap several times phase 0's (docs/physics.md's table: 9.4 and 17 J
    against 0.3 J on the free-play-free model)."""
    seating, speed, accel = default_scene_runs[phase]
    validity = rigid_seating_validity(seating, speed, accel)
    assert not validity.valid
    assert max(validity.cam_speed_fraction, validity.cam_acceleration_fraction) > 100 * RIGID_SEATING_AT_REST
    zero = rigid_seating_validity(*default_scene_runs[0.0])
    assert abs(validity.snap_J) > 3 * abs(zero.snap_J)


def test_the_snap_is_the_stored_energy_change_not_taken_by_the_impacts():
    seating = Seating((0.01, 0.02), (1e-4, 2e-4), 0.5, 3.0, -200.0)
    assert seat_snap_J(seating) == pytest.approx(0.5 + 3e-4, rel=1e-15)
    validity = rigid_seating_validity(seating, 5.0, 500.0)
    assert not validity.valid
    assert validity.cam_speed_fraction == pytest.approx(0.6) and validity.cam_acceleration_fraction == pytest.approx(
        0.4
    )


def test_the_threshold_is_the_cams_state_at_the_seat_change():
    """At the threshold it holds, just above it not (speed or acceleration alone)."""
    at_rest = rigid_seating_validity(Seating((0.0,), (0.0,), 0.0, RIGID_SEATING_AT_REST * 5.0, 0.0), 5.0, 500.0)
    assert at_rest.valid
    moving = rigid_seating_validity(Seating((0.0,), (0.0,), 0.0, 0.0, 1.01 * RIGID_SEATING_AT_REST * 500.0), 5.0, 500.0)
    assert not moving.valid


def test_the_stage_summary_and_report_carry_the_verdict():
    """MachineCycle.seating_validity -> summary.json's machine.seating_model -> the report's Machine
    section (a warning where rigid seating does not hold)."""
    from reporting.outputs import machine_cycle_summary
    from reporting.sections import _seating_paragraphs

    inside = machine_cycle(Seating((0.07, 0.05), (4e-3, 1e-3), 9.4, 3.0, -300.0), True, 5.0, 600.0)
    dwell = machine_cycle(Seating((0.01, 0.01), (1e-5, 1e-5), 0.3), True, 5.0, 600.0)
    assert not inside.seating_validity.valid and dwell.seating_validity.valid
    summaries = [json.loads(json.dumps(machine_cycle_summary(c), allow_nan=False)) for c in (inside, dwell)]
    assert summaries[0]["seating_model"]["valid"] is False and summaries[1]["seating_model"]["valid"] is True
    assert summaries[0]["seating_model"]["snap_J"] == pytest.approx(9.4 + 5e-3)
    summary = {"materials": {"al": {"cams": {"a": {"machine": summaries[0]}, "b": {"machine": summaries[1]}}}}}
    html = _seating_paragraphs(summary)
    assert 'class="warn"' in html and "rigid seating does NOT hold for al / a" in html
    assert summaries[0]["seating_model"]["instead"].startswith("seating through a tooth contact stiffness")
    assert summaries[1]["seating_model"]["instead"] is None and "the model that holds there" in html
    assert "rigid seating holds for al / b" in html
