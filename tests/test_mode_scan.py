"""The blocked modal recurrence (dynamics.solvers.mode_scan) against the step-by-step recurrence and
a closed form.

Both compute the same sums of the same products, regrouped, so they agree to rounding: the bound
1e-12 of the largest state is ~4500 ulps, room for the T / L chained block starts (each a few ulps)
and nothing more.
"""

import numpy as np
import pytest
from test_solvers_exact import sdof_foh_closed_form

from dynamics.models.chain import ChainModel
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.solvers import solve
from dynamics.solvers.exact import _van_loan
from dynamics.solvers.expm_stack import expm_stack
from dynamics.solvers.mode_scan import (
    MAX_BLOCK,
    block_kernel,
    block_length,
    mode_steps,
    propagate_modes,
    propagate_modes_stepwise,
)

H = 1e-3
# rigid, undamped, light, critically damped and overdamped modes (omega^2, damping coefficient)
OMEGA2 = np.array([0.0, 100.0**2, 300.0**2, 2e3**2, 5e3**2, 4e4**2])
DAMPING = np.array([0.0, 0.0, 2 * 0.05 * 300.0, 2 * 1.0 * 2e3, 2 * 3.0 * 5e3, 2 * 0.13 * 4e4])


def stepwise(steps, p, s0, which=None):
    """The recurrence one step at a time; step k uses steps[which[k]] when steps is a list."""
    out = np.empty((p.shape[0], 2, p.shape[1]))
    out[0] = s0
    for k in range(p.shape[0] - 1):
        st = steps if which is None else steps[which[k]]
        out[k + 1] = np.einsum("rij,jr->ir", st.e, out[k]) + p[k] * st.g0.T + p[k + 1] * st.g1.T
    return out


@pytest.mark.parametrize("n_steps", [1, 2, 3, 7, 36, 37, 180, 1500])
def test_blocks_equal_the_step_by_step_recurrence(n_steps):
    rng = np.random.default_rng(n_steps)
    steps = mode_steps(OMEGA2, DAMPING, H)
    p = rng.normal(size=(n_steps + 1, OMEGA2.size))
    s0 = rng.normal(size=(2, OMEGA2.size))
    ref = stepwise(steps, p, s0)
    got = propagate_modes(steps, block_kernel(steps.e, block_length(n_steps)), p, s0)
    assert got.shape == ref.shape
    assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()


def test_any_block_length_gives_the_same_states():
    rng = np.random.default_rng(5)
    steps = mode_steps(OMEGA2, DAMPING, H)
    p = rng.normal(size=(50, OMEGA2.size))
    s0 = rng.normal(size=(2, OMEGA2.size))
    ref = stepwise(steps, p, s0)
    for length in (1, 2, 7, 49, 64):
        got = propagate_modes(steps, block_kernel(steps.e, length), p, s0)
        assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()


def test_block_length_is_about_the_square_root_and_capped():
    assert block_length(1) == 1
    assert block_length(180) == 10
    assert block_length(10**6) == MAX_BLOCK


def test_stepwise_variant_on_an_uneven_grid():
    rng = np.random.default_rng(2)
    steps = [mode_steps(OMEGA2, DAMPING, h) for h in (H, 0.4 * H)]
    which = rng.integers(0, 2, 40)
    p = rng.normal(size=(41, OMEGA2.size))
    s0 = rng.normal(size=(2, OMEGA2.size))
    ref = stepwise(steps, p, s0, which)
    got = propagate_modes_stepwise(steps, which, p, s0)
    assert np.abs(got - ref).max() <= 1e-13 * np.abs(ref).max()


def test_exact_solver_on_a_uniform_grid_matches_the_closed_form():
    # one DOF, uniform steps: the exact solver takes the blocked modal route
    m, k, zeta = 2.0, 1e8, 0.13
    c = 2 * zeta * np.sqrt(k * m)
    t = np.arange(401) * 1e-4
    f = np.random.default_rng(3).normal(0.0, 1e3, t.size)
    x, v = sdof_foh_closed_form(m, c, k, t, f, x0=1e-6, v0=-2e-3)
    r = solve(
        SecondOrderSystem(np.array([[m]]), np.array([[c]]), np.array([[k]])),
        SampledForce(t, f[:, None]),
        t,
        x0=[1e-6],
        v0=[-2e-3],
    )
    # the closed form's own rounding: cos/sin of w h and the particular solution, ~1e-13 relative
    assert np.abs(r.x[:, 0] - x).max() <= 1e-11 * np.abs(x).max()
    assert np.abs(r.v[:, 0] - v).max() <= 1e-11 * np.abs(v).max()


def test_exact_solver_on_the_chain_matches_the_dense_van_loan_recurrence():
    # the 85-link chain from a moving start: modal blocks against the dense (3N x 3N) exponential
    model = ChainModel(85, 2.03, 9.27e7, damping_ratio=0.13, preload_N=0.0)
    system = model.system()
    t = np.arange(181) / 1080.0
    rng = np.random.default_rng(4)
    forces = rng.normal(0.0, 10.0, (t.size, 85))
    x0, v0 = rng.normal(0.0, 1e-6, 85), rng.normal(0.0, 1e-3, 85)
    phi, g0, g1 = _van_loan(system, t[1] - t[0])
    y = np.empty((t.size, 170))
    y[0] = np.r_[x0, v0]
    for i in range(t.size - 1):
        y[i + 1] = phi @ y[i] + g0 @ forces[i] + g1 @ forces[i + 1]
    r = solve(system, SampledForce(t, forces), t, x0=x0, v0=v0)
    assert np.abs(r.x - y[:, :85]).max() <= 1e-11 * np.abs(y[:, :85]).max()
    assert np.abs(r.v - y[:, 85:]).max() <= 1e-11 * np.abs(y[:, 85:]).max()


def test_stacked_exponential_equals_scipy_matrix_by_matrix():
    """One squaring count for the whole stack (set by its largest norm): the small matrices are
    squared more often than scipy would, each squaring adding a few ulps; 1e-13 of each matrix's
    exponential covers the ~14 extra squarings a 1e-4 -> 50 norm spread costs. The matrices are
    damped-oscillator-like (skew part plus a dissipative one), as the solver's are: a matrix whose
    exponential grows like e^50 would amplify any method's rounding by its condition number."""
    from scipy.linalg import expm

    rng = np.random.default_rng(7)
    norms = np.logspace(-4, np.log10(50.0), 12)
    g = rng.normal(size=(12, 4, 4))
    a = g - g.transpose(0, 2, 1) - 0.2 * g @ g.transpose(0, 2, 1)
    a *= (norms / np.abs(a).sum(axis=1).max(axis=1))[:, None, None]
    got = expm_stack(a)
    for g, x in zip(got, a):
        ref = expm(x)
        assert np.abs(g - ref).max() <= 1e-13 * np.abs(ref).max()
    single = a[-1] + np.triu(a[-1], 1) * 5.0  # one 2-D matrix, unequal row and column sums
    ref = expm(single)
    assert np.abs(expm_stack(single) - ref).max() <= 1e-13 * np.abs(ref).max()
    identity = np.broadcast_to(np.eye(4), (3, 4, 4))
    np.testing.assert_allclose(expm_stack(np.zeros((3, 4, 4))), identity, rtol=0, atol=1e-15)


def test_mode_steps_equal_the_textbook_4x4_van_loan():
    """The balanced (q scaled by max(omega, 1/h)) batched construction against scipy's exponential
    of each mode's unscaled 4x4 augmented matrix, for rigid, undamped, light, critically damped,
    overdamped and stiff modes: both exact, so rounding only (measured below 1e-14)."""
    from scipy.linalg import expm

    for h in (1e-5, H, 2.3e-2):
        steps = mode_steps(OMEGA2, DAMPING, h)
        for i, (w2, c) in enumerate(zip(OMEGA2, DAMPING)):
            aug = np.zeros((4, 4))
            aug[0, 1], aug[1, 0], aug[1, 1], aug[1, 2], aug[2, 3] = h, -w2 * h, -c * h, h, 1.0
            ex = expm(aug)
            for got, want in ((steps.e[i], ex[:2, :2]), (steps.g0[i], ex[:2, 2] - ex[:2, 3]), (steps.g1[i], ex[:2, 3])):
                for row in (0, 1):  # q and q' rows have different units: compare each on its own
                    assert np.abs(got[row] - want[row]).max() <= 1e-12 * np.abs(want[row]).max()
