"""Long clearance chains on wheels (issue #24): the accelerated relabelled steady state against plain
cycling, the O(N) setup (top frequency, lowest frequencies, the damping rule's range) against the
dense one where both run, and the model `--model auto` picks at 2,000 links."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.linalg import eigh

from dynamics.cams import CamProgram
from dynamics.machine_scene import simulate_machine
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import Tensioner
from dynamics.models.clearance_machine import ClearanceMachine, _top_frequency, _top_frequency_sparse
from dynamics.models.layout import MachineLayout
from dynamics.models.machine_damping import eigenvalue_bounds, of_machine
from dynamics.models.reduction import DENSE_LINK_LIMIT
from dynamics.models.wheels import Wheel
from dynamics.scene import ChainModelKind, Validity
from dynamics.solvers import machine_shooting
from dynamics.solvers import machine_verlet as mv

PITCH_M = 0.1125
WHEEL = Wheel(12, PITCH_M, 6, 0.688)
LAYOUT = MachineLayout("wheels", WHEEL, WHEEL, None, True)


def _cam():
    return CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)


@pytest.mark.parametrize("tensioner, tooth_phase", [(None, 0.0), (Tensioner(2e5, 20.0, 500.0), 0.0), (None, 0.5)])
def test_the_accelerated_steady_state_is_plain_cyclings_fixed_point(tensioner, tooth_phase):
    """Anderson-accelerated cycling accepts a start by plain cycling's own test (one index cycle and
    the seat change move it by <= tol of the cycle's largest |q|, |q'|), so both land on the same
    fixed point x0 = T(P(x0)) to within tol / (1 - rho) each, rho the contraction per cycle (about
    0.5 here): with tol = 1e-9 they agree to 1e-8 of the motion, in fewer cycles. At a tooth phase
    other than 0 both change seats inside the index."""
    chain = ChainModel(40, 2.03, 9.331e7, friction_coefficient=0.35)
    wheel = replace(WHEEL, tooth_phase=tooth_phase)
    layout = MachineLayout("wheels", wheel, wheel, None, True)
    model = ClearanceMachine.of(chain, layout, tensioner, 94e-6)
    cam = _cam()
    sub = mv.substeps_for(model, cam.cycle_s / 180, 0.31, "ab2")
    n = 180 * sub
    h = cam.cycle_s / n
    zeros = np.zeros(model.topology.n_dof)
    options = dict(tol=1e-9, max_cycles=80, predictor="ab2")
    plain = mv.relabelled_periodic_state(model, cam, h, n, zeros, zeros, **options)
    fast = machine_shooting.relabelled_periodic_state(model, cam, h, n, zeros, zeros, **options)
    assert plain[4] and fast[4]
    assert fast[2] <= plain[2]
    run = plain[5]
    assert run.impacts > 0
    assert np.max(np.abs(fast[0] - plain[0])) < 1e-8 * np.max(np.abs(run.q))
    assert np.max(np.abs(fast[1] - plain[1])) < 1e-8 * np.max(np.abs(run.v))


@pytest.mark.parametrize("tensioner", [None, Tensioner(1e5, 5.0, 100.0)])
def test_the_o_n_setup_is_the_dense_one_where_both_run(tensioner):
    """Just above DENSE_LINK_LIMIT, where the O(N) forms take over: the top frequency (the explicit
    step's limit) by shift-invert Lanczos is the dense eigensolve's to 1e-10, the 10 lowest
    frequencies (sparse shift-invert) the dense ones to 1e-9, and the damping rule's range covers
    S's spectrum (its bottom exact to 1e-8, its top Gershgorin's bound, within 1 % above)."""
    n = DENSE_LINK_LIMIT + 1
    chain = ChainModel(n, 2.03, 9.331e7, damping_ratio=0.13)
    machine = LAYOUT.machine(chain, tensioner)
    assert _top_frequency_sparse(machine) == pytest.approx(_top_frequency(machine), rel=1e-10)
    np.testing.assert_allclose(
        machine.lowest_natural_frequencies_Hz(10), machine.natural_frequencies_Hz()[:10], rtol=1e-9
    )
    red = of_machine(machine)
    k, m = machine.stiffness_matrix()[np.ix_(red.dofs, red.dofs)], machine.mass_matrix()[np.ix_(red.dofs, red.dofs)]
    lam = eigh(k, m, eigvals_only=True)
    tri = red.tri
    bottom, top = eigenvalue_bounds(tri[:, 2], tri[:, 3], red.scalars[0])
    assert bottom == pytest.approx(lam[0], rel=1e-8)
    assert lam[-1] <= top <= 1.01 * lam[-1]


def test_auto_picks_the_clearance_chain_at_2000_links():
    """`--model auto` on the wheels at 2,000 links (the default link's figures, 0.094 mm free play):
    the linear machine leaves pulling contact, so the clearance machine runs (valid), on the O(N)
    damping; one index cycle from rest, no steady state (the choice, not the answer)."""
    chain = ChainModel(2000, 2.03, 9.0092e7, damping_ratio=0.13, preload_N=2224.0, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    cam = _cam()
    t = cam.cycle_s * np.arange(91) / 90
    response, summary = simulate_machine(model, cam, t, steady_state=False, links=[0, 1000])
    assert model.reduced_damping
    assert summary.linear_min_tension_N < 0.0
    assert summary.model == ChainModelKind.CLEARANCE and summary.validity == Validity.VALID
    assert np.all(np.isfinite(response.x_m))


@pytest.mark.parametrize("tensioner", [None, Tensioner(1e5, 5.0, 100.0)])
def test_the_sparse_slow_modes_are_the_dense_ones(tensioner):
    """The steady-state search's slow modes above DENSE_EIGENSOLVE_UP_TO DOFs (block inverse
    iteration from Fourier shapes, dynamics.solvers.shooting.slow_modes), with and without the
    carriage's row, at 420 links: the same modes as the dense eigensolve (every mode slower than
    the limit, none more), eigenvalues to 1e-10 of the largest, shapes to 1e-6 (the iteration stops
    at residual 1e-7 of the largest Ritz value; the eigenvalues converge as its square)."""
    import scipy.sparse as sp

    from dynamics.solvers import shooting

    chain = ChainModel(420, 2.03, 9.331e7, damping_ratio=0.13)
    machine = LAYOUT.machine(chain, tensioner)
    topo = machine.topology
    r = 1.0 / np.sqrt(np.asarray(topo.masses_kg, dtype=float))
    x = (sp.diags(r) @ topo.stiffness_matrix_sparse() @ sp.diags(r)).tocsc()
    assert x.shape[0] > shooting.DENSE_EIGENSOLVE_UP_TO

    def is_slow(omega):
        return np.exp(-0.13 * np.asarray(omega) * _cam().cycle_s) > shooting.SLOW_DECAY

    omega, shapes = shooting.slow_modes(x, is_slow)
    lam, vec = np.linalg.eigh(x.toarray())
    wanted = is_slow(np.sqrt(np.maximum(lam, 0.0)))
    assert omega.size == np.count_nonzero(wanted) > 5
    np.testing.assert_allclose(omega**2, lam[wanted], rtol=0, atol=1e-10 * lam[wanted][-1])
    np.testing.assert_allclose(shapes.T @ shapes, np.eye(omega.size), atol=1e-12)
    assert np.min(np.abs(np.sum(shapes * vec[:, wanted], axis=0))) > 1 - 1e-6


def test_a_long_chains_search_starts_coarse_and_is_accepted_at_its_own_step():
    """Above DENSE_LINK_LIMIT links the search runs at SEARCH_SAFETY's coarser step first and
    finishes at the step asked for (machine_scene.start_state): the state returned passes the
    test at that step (one more index cycle there moves it by <= tol), the cycles counted are both
    searches', and up to DENSE_LINK_LIMIT links there is no coarse search."""
    from dynamics.machine_scene import SEARCH_SAFETY, SearchSettings, _coarse_substeps, start_state

    chain = ChainModel(DENSE_LINK_LIMIT + 20, 2.03, 9.0092e7, damping_ratio=0.13, friction_coefficient=0.35)
    linear = ClearanceMachine.of(chain, LAYOUT, None, 0.0)
    cam = _cam()
    h_out = cam.cycle_s / 90
    safety = SEARCH_SAFETY["global"] / 3
    sub = mv.substeps_for(linear, h_out, safety, "ab2")
    coarse = _coarse_substeps(linear, h_out, sub, "ab2")
    assert coarse is not None and coarse < sub
    zeros = np.zeros(linear.topology.n_dof)
    tol = 1e-4
    search = SearchSettings("ab2", safety, tol, 30, default_step=False)
    (q0, v0), ss, last = start_state(linear, cam, h_out, 90, sub, (zeros, zeros), search)
    assert ss.found and ss.cycles >= 2
    q1, v1, run, _ = mv.next_index_start(
        linear, cam, mv.cycle_nodes(cam, h_out / sub, 90 * sub), h_out / sub, q0, v0, out_every=sub, predictor="ab2"
    )
    assert np.max(np.abs(q1 - q0)) <= tol * np.max(np.abs(run.q))
    assert np.max(np.abs(v1 - v0)) <= tol * np.max(np.abs(run.v))
    assert last.step_s == pytest.approx(h_out / sub)
    short = ClearanceMachine.of(replace(chain, n_links=DENSE_LINK_LIMIT), LAYOUT, None, 0.0)
    assert _coarse_substeps(short, h_out, sub, "ab2") is None


def test_a_long_chains_unfound_search_is_not_repeated_at_the_window_step(monkeypatch):
    """A default-step search that finds no steady state is redone at the window's step
    (machine_scene._searched_and_settled); above DENSE_LINK_LIMIT links that search starts with the
    same coarse search from the same state (`_coarse_substeps`), which is handed over, not run again:
    each step's search runs once, and the redo's result is the one the repeated search gives."""
    from dynamics import machine_scene
    from dynamics.machine_scene import SEARCH_SAFETY, SearchSettings, _searched_and_settled

    chain = ChainModel(DENSE_LINK_LIMIT + 20, 2.03, 9.0092e7, damping_ratio=0.13, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    cam = _cam()
    h_out = cam.cycle_s / 90
    zeros = np.zeros(model.topology.n_dof)
    steps = []
    search = machine_shooting.relabelled_periodic_state

    def counted(model, cam, step_s, *args, **kwargs):
        steps.append(step_s)
        return search(model, cam, step_s, *args, **kwargs)

    monkeypatch.setattr(machine_shooting, "relabelled_periodic_state", counted)
    safety = 0.31
    settings = SearchSettings("ab2", safety, 1e-12, 2)
    state, ss, fine = _searched_and_settled(model, cam, h_out, 90, (zeros, zeros), settings)
    assert not ss.found and ss.cycles == 3  # two coarse cycles, one at the window's step
    coarse = mv.substeps_for(model, h_out, SEARCH_SAFETY["global"], "ab2")
    assert steps == pytest.approx([h_out / coarse, h_out / fine])
    # the search at the window's step run whole (its coarse part again) gives the same state; the O(N)
    # damping's sums vary at round-off between runs (docs/performance.md)
    (q_whole, v_whole), whole, _ = machine_scene.start_state(model, cam, h_out, 90, fine, (zeros, zeros), settings)
    assert whole.cycles == ss.cycles and len(steps) == 4
    np.testing.assert_allclose(state[0], q_whole, rtol=0, atol=1e-9 * np.max(np.abs(q_whole)))
    np.testing.assert_allclose(state[1], v_whole, rtol=0, atol=1e-9 * np.max(np.abs(v_whole)))


def test_a_long_chains_default_run_searches_each_machine_once_at_the_coarse_step(monkeypatch):
    """Above DENSE_LINK_LIMIT links the default step (machine_scene.simulate_machine) decides the model
    from the linear machine's search at SEARCH_SAFETY alone (to CHOICE_TOL, no confirming cycle at the
    default safety), searches the clearance machine's steady state there to long_search_tol (the
    tolerance its summary reports), then settles it at the default safety: one cycle where the slowest
    mode keeps at most SETTLE_SEARCH_ABOVE_DECAY of itself per cycle (420 links: rho about 0.6), else
    the search on to the same tolerance at the default safety, and above
    SETTLE_DEFECT_CORRECTED_ABOVE_DECAY that fixed point by defect correction from the same coarse
    search (each forced here by a threshold of 0); a short chain keeps `tol` and settles for one cycle
    at the window's step."""
    from dynamics import machine_scene
    from dynamics.machine_scene import CHOICE_TOL, SEARCH_SAFETY, WINDOW_REFINEMENT, long_search_tol
    from dynamics.solvers import clearance_verlet as verlet

    searches, settles = [], []
    accelerated, plain = machine_shooting.relabelled_periodic_state, mv.relabelled_periodic_state
    two_level = machine_shooting.defect_corrected_periodic_state

    def counted_search(model, cam, step_s, *args, **kwargs):
        searches.append((model.clearance_m, step_s, kwargs["tol"]))
        return accelerated(model, cam, step_s, *args, **kwargs)

    def counted_two_level(model, cam, coarse, fine, *args, **kwargs):
        searches.append((model.clearance_m, coarse[0], kwargs["tol"]))
        settles.append((model.clearance_m, fine[0], kwargs["tol"]))
        return two_level(model, cam, coarse, fine, *args, **kwargs)

    def counted_plain(model, cam, step_s, *args, **kwargs):
        (settles if kwargs["tol"] == 0.0 else searches).append((model.clearance_m, step_s, kwargs["tol"]))
        return plain(model, cam, step_s, *args, **kwargs)

    monkeypatch.setattr(machine_shooting, "relabelled_periodic_state", counted_search)
    monkeypatch.setattr(mv, "relabelled_periodic_state", counted_plain)
    monkeypatch.setattr(machine_shooting, "defect_corrected_periodic_state", counted_two_level)
    cam = _cam()
    t = cam.cycle_s * np.arange(91) / 90
    h_out = t[1]
    default_threshold = machine_scene.SETTLE_SEARCH_ABOVE_DECAY
    for links, long_chain, settle_searched, corrected in (
        (DENSE_LINK_LIMIT + 20, True, True, True),
        (DENSE_LINK_LIMIT + 20, True, True, False),
        (DENSE_LINK_LIMIT + 20, True, False, False),
        (40, False, False, False),
    ):
        searches.clear()
        settles.clear()
        threshold = 0.0 if settle_searched else default_threshold
        monkeypatch.setattr(machine_scene, "SETTLE_SEARCH_ABOVE_DECAY", threshold)
        monkeypatch.setattr(machine_scene, "SETTLE_DEFECT_CORRECTED_ABOVE_DECAY", 0.0 if corrected else 1.0)
        chain = ChainModel(links, 2.03, 9.0092e7, damping_ratio=0.13, friction_coefficient=0.35)
        model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
        linear = ClearanceMachine.of(chain, LAYOUT, None, 0.0)
        _, summary = simulate_machine(model, cam, t, links=[0], tol=1e-6)
        assert summary.model == ChainModelKind.CLEARANCE and summary.steady_state.found
        pred = verlet.default_predictor(model)
        safety = verlet.default_safety(model, pred)
        coarse = mv.substeps_for(model, h_out, SEARCH_SAFETY["global"], pred)
        fine = mv.substeps_for(model, h_out, safety / WINDOW_REFINEMENT["global"], pred)
        assert summary.steps_per_output == fine
        if long_chain:
            lin_coarse = mv.substeps_for(linear, h_out, SEARCH_SAFETY["global"], pred)
            search_tol = long_search_tol(model, cam, 1e-6)
            assert 1e-6 < search_tol < 1e-2
            settle = mv.substeps_for(model, h_out, safety, pred)
            expected = [(0.0, h_out / lin_coarse, CHOICE_TOL), (94e-6, h_out / coarse, search_tol)]
            if settle_searched and not corrected:
                expected.append((94e-6, h_out / settle, search_tol))
            np.testing.assert_allclose(searches, expected, rtol=1e-12)
            assert summary.steady_state.residual <= search_tol
            assert f"<= {search_tol:g}" in summary.steady_state.statement
            if corrected:
                np.testing.assert_allclose(settles, [(94e-6, h_out / settle, search_tol)], rtol=1e-12)
            elif settle_searched:
                assert settles == []
            else:
                assert machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s) < threshold
                np.testing.assert_allclose(settles, [(94e-6, h_out / settle, 0.0)], rtol=1e-12)
        else:
            assert [s[2] for s in searches] == [CHOICE_TOL, 1e-6]
            np.testing.assert_allclose(settles, [(94e-6, h_out / fine, 0.0)], rtol=1e-12)
        assert machine_scene.SETTLE_CYCLES == 1


def test_the_slowest_decay_per_cycle_is_the_dense_lowest_modes(monkeypatch):
    """machine_shooting.slowest_decay_per_cycle (one sparse shift-invert Lanczos) is exp(-zeta omega_1 T)
    of the lowest mode of the dense (K, M) eigensolve, with and without a tensioner's carriage, and
    long_search_tol is LONG_SEARCH_STATE_ERROR (1 - that), never below the caller's tol nor
    LONG_SEARCH_TOL; above LONG_SEARCH_STATE_ERROR_UP_TO_DECAY (moved below this chain's decay)
    LONG_SEARCH_SLACK_STATE_ERROR (1 - that), never below LONG_SEARCH_TOL_FLOOR (the Kelvin-Voigt
    law's nearly undamped slow modes)."""
    from dynamics import machine_scene
    from dynamics.machine_scene import (
        LONG_SEARCH_SLACK_STATE_ERROR,
        LONG_SEARCH_STATE_ERROR,
        LONG_SEARCH_TOL,
        LONG_SEARCH_TOL_FLOOR,
        long_search_tol,
    )

    cam = _cam()
    for tensioner in (None, Tensioner(2e5, 20.0, 500.0)):
        chain = ChainModel(DENSE_LINK_LIMIT + 20, 2.03, 9.0092e7, damping_ratio=0.13, friction_coefficient=0.35)
        model = ClearanceMachine.of(chain, LAYOUT, tensioner, 94e-6)
        topo = model.topology
        lam = eigh(topo.stiffness_matrix_sparse().toarray(), np.diag(topo.masses_kg), eigvals_only=True)
        omega = np.sqrt(lam[0])
        expected = np.exp(-model.damping_ratio_at(omega) * omega * cam.cycle_s)
        decay = machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s)
        assert 0.0 < decay < 1.0
        np.testing.assert_allclose(decay, expected, rtol=1e-10)
        assert decay < machine_scene.LONG_SEARCH_STATE_ERROR_UP_TO_DECAY
        assert LONG_SEARCH_STATE_ERROR * (1.0 - expected) > LONG_SEARCH_TOL
        np.testing.assert_allclose(long_search_tol(model, cam, 1e-6), LONG_SEARCH_STATE_ERROR * (1.0 - expected))
        assert long_search_tol(model, cam, 0.5) == 0.5
        with monkeypatch.context() as patched:
            patched.setattr(machine_scene, "LONG_SEARCH_STATE_ERROR_UP_TO_DECAY", 0.99 * decay)
            assert LONG_SEARCH_SLACK_STATE_ERROR * (1.0 - expected) > LONG_SEARCH_TOL_FLOOR
            np.testing.assert_allclose(
                long_search_tol(model, cam, 1e-6), LONG_SEARCH_SLACK_STATE_ERROR * (1.0 - expected)
            )
            assert long_search_tol(model, cam, 0.5) == 0.5
    kelvin_voigt = ClearanceMachine.of(chain, LAYOUT, None, 94e-6, "kelvin-voigt")
    kv_decay = machine_shooting.slowest_decay_per_cycle(kelvin_voigt, cam.cycle_s)
    assert kv_decay > machine_scene.LONG_SEARCH_STATE_ERROR_UP_TO_DECAY
    assert LONG_SEARCH_SLACK_STATE_ERROR * (1.0 - kv_decay) < LONG_SEARCH_TOL_FLOOR
    assert long_search_tol(kelvin_voigt, cam, 1e-6) == LONG_SEARCH_TOL_FLOOR


@pytest.mark.parametrize("links", [DENSE_LINK_LIMIT + 20, pytest.param(2000, marks=pytest.mark.slow)])
def test_a_long_search_at_its_tolerance_is_within_the_state_error_of_the_fixed_point(links):
    """The clearance machine's search above DENSE_LINK_LIMIT links stopped at long_search_tol (the
    default run's, from the linear machine's steady state, at SEARCH_SAFETY) lands within
    LONG_SEARCH_STATE_ERROR of the fixed point the same search finds at 1e-9, relative to the
    cycle's largest |q| and |q'|: the bound residual / (1 - rho) that sets the tolerance (rho the
    slowest mode's decay per cycle: about 0.6 at 420 links, 0.89 at 2,000; slow: 2,000 links, about
    40 index cycles of 4,000 DOFs)."""
    from dynamics import machine_scene
    from dynamics.solvers import clearance_verlet as verlet

    chain = ChainModel(links, 2.03, 9.0092e7, damping_ratio=0.13, preload_N=2224.0, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    linear = ClearanceMachine(model.machine, 0.0, "global", None, model.friction_chain)
    cam = _cam()
    pred = verlet.default_predictor(model)
    h_out = cam.cycle_s / 90
    sub = mv.substeps_for(model, h_out, machine_scene.SEARCH_SAFETY["global"], pred)
    n = 90 * sub
    zeros = np.zeros(model.topology.n_dof)
    options = dict(max_cycles=60, predictor=pred)
    start = machine_shooting.relabelled_periodic_state(linear, cam, h_out / sub, n, zeros, zeros, tol=1e-3, **options)
    tol = machine_scene.long_search_tol(model, cam, 1e-6)
    loose = machine_shooting.relabelled_periodic_state(model, cam, h_out / sub, n, *start[:2], tol=tol, **options)
    tight = machine_shooting.relabelled_periodic_state(model, cam, h_out / sub, n, *start[:2], tol=1e-9, **options)
    assert loose[4] and tight[4] and loose[2] < tight[2]
    run = tight[5]
    assert run.impacts > 0
    assert np.max(np.abs(loose[0] - tight[0])) < machine_scene.LONG_SEARCH_STATE_ERROR * np.max(np.abs(run.q))
    assert np.max(np.abs(loose[1] - tight[1])) < machine_scene.LONG_SEARCH_STATE_ERROR * np.max(np.abs(run.v))


def test_the_slow_mode_newton_step_inverts_each_slow_modes_cycle():
    """machine_shooting.slow_mode_newton on a slow mode's shape: (I - Phi)^-1 applied to it, Phi the
    mode's one-cycle propagator in closed form (a damped oscillator, x(T) = e^(-zeta w T) (cos wd T
    x0 + sin wd T (x0' + zeta w x0) / wd)), independent of the batched matrix exponential; a shape
    orthogonal to the slow ones is left as it is."""
    chain = ChainModel(300, 2.03, 9.331e7, damping_ratio=0.13)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    period = _cam().cycle_s
    step = machine_shooting.slow_mode_newton(model, period, 1e-2)
    topo = model.topology
    masses = np.asarray(topo.masses_kg, dtype=float)
    lam, vec = eigh(topo.stiffness_matrix_sparse().toarray(), np.diag(masses))
    omega = np.sqrt(lam)
    zeta = np.array([model.damping_ratio_at(o) for o in omega])
    decay = np.exp(-zeta * omega * period)
    newton = (decay > 1e-2) & (decay <= machine_shooting.NEWTON_DECAY_CAP)
    assert np.count_nonzero(newton) >= 3
    n = topo.n_dof
    for j in np.flatnonzero(newton)[:3]:
        w, z = omega[j], zeta[j]
        wd = w * np.sqrt(1.0 - z * z)
        c, s = np.cos(wd * period), np.sin(wd * period)
        phi = decay[j] * np.array([[c + z * w * s / wd, s / wd], [-w * w * s / wd, c - z * w * s / wd]])
        expected = np.linalg.solve(np.eye(2) - phi, [1.0, 2.0])
        out = step(np.concatenate([vec[:, j], 2.0 * vec[:, j]]))
        np.testing.assert_allclose(out[:n], expected[0] * vec[:, j], atol=1e-9 * abs(expected).max())
        np.testing.assert_allclose(out[n:], expected[1] * vec[:, j], atol=1e-9 * abs(expected).max())
    fast = np.flatnonzero(decay <= 1e-2)[0]
    r = np.concatenate([vec[:, fast], vec[:, fast]])
    np.testing.assert_allclose(step(r), r, atol=1e-9)


def test_the_newton_step_takes_every_slow_mode_unless_the_slowest_keeps_more_than_its_bound(monkeypatch):
    """slow_mode_newton leaves the modes above NEWTON_DECAY_CAP to Anderson only where the slowest
    mode keeps more than NEWTON_EVERY_SLOW_MODE_UP_TO_DECAY of itself per cycle: on the slowest
    mode's shape the step is (I - Phi)^-1 (closed form, as above) with the bound above its decay, and
    the shape itself (no step) with the bound below it, the cap below the decay in both."""
    chain = ChainModel(300, 2.03, 9.331e7, damping_ratio=0.13)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    period = _cam().cycle_s
    topo = model.topology
    lam, vec = eigh(topo.stiffness_matrix_sparse().toarray(), np.diag(np.asarray(topo.masses_kg, dtype=float)))
    w = np.sqrt(lam[0])
    z = model.damping_ratio_at(w)
    decay = np.exp(-z * w * period)
    wd = w * np.sqrt(1.0 - z * z)
    c, s = np.cos(wd * period), np.sin(wd * period)
    phi = decay * np.array([[c + z * w * s / wd, s / wd], [-w * w * s / wd, c - z * w * s / wd]])
    expected = np.linalg.solve(np.eye(2) - phi, [1.0, 2.0])
    r = np.concatenate([vec[:, 0], 2.0 * vec[:, 0]])
    n = topo.n_dof
    monkeypatch.setattr(machine_shooting, "NEWTON_DECAY_CAP", 0.5 * decay)
    for bound, stepped in ((0.5 * (1.0 + decay), True), (0.5 * decay, False)):
        monkeypatch.setattr(machine_shooting, "NEWTON_EVERY_SLOW_MODE_UP_TO_DECAY", bound)
        out = machine_shooting.slow_mode_newton(model, period, 1e-2)(r)
        want = np.concatenate([expected[0] * vec[:, 0], expected[1] * vec[:, 0]]) if stepped else r
        np.testing.assert_allclose(out[:n], want[:n], atol=1e-9 * abs(want).max())
        np.testing.assert_allclose(out[n:], want[n:], atol=1e-9 * abs(want).max())


def test_the_linear_machine_settles_in_a_few_cycles_with_its_slowest_mode_just_above_the_cap():
    """The slowest mode keeping about 0.92 of itself per cycle (above NEWTON_DECAY_CAP and below
    NEWTON_EVERY_SLOW_MODE_UP_TO_DECAY): the linear machine's search from rest to 1e-3 at SEARCH_SAFETY,
    as the default run decides the model with it, finds its steady state in a few cycles (4 measured;
    with the cap, NEWTON_EVERY_SLOW_MODE_UP_TO_DECAY below the decay, it had not in 20: 0.18). The
    default link's figures showed it at 2,500 links (0.91; 3 cycles, none in 60 with the cap); here
    2,000 links with zeta 0.10 put the slowest mode in the same band with a fifth fewer links to step."""
    from dynamics import machine_scene
    from dynamics.solvers import clearance_verlet as verlet

    chain = ChainModel(2000, 2.03, 9.0092e7, damping_ratio=0.10, preload_N=2224.0, friction_coefficient=0.35)
    linear = machine_scene.linear_machine(ClearanceMachine.of(chain, LAYOUT, None, 94e-6))
    cam = _cam()
    decay = machine_shooting.slowest_decay_per_cycle(linear, cam.cycle_s)
    assert machine_shooting.NEWTON_DECAY_CAP < decay < machine_shooting.NEWTON_EVERY_SLOW_MODE_UP_TO_DECAY
    pred = verlet.default_predictor(linear)
    h_out = cam.cycle_s / 90
    sub = mv.substeps_for(linear, h_out, machine_scene.SEARCH_SAFETY["global"], pred)
    zeros = np.zeros(linear.topology.n_dof)
    *_, cycles, residual, found, _ = machine_shooting.relabelled_periodic_state(
        linear, cam, h_out / sub, 90 * sub, zeros, zeros, tol=machine_scene.CHOICE_TOL, max_cycles=60, predictor=pred
    )
    assert found and residual <= machine_scene.CHOICE_TOL and cycles <= 6


def test_above_newton_free_play_links_the_clearance_search_is_anderson_alone(monkeypatch):
    """Above NEWTON_FREE_PLAY_LINKS a machine with free play is searched without the slow-mode Newton
    step, with FREE_PLAY_DEPTH and FREE_PLAY_STALL (the linear machine keeps the step and the
    defaults), and the search still lands on plain cycling's fixed point (the same acceptance
    test: within tol / (1 - rho), rho about 0.5 here)."""
    from dynamics.solvers import shooting

    chain = ChainModel(40, 2.03, 9.331e7, friction_coefficient=0.35)
    clearance = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    linear = ClearanceMachine(clearance.machine, 0.0, "global", None, clearance.friction_chain)
    monkeypatch.setattr(machine_shooting, "NEWTON_FREE_PLAY_LINKS", 39)
    built = []
    real = machine_shooting._cached_slow_mode_newton
    monkeypatch.setattr(machine_shooting, "_cached_slow_mode_newton", lambda m, t: built.append(m) or real(m, t))
    histories = []
    search = machine_shooting.shooting.accelerated_fixed_point

    def recorded(*args, **kwargs):
        histories.append((kwargs["depth"], kwargs["stall"]))
        return search(*args, **kwargs)

    monkeypatch.setattr(machine_shooting.shooting, "accelerated_fixed_point", recorded)
    cam = _cam()
    sub = mv.substeps_for(clearance, cam.cycle_s / 180, 0.31, "ab2")
    n = 180 * sub
    zeros = np.zeros(clearance.topology.n_dof)
    options = dict(tol=1e-9, max_cycles=80, predictor="ab2")
    fast = machine_shooting.relabelled_periodic_state(clearance, cam, cam.cycle_s / n, n, zeros, zeros, **options)
    assert built == []
    plain = mv.relabelled_periodic_state(clearance, cam, cam.cycle_s / n, n, zeros, zeros, **options)
    assert fast[4] and plain[4] and fast[2] <= plain[2]
    assert np.max(np.abs(fast[0] - plain[0])) < 1e-8 * np.max(np.abs(plain[5].q))
    machine_shooting.relabelled_periodic_state(linear, cam, cam.cycle_s / n, n, zeros, zeros, **options)
    assert built == [linear]
    free_play = (machine_shooting.FREE_PLAY_DEPTH, machine_shooting.FREE_PLAY_STALL)
    assert histories == [free_play, (shooting.DEFAULT_DEPTH, shooting.DEFAULT_STALL)]


@pytest.mark.slow
def test_the_5000_link_clearance_machine_finds_its_steady_state():
    """At 5,000 links (the default link's figures, 0.094 mm free play, 180 rpm modified sine) the
    clearance machine's search, Anderson alone above NEWTON_FREE_PLAY_LINKS, reaches its tolerance
    within the default cycle budget (with the slow-mode Newton step it stalled near 5e-3 per
    cycle); slow: about 40 index cycles of 10,000 DOFs."""
    chain = ChainModel(5000, 2.03, 9.0092e7, damping_ratio=0.13, preload_N=2224.0, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    cam = _cam()
    t = cam.cycle_s * np.arange(91) / 90
    _, summary = simulate_machine(model, cam, t, links=[0, 2500])
    assert model.n_links > machine_shooting.NEWTON_FREE_PLAY_LINKS
    assert summary.model == ChainModelKind.CLEARANCE
    assert summary.steady_state.found, summary.steady_state.statement


@pytest.mark.slow
def test_the_10000_link_clearance_machine_finds_its_steady_state_to_the_long_search_tolerance():
    """At 10,000 links (as above) the clearance machine's search reaches long_search_tol, about 1.1e-5
    there (the slowest mode keeps 0.978 of itself per cycle, above LONG_SEARCH_STATE_ERROR_UP_TO_DECAY:
    LONG_SEARCH_SLACK_STATE_ERROR (1 - rho)), within the default cycle budget; slow: about 86 index
    cycles of 20,000 DOFs (on the benchmark's scenario: the coarse search to ten times it, then the
    settle by defect correction, its fine cycles at the window's step)."""
    from dynamics import machine_scene
    from dynamics.machine_scene import long_search_tol

    chain = ChainModel(10000, 2.03, 9.0092e7, damping_ratio=0.13, preload_N=2224.0, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    cam = _cam()
    t = cam.cycle_s * np.arange(91) / 90
    _, summary = simulate_machine(model, cam, t, links=[0, 5000])
    tol = long_search_tol(model, cam, 1e-6)
    decay = machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s)
    assert decay > machine_scene.LONG_SEARCH_STATE_ERROR_UP_TO_DECAY
    assert tol == pytest.approx(machine_scene.LONG_SEARCH_SLACK_STATE_ERROR * (1.0 - decay), rel=1e-12)
    assert 0.5e-5 < tol < 2e-5
    assert summary.model == ChainModelKind.CLEARANCE
    assert summary.steady_state.found, summary.steady_state.statement
    assert summary.steady_state.residual <= tol
