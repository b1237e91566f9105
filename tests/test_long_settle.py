"""A long chain's settle by defect correction (issue #24): the fine map's fixed point searched with
coarse periods (dynamics.solvers.shooting.defect_corrected_fixed_point,
dynamics.solvers.machine_shooting.defect_corrected_periodic_state) against the fine map's own fixed
point, and, where the two maps are the same, the coarse search's result unchanged."""

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import MachineLayout
from dynamics.models.reduction import DENSE_LINK_LIMIT
from dynamics.models.wheels import Wheel
from dynamics.solvers import machine_shooting
from dynamics.solvers import machine_verlet as mv
from dynamics.solvers.shooting import DEFECT_INNER_TOL_FRACTION, accelerated_fixed_point, defect_corrected_fixed_point

PITCH_M = 0.1125
LAYOUT = MachineLayout("wheels", Wheel(12, PITCH_M, 6, 0.688), Wheel(12, PITCH_M, 6, 0.688), None, True)
# a contraction in rotated coordinates: 30 rates, the slowest 0.99 per period (plain periods need
# about 1,400 to 1e-6), the fast ones at most 0.1; the fine map keeps the slow rates, moves the fast
# ones by half and its fixed point mostly along the slowest direction, as a finer step moves a chain's
# fast modes and its fixed point along the slow ones
RATES = np.concatenate([[0.99, 0.97, 0.95, 0.9], np.linspace(0.001, 0.1, 26)])
FINE_RATES = RATES * np.where(RATES < 0.6, 1.5, 1.0)


def _linear_maps(seed=5):
    rng = np.random.default_rng(seed)
    basis, _ = np.linalg.qr(rng.normal(size=(RATES.size, RATES.size)))
    coarse_target = rng.normal(size=RATES.size)
    fine_target = coarse_target + 0.05 * basis[:, 0] + 1e-3 * rng.normal(size=RATES.size)

    def map_of(rates, target):
        jacobian = basis @ np.diag(rates) @ basis.T

        def period(x):
            return target + jacobian @ (x - target), np.ones_like(x)

        return period

    return map_of(RATES, coarse_target), map_of(FINE_RATES, fine_target), fine_target


def test_defect_correction_lands_on_the_fine_maps_fixed_point_with_few_fine_periods():
    """The search accepts a start by the fine map's test (one fine period moves it by <= tol), so the
    state is within about tol / (1 - 0.99) of the fine map's fixed point; and it takes the slow
    offset between the two fixed points with coarse periods: fewer than half the fine periods of the
    fine map's own accelerated search from the same coarse fixed point (measured 5 against 13; each
    defect renewal leaves about the fast rates' change / (1 - fast rate), 5 %, of the last one)."""
    coarse, fine, fine_target = _linear_maps()
    tol = 1e-8
    found = accelerated_fixed_point(coarse, np.zeros(RATES.size), tol=tol, max_periods=200, depth=16)
    assert found.converged and len(found.history[0]) > 0
    two = defect_corrected_fixed_point(coarse, fine, found, tol=tol, max_periods=200, depth=16)
    result = two.search
    assert result.converged and result.residual <= tol
    assert result.periods == two.coarse_periods + two.fine_periods
    bound = tol / (1.0 - RATES.max())
    np.testing.assert_allclose(result.state, fine_target, rtol=0, atol=bound)
    direct = accelerated_fixed_point(fine, found.state, tol=tol, max_periods=200, depth=16)
    assert direct.converged
    assert 2 * two.fine_periods < direct.periods


def test_without_a_defect_it_is_the_coarse_search():
    """Where the fine map is the coarse one (d = 0) the first fine period is the coarse search's last:
    the coarse search's state is accepted as it is, after that one period."""
    coarse, _, _ = _linear_maps()
    found = accelerated_fixed_point(coarse, np.zeros(RATES.size), tol=1e-8, max_periods=200, depth=16)
    two = defect_corrected_fixed_point(coarse, coarse, found, tol=1e-8, max_periods=200, depth=16)
    assert two.search.converged and two.fine_periods == 1 and two.coarse_periods == 0
    np.testing.assert_array_equal(two.search.state, found.state)
    assert two.search.residual == found.residual


def test_a_looser_coarse_search_lands_on_the_same_fine_fixed_point_in_no_more_periods():
    """The coarse search stopped at DEFECT_COARSE_TOL_FACTOR times the tolerance (as
    machine_shooting.defect_corrected_periodic_state stops it): the defect correction carries its
    history on to the same fine fixed point, within the same bound, and the coarse map's own fixed
    point, which the fine map never sees, is not searched to the end: no more periods of both maps
    together than from the coarse search at the tolerance itself (here as many: Anderson with 16
    residuals takes this 30-dimensional linear map's every direction in about 14 periods, where the
    machine's coarse search crawls: 8 cycle-equivalents fewer at 10,000 links, docs/performance.md)."""
    coarse, fine, fine_target = _linear_maps()
    tol = 1e-8
    options = dict(tol=tol, max_periods=200, depth=16)
    periods = {}
    for factor in (1.0, machine_shooting.DEFECT_COARSE_TOL_FACTOR):
        found = accelerated_fixed_point(coarse, np.zeros(RATES.size), **{**options, "tol": factor * tol})
        assert found.converged
        two = defect_corrected_fixed_point(coarse, fine, found, **options)
        assert two.search.converged and two.search.residual <= tol
        np.testing.assert_allclose(two.search.state, fine_target, rtol=0, atol=tol / (1.0 - RATES.max()))
        periods[factor] = found.periods + two.coarse_periods + two.fine_periods
    assert periods[machine_shooting.DEFECT_COARSE_TOL_FACTOR] <= periods[1.0]


def test_the_budget_bounds_both_maps_periods():
    """max_periods bounds the coarse and fine periods together; a search out of budget says so."""
    coarse, fine, _ = _linear_maps()
    found = accelerated_fixed_point(coarse, np.zeros(RATES.size), tol=1e-12, max_periods=200, depth=16)
    two = defect_corrected_fixed_point(coarse, fine, found, tol=1e-14, max_periods=4, depth=16)
    assert not two.search.converged
    assert two.coarse_periods + two.fine_periods <= 4 and two.fine_periods >= 1


def _machine(links=DENSE_LINK_LIMIT + 20):
    from dynamics.solvers import clearance_verlet as verlet

    chain = ChainModel(links, 2.03, 9.0092e7, damping_ratio=0.13, preload_N=2224.0, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)
    pred = verlet.default_predictor(model)
    return model, cam, pred, verlet.default_safety(model, pred)


def test_the_machines_defect_corrected_settle_is_the_default_steps_fixed_point():
    """Above DENSE_LINK_LIMIT links (420, the O(N) damping) from the linear machine's state: the state
    the defect correction returns, searched at SEARCH_SAFETY and accepted at the default safety to
    1e-6, is within 2 tol / (1 - rho) of the default step's fixed point found by its own search to 1e-10
    (relative to the cycle's largest |q| and |q'|; rho the slowest mode's decay per cycle, the bound
    residual / (1 - rho) of a start's distance from the fixed point, doubled for the map's
    nonlinearity), and its last cycle is the default step's."""
    from dynamics.machine_scene import SEARCH_SAFETY

    model, cam, pred, safety = _machine()
    linear = ClearanceMachine(model.machine, 0.0, "global", None, model.friction_chain)
    h_out = cam.cycle_s / 90
    coarse = mv.substeps_for(model, h_out, SEARCH_SAFETY["global"], pred)
    settle = mv.substeps_for(model, h_out, safety, pred)
    assert coarse < settle
    zeros = np.zeros(model.topology.n_dof)
    options = dict(max_cycles=60, predictor=pred)
    start = machine_shooting.relabelled_periodic_state(
        linear, cam, h_out / coarse, 90 * coarse, zeros, zeros, tol=1e-3, **options
    )
    tol = 1e-6
    two = machine_shooting.defect_corrected_periodic_state(
        model, cam, (h_out / coarse, 90 * coarse), (h_out / settle, 90 * settle), *start[:2], tol=tol, **options
    )
    assert two.found and two.residual <= tol and two.settled.coarse_periods > 0
    assert two.cycles == two.coarse.periods + two.settled.coarse_periods + two.settled.fine_periods
    assert two.last_run.step_s == pytest.approx(h_out / settle)
    tight = machine_shooting.relabelled_periodic_state(
        model, cam, h_out / settle, 90 * settle, two.q0, two.v0, tol=1e-10, **options
    )
    assert tight[4]
    run = tight[5]
    bound = 2.0 * tol / (1.0 - machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s))
    assert np.max(np.abs(two.q0 - tight[0])) < bound * np.max(np.abs(run.q))
    assert np.max(np.abs(two.v0 - tight[1])) < bound * np.max(np.abs(run.v))


def test_the_machines_settle_at_the_search_step_is_the_search():
    """With the fine step the coarse one (no defect) the state is the accelerated search's at that
    step carried on with its history: the coarse search to DEFECT_COARSE_TOL_FACTOR times the
    tolerance, then, the defect 0, the same extrapolation on to DEFECT_INNER_TOL_FRACTION of it, each
    of the two stretches ended by one more cycle at the (same) fine step (the O(N) damping's sums vary
    at round-off between runs, docs/performance.md)."""
    from dynamics.machine_scene import SEARCH_SAFETY

    model, cam, pred, _ = _machine()
    h_out = cam.cycle_s / 90
    coarse = mv.substeps_for(model, h_out, SEARCH_SAFETY["global"], pred)
    step = (h_out / coarse, 90 * coarse)
    zeros = np.zeros(model.topology.n_dof)
    options = dict(tol=1e-4, max_cycles=60, predictor=pred)
    inner = {**options, "tol": DEFECT_INNER_TOL_FRACTION * options["tol"]}
    search = machine_shooting.relabelled_periodic_state(model, cam, *step, zeros, zeros, **inner)
    two = machine_shooting.defect_corrected_periodic_state(model, cam, step, step, zeros, zeros, **options)
    assert search[4] and two.found
    assert two.coarse.residual > DEFECT_INNER_TOL_FRACTION * options["tol"]
    assert two.settled.fine_periods == 2 and two.cycles == search[2] + 2
    np.testing.assert_allclose(two.q0, search[0], rtol=0, atol=1e-9 * np.max(np.abs(search[0])))
    np.testing.assert_allclose(two.v0, search[1], rtol=0, atol=1e-9 * np.max(np.abs(search[1])))
