"""Long chains (issue 24): the steady-state search in few cam cycles, and the long chain's linear
solve in its modal basis stepped mode by mode.

- The Anderson-accelerated search (dynamics.solvers.shooting) finds the state the plain search finds,
  to the steady-state tolerance, on a short chain; with depth 0 it is the plain search itself.
- Above 400 links (the O(N) damping) it finds the periodic state, in fewer cycles than the plain
  search needs.
- An uncoupled system (the modal basis) with a nonlinear force is stepped mode by mode; that equals
  the dense step loop on the same system written in rotated coordinates, to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain
from dynamics.models.system import SecondOrderSystem
from dynamics.scene import _periodic_state, simulate_chain
from dynamics.solvers import clearance_verlet as verlet
from dynamics.solvers.exact import propagate
from dynamics.solvers.shooting import accelerated_fixed_point
from dynamics.solvers.simulate import simulate


def _chain(n, friction=0.35):
    return ChainModel(n_links=n, link_mass_kg=2.03, stiffness_N_per_m=9.0092e7, friction_coefficient=friction)


def _cam():
    return CamProgram.indexing("modified-sine", pitch_m=0.1125, rpm=180.0)


def _search(model, depth, t):
    lin = simulate(model.chain, _cam(), t, steady_state=True)
    h = (t[1] - t[0]) / verlet.substeps_for(model, float(t[1] - t[0]), 0.31, "ab2")
    start = (lin.x_m[0] - lin.z_m[0], lin.v_m_s[0] - lin.zdot_m_s[0], 0.0, 0.0)
    return _periodic_state(model, _cam(), t[0], h, start, 1e-6, 60, "ab2", depth=depth)


def test_accelerated_search_finds_the_plain_searchs_state_to_the_tolerance():
    model = ClearanceChain(_chain(40), 94e-6)
    t = np.arange(361) / 4 / (6 * 180.0)
    (y_p, w_p, _, _), plain = _search(model, 0, t)
    (y_a, w_a, _, _), accelerated = _search(model, 8, t)
    assert plain.found and accelerated.found and plain.period_cycles == accelerated.period_cycles == 1
    assert accelerated.residual <= 1e-6 and accelerated.cycles <= plain.cycles
    # the plain search stops within tol per cycle of the fixed point, at a distance of up to
    # tol / (1 - its contraction): a few tol
    assert np.max(np.abs(y_a - y_p)) <= 1e-5 * np.max(np.abs(y_p))
    assert np.max(np.abs(w_a - w_p)) <= 1e-5 * np.max(np.abs(w_p))


def test_depth_zero_is_the_plain_fixed_point_iteration():
    calls = []

    def halve(x):
        calls.append(x.copy())
        return 0.5 * x, np.ones_like(x)

    search = accelerated_fixed_point(halve, np.ones(3), tol=1e-3, max_periods=30, depth=0)
    # period k changes 2^-(k-1) into 2^-k: by 2^-k, first <= 1e-3 at k = 10
    assert search.converged and search.periods == 10 and len(calls) == 10
    np.testing.assert_array_equal(search.state, 0.5**10 * np.ones(3))
    assert len(search.plain_ends) == 11


def test_acceleration_solves_a_slow_linear_map_in_a_few_periods():
    """A contraction with a slow direction (0.99 per period, the plain search needs ~1,400 periods
    to 1e-6): Anderson on a linear map is GMRES, exact after as many periods as distinct rates."""
    rates = np.array([0.99, 0.9, 0.5, 0.1])
    target = np.array([1.0, -2.0, 3.0, 0.5])

    def period(x):
        return target + rates * (x - target), np.ones_like(x)

    search = accelerated_fixed_point(period, np.zeros(4), tol=1e-10, max_periods=60)
    assert search.converged and search.periods <= 7
    np.testing.assert_allclose(search.state, target, rtol=0, atol=1e-9)


def test_above_400_links_the_steady_state_is_found_in_few_cycles():
    n = 420  # the O(N) damping form; friction 0 keeps the linear chain's part cheap
    model = ClearanceChain(_chain(n, friction=0.0), 94e-6)
    assert model.damping_is_reduced
    t = np.arange(361) / 4 / (6 * 180.0)
    _, contact = simulate_chain(model, _cam(), t, n_modes=400, links=[0])
    ss = contact.steady_state
    assert contact.model == "clearance" and ss.found and ss.period_cycles == 1 and ss.residual <= 1e-6
    assert ss.cycles <= 15  # measured 10-12; the plain search took 20 at 400 links with friction


def test_uncoupled_system_is_stepped_mode_by_mode_as_the_dense_loop_steps_it():
    rng = np.random.default_rng(3)
    n = 5
    omega2 = np.array([0.0, 4.0, 90.0, 1e3, 4e4])
    c = 2 * 0.1 * np.sqrt(omega2) + 0.3
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))  # rotation: the same system, coupled coordinates
    modal = SecondOrderSystem(np.eye(n), np.diag(c), np.diag(omega2))
    coupled = SecondOrderSystem(np.eye(n), q @ np.diag(c) @ q.T, q @ np.diag(omega2) @ q.T)

    def friction(_t, _x, v):
        return -2.0 * np.tanh(v / 0.05)

    def rotated_friction(t, x, v):
        return q @ friction(t, q.T @ x, q.T @ v)

    grid = np.linspace(0.0, 0.5, 201)
    forces = np.sin(7 * grid)[:, None] * rng.normal(size=n)[None, :]
    y0 = rng.normal(size=2 * n)
    y_modal = propagate(modal, grid, forces, y0, friction)
    y_dense = propagate(coupled, grid, forces @ q.T, np.concatenate([q @ y0[:n], q @ y0[n:]]), rotated_friction)
    back = np.hstack([y_dense[:, :n] @ q, y_dense[:, n:] @ q])
    np.testing.assert_allclose(y_modal, back, rtol=0, atol=1e-11 * np.max(np.abs(back)))


def test_an_extrapolated_start_the_step_cannot_take_falls_back_to_the_last_period_end():
    from dynamics.errors import SolverDivergedError

    starts = []

    def period(x):
        starts.append(x.copy())
        if len(starts) == 3:  # the first extrapolated start (two periods of history)
            raise SolverDivergedError("diverged")
        return 2.0 + 0.5 * (x - 2.0), np.ones_like(x)

    search = accelerated_fixed_point(period, np.zeros(2), tol=1e-9, max_periods=30)
    np.testing.assert_array_equal(starts[3], 2.0 + 0.5 * (starts[1] - 2.0))  # the second period's end
    assert search.converged
    np.testing.assert_allclose(search.state, 2.0, rtol=0, atol=1e-8)

    def diverges(_x):
        raise SolverDivergedError("diverged")

    with pytest.raises(SolverDivergedError):  # a start the chain really reached is not hidden
        accelerated_fixed_point(diverges, np.zeros(2), tol=1.0, max_periods=3)
