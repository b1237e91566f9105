"""The long chain's default run against a tight run (issue #24): what the default step and search
leave of the station metrics at 2,000 links (benchmarks/bench_long_accuracy.py separates it)."""

import functools

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.machine_scene import every_step_metrics, simulate_machine
from dynamics.models import clearance_machine, machine_damping
from dynamics.models.chain import ChainModel
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import MachineLayout
from dynamics.models.wheels import Wheel
from dynamics.solvers import clearance_verlet as verlet

PITCH_M = 0.1125
LAYOUT = MachineLayout("wheels", Wheel(12, PITCH_M, 6, 0.688), Wheel(12, PITCH_M, 6, 0.688), None, True)
# the tight run: the step at the default safety / 5 (twice the window's refinement) for the search,
# the settle and the window, searched to 1e-8, each mode's damping ratio to 1e-7
TIGHT_SAFETY_DIVISOR = 5.0
TIGHT_TOL = 1e-8
TIGHT_DAMPING_TOLERANCE = 1e-7
# the tight run's search budget in index cycles (benchmarks/bench_long_accuracy.py: at 3,000 links the
# search at / 5 needs about 105, more than the default 60)
TIGHT_MAX_CYCLES = 300
# 3,000 links: the default run's worst station metric against the tight run, measured 3.1e-4 (the slack
# side's RMS a; benchmarks/bench_long_accuracy.py --links 3000 --reference tight-5 --variants default),
# plus the tight run's own 4.0e-5 from the run at / 10, rounded up (issue #24's target is 1e-3)
BOUND_3000 = 5e-4
METRICS = ("rms_displacement_m", "rms_velocity_m_s", "rms_acceleration_m_s2", "max_abs_acceleration_m_s2")
METRICS += ("residual_vibration_m",)


def _station_metrics(model, cam, t, **options) -> np.ndarray:
    """(4 stations, METRICS) as the pipeline has them (stages/chain.py): the kernel's over every step
    (the RMS over time, max |a| and the residual vibration its peaks)."""
    cols = list(model.machine.stations().values())
    r, _ = simulate_machine(model, cam, t, links=cols, **options)
    every_step = every_step_metrics(r)
    return np.array([[every_step[name][k] for k in METRICS] for name in model.machine.stations()])


@pytest.mark.slow
def test_the_2000_link_default_run_is_within_its_documented_accuracy_of_a_tight_run(monkeypatch):
    """2,000 links (default wheels and link, 0.094 mm, 180 rpm modified sine, the pipeline's output
    grid, steady state): the default run's 20 station metrics against the tight run (TIGHT_*), as the
    pipeline reports them (every step: the RMS over time, the peaks). Measured (bench_long_accuracy.py,
    against the run at safety / 10, which the one at / 5 is within 1.6e-4 of): worst 3.9e-4, the
    slack-side station's RMS acceleration (2.4e-3 when its RMS was taken over the output samples,
    which alias the ringing after two impacts there); against the run at / 5 here 2.3e-4. Bound: the
    measured 3.9e-4 plus the tight run's own 1.6e-4, rounded up to 6e-4 (issue #24's target is 1e-3).
    Slow: the tight run is about 2 x 10^5 steps of 4,000 DOFs (about 30 s of CPU)."""
    links = 2000
    chain = ChainModel(links, 2.03, 9.0092e7, damping_ratio=0.13, preload_N=2224.0, friction_coefficient=0.35)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)
    t = np.arange(721) / 4 / (6.0 * 180)  # 180 degrees at 4 per degree, the pipeline's grid
    default = _station_metrics(ClearanceMachine.of(chain, LAYOUT, None, 94e-6), cam, t)
    tight_damping = functools.partial(machine_damping.of_machine, tolerance=TIGHT_DAMPING_TOLERANCE)
    monkeypatch.setattr(clearance_machine, "of_machine", tight_damping)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    safety = verlet.default_safety(model, verlet.default_predictor(model)) / TIGHT_SAFETY_DIVISOR
    tight = _station_metrics(model, cam, t, safety=safety, tol=TIGHT_TOL)
    error = np.abs(default - tight) / np.abs(tight)
    assert np.max(error) < 6e-4


@pytest.mark.parametrize("corrected", [False, True])
def test_a_long_chains_settle_is_searched_to_its_tolerance_at_the_default_safety(monkeypatch, corrected):
    """Above DENSE_LINK_LIMIT links (420 here: rho about 0.6) the coarse search's fixed point is carried
    to the default safety's by the same search or by defect correction with coarse cycles
    (machine_scene._searched_and_settled, machine_shooting.defect_corrected_periodic_state): one more index
    cycle there moves the state returned by at most long_search_tol of the cycle's largest |q|, |q'|
    (the test that accepts it), and the cycles reported are both searches'. Asked for 1e-5 here (the
    default's 1.8e-3 at this rho is looser than what one settling cycle leaves at this length): one
    settling cycle, as before, left the next cycle's change at 4.0e-5 of max |q'|."""
    from dynamics import machine_scene
    from dynamics.machine_scene import SearchSettings, _searched_and_settled, long_search_tol
    from dynamics.models.reduction import DENSE_LINK_LIMIT
    from dynamics.solvers import machine_verlet as mv

    monkeypatch.setattr(machine_scene, "SETTLE_SEARCH_ABOVE_DECAY", 0.0)  # the search at any rho
    monkeypatch.setattr(machine_scene, "SETTLE_DEFECT_CORRECTED_ABOVE_DECAY", 0.0 if corrected else 1.0)
    monkeypatch.setattr(machine_scene, "LONG_SEARCH_STATE_ERROR", 1e-5)
    monkeypatch.setattr(machine_scene, "LONG_SEARCH_TOL", 1e-5)
    chain = ChainModel(DENSE_LINK_LIMIT + 20, 2.03, 9.0092e7, damping_ratio=0.13, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)
    h_out = cam.cycle_s / 90
    pred = verlet.default_predictor(model)
    safety = verlet.default_safety(model, pred)
    zeros = np.zeros(model.topology.n_dof)
    (q0, v0), ss, _ = _searched_and_settled(
        model, cam, h_out, 90, (zeros, zeros), SearchSettings(pred, safety, 1e-6, 60)
    )
    tol = long_search_tol(model, cam, 1e-6)
    assert tol == 1e-5
    assert ss.found and ss.residual <= tol and ss.cycles >= 3
    settle = mv.substeps_for(model, h_out, safety, pred)
    nodes = mv.cycle_nodes(cam, h_out / settle, 90 * settle)
    q1, v1, run, _ = mv.next_index_start(model, cam, nodes, h_out / settle, q0, v0, out_every=settle, predictor=pred)
    assert run.impacts > 0
    assert np.max(np.abs(q1 - q0)) <= tol * np.max(np.abs(run.q))
    assert np.max(np.abs(v1 - v0)) <= tol * np.max(np.abs(run.v))


@pytest.mark.slow
def test_the_3000_link_default_run_is_within_1e_3_of_a_tight_run(monkeypatch):
    """3,000 links (the scene above; rho 0.926, above the 0.92 where the settle is by defect correction
    at the window's step, the search's tolerance LONG_SEARCH_SLACK_STATE_ERROR (1 - rho) and each
    mode's damping ratio to 1e-7 by length): the default run's 20 station metrics against the tight
    run (TIGHT_*), as the pipeline reports them: within BOUND_3000 (its comment: the measured error
    and the tight run's own). Slow: the tight run is 105 index cycles at 43 steps per output sample
    (about 140 s of CPU), the default run about 25 s."""
    links = 3000
    chain = ChainModel(links, 2.03, 9.0092e7, damping_ratio=0.13, preload_N=2224.0, friction_coefficient=0.35)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)
    t = np.arange(721) / 4 / (6.0 * 180)
    default = _station_metrics(ClearanceMachine.of(chain, LAYOUT, None, 94e-6), cam, t)
    tight_damping = functools.partial(machine_damping.of_machine, tolerance=TIGHT_DAMPING_TOLERANCE)
    monkeypatch.setattr(clearance_machine, "of_machine", tight_damping)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    safety = verlet.default_safety(model, verlet.default_predictor(model)) / TIGHT_SAFETY_DIVISOR
    tight = _station_metrics(model, cam, t, safety=safety, tol=TIGHT_TOL, max_cycles=TIGHT_MAX_CYCLES)
    error = np.abs(default - tight) / np.abs(tight)
    assert np.max(error) < BOUND_3000
