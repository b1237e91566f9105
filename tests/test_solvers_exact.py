"""The exact (first-order-hold matrix exponential) solver against independent closed forms."""

import numpy as np
import pytest

from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.solvers import METHODS, cache, solve, solve_with_diagnostics
from dynamics.solvers.exact import foh_matrices


def sdof_foh_closed_form(m, c, k, t, f, x0=0.0, v0=0.0):
    """Underdamped single DOF under a piecewise-linear force, interval by interval in closed form:
    x = x_p + e^(-zeta w tau) (A cos wd tau + B sin wd tau), x_p the ramp's particular solution."""
    w = np.sqrt(k / m)
    zeta = c / (2 * np.sqrt(k * m))
    wd = w * np.sqrt(1 - zeta**2)
    x, v = [x0], [v0]
    for i in range(t.size - 1):
        h = t[i + 1] - t[i]
        s = (f[i + 1] - f[i]) / h
        xp0 = f[i] / k - s * c / k**2
        vp = s / k
        a_ = x[-1] - xp0
        b_ = (v[-1] - vp + zeta * w * a_) / wd
        e = np.exp(-zeta * w * h)
        cs, sn = np.cos(wd * h), np.sin(wd * h)
        x.append(xp0 + s * h / k + e * (a_ * cs + b_ * sn))
        v.append(vp + e * ((-zeta * w * a_ + wd * b_) * cs + (-zeta * w * b_ - wd * a_) * sn))
    return np.array(x), np.array(v)


@pytest.mark.parametrize("k", [1e5, 1e8, 1e10])
@pytest.mark.parametrize("zeta", [0.0, 0.05, 0.13])
def test_single_dof_matches_closed_form_under_foh_force(k, zeta):
    m = 2.0
    c = 2 * zeta * np.sqrt(k * m)
    rng = np.random.default_rng(1)
    t = np.cumsum(np.r_[0.0, rng.uniform(0.5, 1.5, 60)]) * 1e-3  # uneven steps: several matrix sets
    f = rng.normal(0.0, 1e3, t.size)
    sys = SecondOrderSystem(np.array([[m]]), np.array([[c]]), np.array([[k]]))
    r = solve(sys, SampledForce(t, f[:, None]), t, x0=[1e-4], v0=[0.01])
    x_ref, v_ref = sdof_foh_closed_form(m, c, k, t, f, 1e-4, 0.01)
    # Both are exact; the only error is rounding in expm and in the trigonometric recurrences,
    # which grows with w*t (up to 1e4 rad here): 1e-9 of the response scale.
    assert np.max(np.abs(r.x[:, 0] - x_ref)) < 1e-9 * np.max(np.abs(x_ref))
    assert np.max(np.abs(r.v[:, 0] - v_ref)) < 1e-9 * np.max(np.abs(v_ref))
    # the reported acceleration satisfies the equation of motion at the samples
    np.testing.assert_allclose(m * r.a[:, 0], f - c * r.v[:, 0] - k * r.x[:, 0], rtol=0, atol=1e-9 * np.abs(f).max())


def ring(n, k, m, drive_k=None):
    """Closed ring of n masses m and springs k; drive_k grounds mass 0 (None: free ring)."""
    kk = np.zeros((n, n))
    for i in range(n):
        j = (i + 1) % n
        kk[i, i] += k
        kk[j, j] += k
        kk[i, j] -= k
        kk[j, i] -= k
    if drive_k is not None:
        kk[0, 0] += drive_k
    return kk


@pytest.mark.parametrize("n, j", [(8, 1), (85, 1), (85, 3), (20, 7)])
def test_free_ring_mode_oscillates_at_closed_form_frequency(n, j):
    k, m = 1e8, 2.0
    omega = 2 * np.sqrt(k / m) * np.sin(j * np.pi / n)
    shape = np.cos(2 * np.pi * j * np.arange(n) / n)
    sys = SecondOrderSystem(m * np.eye(n), np.zeros((n, n)), ring(n, k, m))
    t = np.linspace(0.0, 20 * 2 * np.pi / omega, 401)
    r = solve(sys, SampledForce(t, np.zeros((t.size, n))), t, x0=shape)
    # x(t) = shape cos(w t) exactly; rounding only (1e-9 of the amplitude after 20 periods)
    np.testing.assert_allclose(r.x, np.outer(np.cos(omega * t), shape), atol=1e-9)


@pytest.mark.parametrize("n, j", [(85, 1), (85, 84), (12, 5)])
def test_ring_with_held_driven_link_has_closed_form_frequencies(n, j):
    k, m = 1e8, 2.0
    omega = 2 * np.sqrt(k / m) * np.sin(j * np.pi / (2 * n))
    free = ring(n, k, m)[1:, 1:]  # link 0 held: the rest is a fixed-fixed line of n - 1 masses
    shape = np.sin(j * np.pi * np.arange(1, n) / n)
    sys = SecondOrderSystem(m * np.eye(n - 1), np.zeros((n - 1, n - 1)), free)
    t = np.linspace(0.0, 5 * 2 * np.pi / omega, 301)
    r = solve(sys, SampledForce(t, np.zeros((t.size, n - 1))), t, x0=shape)
    np.testing.assert_allclose(r.x, np.outer(np.cos(omega * t), shape), atol=1e-9)


def test_field_note_frequencies_n85_k1e8_m2():
    n, k, m = 85, 1e8, 2.0
    lam = np.linalg.eigvalsh(ring(n, k, m)[1:, 1:] / m)
    f_hz = np.sqrt(lam) / (2 * np.pi)
    assert f_hz[0] == pytest.approx(41.6, abs=0.05)  # field notes: f1 = 41.6 Hz
    assert f_hz[-1] == pytest.approx(2250, rel=2e-3)  # field notes: fmax about 2250 Hz


def test_matrices_are_cached_per_system_and_step():
    n = 6
    sys = SecondOrderSystem(np.eye(n), 0.01 * np.eye(n), ring(n, 1e4, 1.0, 1e4))
    a = foh_matrices(sys, 1e-3)
    assert foh_matrices(sys, 1e-3) is a
    assert foh_matrices(SecondOrderSystem(np.eye(n), 0.01 * np.eye(n), ring(n, 1e4, 1.0, 1e4)), 1e-3) is a
    assert foh_matrices(sys, 2e-3) is not a
    assert cache.size() <= cache.SIZE


def test_a_system_cannot_change_under_its_cached_matrices():
    """Cache entries are keyed by the system's contents, computed once per system: that is only
    sound because a system keeps its own read-only copies of the matrices."""
    n = 6
    stiffness = ring(n, 1e4, 1.0, 1e4)
    sys = SecondOrderSystem(np.eye(n), 0.01 * np.eye(n), stiffness)
    a = foh_matrices(sys, 1e-3)
    stiffness *= 2.0  # the caller's array, not the system's
    assert np.array_equal(sys.stiffness, stiffness / 2.0)
    assert foh_matrices(sys, 1e-3) is a
    assert foh_matrices(SecondOrderSystem(np.eye(n), 0.01 * np.eye(n), stiffness), 1e-3) is not a
    with pytest.raises(ValueError, match="read-only"):
        sys.stiffness[0, 0] = 0.0
    with pytest.raises(DynamicsError, match="system.damping: expected a real"):
        SecondOrderSystem(np.eye(2), [[1.0, 2.0], [3.0]], np.eye(2))


def test_force_knots_between_outputs_are_honoured():
    """A force sampled more finely than the outputs: the solver steps through every knot, so the
    result equals the run that outputs at every knot."""
    m, c, k = 1.0, 0.2, 100.0
    sys = SecondOrderSystem(np.array([[m]]), np.array([[c]]), np.array([[k]]))
    t_f = np.linspace(0, 2, 81)
    f = SampledForce(t_f, np.sin(3 * t_f)[:, None] + (t_f > 1)[:, None])
    fine = solve(sys, f, t_f)
    coarse = solve(sys, f, t_f[::8])
    np.testing.assert_allclose(coarse.x, fine.x[::8], atol=1e-13)


def test_nonlinear_force_splitting_is_second_order():
    """Heun splitting for a smooth nonlinear force (cubic spring): error falls about 4x per halving
    of the step (second order); the reference is the same scheme at a 16x finer step."""
    m, c, k = 1.0, 0.5, 400.0
    sys = SecondOrderSystem(np.array([[m]]), np.array([[c]]), np.array([[k]]), lambda x, v: -4e4 * x**3)
    t = np.linspace(0, 1, 51)
    f = SampledForce(t, np.full((t.size, 1), 10.0))
    ref = solve(sys, f, t, substeps=64).x
    errs = [np.max(np.abs(solve(sys, f, t, substeps=s).x - ref)) for s in (2, 4, 8)]
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all((rates > 1.8) & (rates < 2.3))


def test_bad_inputs_raise_dynamics_error():
    sys = SecondOrderSystem(np.eye(2), np.zeros((2, 2)), np.eye(2))
    t = np.linspace(0, 1, 5)
    f = SampledForce(t, np.zeros((5, 2)))
    with pytest.raises(DynamicsError, match="t_eval_s"):
        solve(sys, f, t[::-1])
    with pytest.raises(DynamicsError, match="force.values"):
        solve(sys, SampledForce(t, np.zeros((5, 3))), t)
    with pytest.raises(DynamicsError, match="x0"):
        solve(sys, f, t, x0=[1.0])
    with pytest.raises(DynamicsError, match="method"):
        solve(sys, f, t, method="euler")
    with pytest.raises(DynamicsError, match="options for exact"):
        solve(sys, f, t, rtol=1e-3)
    with pytest.raises(DynamicsError, match="substeps"):
        solve(sys, f, t, substeps=0)
    with pytest.raises(DynamicsError, match="system.mass"):
        solve(SecondOrderSystem(-np.eye(2), np.zeros((2, 2)), np.eye(2)), f, t)


def test_registry_describes_every_method():
    assert {
        "exact",
        "modal",
        "newmark",
        "hht",
        "central-difference",
        "rk45",
        "dop853",
        "radau",
        "bdf",
        "lsoda",
        "report-rk45",
    } <= set(METHODS)
    for name, info in METHODS.items():
        assert info.id == name and info.description
    assert METHODS["exact"].handles_nonlinear_force
    assert METHODS["report-rk45"].handles_nonlinear_force
    assert not METHODS["modal"].handles_nonlinear_force


def test_linear_only_methods_refuse_a_nonlinear_force():
    sys = SecondOrderSystem(np.eye(1), np.zeros((1, 1)), np.eye(1), lambda x, v: -np.sign(v))
    t = np.linspace(0, 1, 5)
    with pytest.raises(DynamicsError, match="cannot take a nonlinear force"):
        solve(sys, SampledForce(t, np.zeros((5, 1))), t, method="newmark")


def test_diagnostics_report_steps():
    sys = SecondOrderSystem(np.eye(1), np.zeros((1, 1)), np.eye(1))
    t = np.linspace(0, 1, 5)
    _, diag = solve_with_diagnostics(sys, SampledForce(t, np.zeros((5, 1))), t, substeps=3)
    assert diag["n_steps"] == 12


def test_every_method_accepts_exactly_its_listed_options():
    """Each registered option is accepted by its method (no option listed that the method lacks)."""
    sys = SecondOrderSystem(np.eye(1), 0.1 * np.eye(1), np.eye(1))
    t = np.linspace(0, 1, 11)
    f = SampledForce(t, np.zeros((11, 1)))
    values = {
        "substeps": 2,
        "n_modes": 1,
        "dt": 0.05,
        "alpha": -0.1,
        "rtol": 1e-6,
        "atol": 1e-9,
        "max_step": 0.5,
        "max_step_fraction": 0.2,
        "nip": 2,
    }
    for name, info in METHODS.items():
        opts = {k: values[k] for k in info.options}
        assert solve(sys, f, t, method=name, x0=[1.0], **opts).x.shape == (11, 1)


def test_too_coarse_a_step_for_a_stiff_nonlinear_force_is_reported_with_the_remedy():
    """A stiff velocity-dependent force g = -1e4 v (unit mass): at h = 1e-3 the splitting's
    h * |dg/dv| / m = 10 exceeds its limit 2 and the run diverges; 16 sub-steps (0.6) are stable and
    match the same damping put in the linear part. (A saturating force such as tanh friction cannot
    diverge; there a too-coarse step only chatters, which is why simulate() sets the sub-steps.)"""
    t = np.linspace(0, 0.5, 501)
    f = SampledForce(t, np.full((t.size, 1), 50.0))
    split = SecondOrderSystem(np.eye(1), np.array([[0.1]]), np.array([[100.0]]), lambda x, v: -1e4 * v)
    with pytest.raises(SolverDivergedError, match="raise `substeps`"):
        solve(split, f, t, x0=[0.0], v0=[1.0])
    linear = solve(SecondOrderSystem(np.eye(1), np.array([[1e4 + 0.1]]), np.array([[100.0]])), f, t, x0=[0.0], v0=[1.0])
    fine = solve(split, f, t, x0=[0.0], v0=[1.0], substeps=16)
    # second-order splitting at h * slope = 0.6 on a 1e-4 s time constant: 1 % of the response
    assert np.max(np.abs(fine.x - linear.x)) < 1e-2 * np.max(np.abs(linear.x))


def test_modal_construction_of_the_foh_matrices_equals_van_loan():
    # Classical (modal) damping takes the per-mode route; both are exact discretisations of the same
    # system, so they agree to rounding (the per-mode exponentials are of 4x4 matrices, the augmented
    # one of 3N x 3N: a few ulps times N).
    from dynamics.models.chain import ChainModel
    from dynamics.solvers.exact import _modal_foh, _van_loan, classical_modes
    from dynamics.solvers.mode_scan import mode_steps

    for n, k, zeta in ((2, 1e5, 0.02), (40, 9e7, 0.13), (12, 1e10, 0.05)):
        system = ChainModel(n, 2.0, k, damping_ratio=zeta).system()
        modes = classical_modes(system)
        assert modes is not None
        for h in (1e-5, 2.3e-4):
            for a, b in zip(_van_loan(system, h), _modal_foh(modes, mode_steps(modes.omega2, modes.damping, h))):
                assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max()


def test_non_classical_damping_is_not_taken_for_classical():
    from dynamics.models.mqp2012 import replica_system

    system, _ = replica_system("al6061-t6", 30, 0.0)  # the script's asymmetric damping
    from dynamics.solvers.exact import classical_modes

    assert classical_modes(system) is None


def test_the_report_models_complex_modes_are_too_ill_conditioned_to_step_in():
    """Why the report's own model is stepped with its dense exponential (README, Speed): its state
    matrix's eigenvectors at 85 links have a condition number near 1e13 (bench_dynamics prints it),
    so modal coordinates would lose about 13 of 16 digits. 1e10 leaves three decades of margin for
    the LAPACK build's own rounding in a near-defective eigenproblem."""
    from dynamics.models.mqp2012 import replica_system
    from dynamics.solvers._common import state_matrices

    system, _ = replica_system("al6061-t6", 85, 0.0)
    vectors = np.linalg.eig(state_matrices(system)[0])[1]
    assert np.linalg.cond(vectors) > 1e10


def _textbook_van_loan(system, h):
    """Van Loan's augmented exponential as written (all force columns, no scaling)."""
    from scipy.linalg import expm

    n = system.n_dof
    m_inv = np.linalg.inv(system.mass)
    aug = np.zeros((4 * n, 4 * n))
    aug[:n, n : 2 * n] = np.eye(n) * h
    aug[n : 2 * n, :n] = -m_inv @ system.stiffness * h
    aug[n : 2 * n, n : 2 * n] = -m_inv @ system.damping * h
    aug[n : 2 * n, 2 * n : 3 * n] = m_inv * h
    aug[2 * n : 3 * n, 3 * n :] = np.eye(n)
    e = expm(aug)
    q = e[: 2 * n, 3 * n :]
    return e[: 2 * n, : 2 * n], e[: 2 * n, 2 * n : 3 * n] - q, q


def test_van_loan_over_the_force_dofs_equals_the_textbook_one():
    """The solver's exponential (force columns restricted to the loaded DOFs, positions scaled by
    the frequency bound) against the textbook augmented one on the report's non-classical model.
    Both are exact; they differ by rounding of the unscaled textbook exponential (||A h|| up to 1e5,
    about 15 squarings, each adding a few ulps): measured 5e-15 of each block's largest entry, so
    1e-13 leaves room for another BLAS's rounding and would still catch a mis-scaled block."""
    from dynamics.models.mqp2012 import replica_system
    from dynamics.solvers.exact import _van_loan

    system, _ = replica_system("ti-grade2", 30, 0.0)
    inputs = (0, 7, 13)
    n = system.n_dof
    for h in (1e-5, 2.3e-4, 9.26e-4):
        phi_ref, g0_ref, g1_ref = _textbook_van_loan(system, h)
        phi, g0, g1 = _van_loan(system, h, inputs)
        for got, want in ((phi, phi_ref), (g0, g0_ref[:, inputs]), (g1, g1_ref[:, inputs])):
            for rows in (slice(0, n), slice(n, 2 * n)):
                for cols in (slice(0, n), slice(n, 2 * n)) if got.shape[1] == 2 * n else (slice(None),):
                    block = want[rows, cols]
                    assert np.abs(got[rows, cols] - block).max() <= 1e-13 * np.abs(block).max()


def test_a_force_on_few_dofs_gives_the_same_response_as_on_all():
    """The solver builds its exponential over the loaded DOFs only; a force with a negligible
    (1e-300 N) entry on every other DOF takes the all-DOF path and must give the same response."""
    from dynamics.models.mqp2012 import replica_system

    system, _ = replica_system("al6061-t6", 30, 0.0)
    t = np.linspace(0.0, 0.05, 101)
    sparse = np.zeros((t.size, 30))
    sparse[:, 0] = 1e3 * np.sin(200 * t)
    sparse[:, 7] = 50.0
    dense = sparse.copy()
    dense[dense == 0.0] = 1e-300
    x_sparse = solve(system, SampledForce(t, sparse), t).x
    x_dense = solve(system, SampledForce(t, dense), t).x
    assert np.abs(x_sparse - x_dense).max() <= 1e-12 * np.abs(x_dense).max()


def test_accelerations_from_the_modes_equal_the_equation_of_motion():
    """On the modal route the solver returns q'' = p - c q' - w^2 q mapped back, which is
    M^-1 (f - C v - K x) written in the modes: the same numbers to rounding (measured 1e-15 of the
    largest acceleration; 1e-12 leaves room for the 1e-10 tolerance on classical damping)."""
    from dynamics.models.chain import ChainModel
    from dynamics.solvers._common import accelerations, make_problem

    system = ChainModel(40, 2.03, 9.27e7, damping_ratio=0.13, preload_N=0.0).system()
    t = np.arange(121) / 1080.0
    rng = np.random.default_rng(11)
    force = SampledForce(t, rng.normal(0.0, 50.0, (t.size, 40)))
    x0, v0 = rng.normal(0.0, 1e-6, 40), rng.normal(0.0, 1e-3, 40)
    problem = make_problem(system, force, t, x0, v0, None)
    x, v, a, _ = METHODS["exact"].run(problem)
    assert a is not None  # the modal route was taken
    ref = accelerations(problem, x, v)
    assert np.abs(a - ref).max() <= 1e-12 * np.abs(ref).max()
    np.testing.assert_array_equal(solve(system, force, t, x0=x0, v0=v0).a, a)
