"""Every solver method against the exact one on closed driven chains (several N, k and damping),
each with the error its theory predicts."""

import numpy as np
import pytest
from scipy.linalg import eigh
from test_solvers_exact import ring

from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.solvers import solve, solve_with_diagnostics
from dynamics.solvers.central_difference import stability_limit

CASES = [(2, 1e5, 0.02), (8, 1e8, 0.13), (20, 1e10, 0.05)]


def driven_ring(n, k, m, zeta):
    """Ring of n masses, link 0 grounded by a drive spring k, modal damping zeta on every mode."""
    kk = ring(n, k, m, drive_k=k)
    mm = m * np.eye(n)
    lam, phi = eigh(kk, mm)
    omega = np.sqrt(lam)
    cc = mm @ phi @ np.diag(2 * zeta * omega) @ phi.T @ mm
    return SecondOrderSystem(mm, cc, kk), omega


def cycloidal_drive(n, k, omega1, samples=201):
    """Drive spring pulled through a 0.1 m cycloidal rise lasting two first-mode periods, then held;
    the span is four periods so the residual vibration is in the record."""
    period = 2 * np.pi / omega1
    t = np.linspace(0.0, 4 * period, samples)
    u = np.clip(t / (2 * period), 0.0, 1.0)
    z = 0.1 * (u - np.sin(2 * np.pi * u) / (2 * np.pi))
    f = np.zeros((t.size, n))
    f[:, 0] = k * z
    return t, SampledForce(t, f)


def setup(n, k, zeta):
    sys, omega = driven_ring(n, k, 2.0, zeta)
    t, f = cycloidal_drive(n, k, omega[0])
    ref = solve(sys, f, t, method="exact")
    return sys, omega, t, f, ref


def rel_err(r, ref):
    return np.max(np.abs(r.x - ref.x)) / np.max(np.abs(ref.x))


@pytest.mark.parametrize("n, k, zeta", CASES)
def test_modal_with_all_modes_equals_exact(n, k, zeta):
    sys, _, t, f, ref = setup(n, k, zeta)
    # both exact for the FOH force; rounding only
    assert rel_err(solve(sys, f, t, method="modal"), ref) < 1e-10


@pytest.mark.parametrize("method", ["newmark", "hht"])
@pytest.mark.parametrize("n, k, zeta", CASES)
def test_newmark_family_converges_at_second_order(method, n, k, zeta):
    sys, _, t, f, ref = setup(n, k, zeta)
    h = t[1] - t[0]
    errs = [rel_err(solve(sys, f, t, method=method, dt=h / s), ref) for s in (2, 4)]
    # period error ~ (w h)^2 / 12: halving the step divides the error by 4 (3.5..4.5 allows for the
    # higher-order terms at w1 h = 0.06); at w1 h = 0.06 it is already below 2e-4 of the response
    assert 3.5 < errs[0] / errs[1] < 4.5
    assert errs[0] < 2e-4


@pytest.mark.parametrize("n, k, zeta", CASES)
def test_central_difference_converges_at_second_order_below_the_limit(n, k, zeta):
    sys, _, t, f, ref = setup(n, k, zeta)
    dt0 = min(0.5 * stability_limit(sys), (t[1] - t[0]) / 2)
    errs = [rel_err(solve(sys, f, t, method="central-difference", dt=dt0 / s), ref) for s in (1, 2)]
    assert 3.5 < errs[0] / errs[1] < 4.5  # second order, as for Newmark
    assert errs[1] < 1e-4


@pytest.mark.parametrize("method", ["rk45", "dop853", "radau", "bdf", "lsoda"])
@pytest.mark.parametrize("n, k, zeta", CASES)
def test_solve_ivp_methods_are_tolerance_bounded(method, n, k, zeta):
    sys, _, t, f, ref = setup(n, k, zeta)
    # default rtol 1e-8: local errors of 1e-8 accumulate over a few thousand steps and the force's
    # kinks at the samples; 1e-6 of the response is the bound the tolerance can promise
    assert rel_err(solve(sys, f, t, method=method), ref) < 1e-6
    # a looser tolerance gives a larger but still bounded error
    assert rel_err(solve(sys, f, t, method=method, rtol=1e-5, atol=1e-9), ref) < 1e-3


def test_central_difference_stable_just_below_limit_and_refused_just_above():
    sys, omega, t, f, ref = setup(8, 1e8, 0.0)
    limit = stability_limit(sys)
    assert limit == pytest.approx(2 / omega[-1], rel=1e-12)
    t_fine = np.arange(0, 4000) * (0.999 * limit)
    f_fine = SampledForce(t_fine, np.zeros((t_fine.size, 8)))
    x0 = np.linspace(-1, 1, 8) * 1e-3
    r = solve(sys, f_fine, t_fine, method="central-difference", x0=x0)
    # undamped and just stable: the energy-like amplitude neither grows nor is lost
    assert np.max(np.abs(r.x)) < 10 * np.max(np.abs(x0))
    t_over = np.arange(0, 4000) * (1.001 * limit)
    with pytest.raises(SolverDivergedError, match=r"central-difference: step .* exceeds the stability limit"):
        solve(sys, SampledForce(t_over, np.zeros((t_over.size, 8))), t_over, method="central-difference", x0=x0)


def test_divergence_of_an_unstable_nonlinear_force_is_reported_not_returned():
    """A destabilising force (negative damping far beyond the damping) blows the solution up:
    every method that takes the force raises SolverDivergedError instead of returning numbers."""
    sys = SecondOrderSystem(np.eye(1), np.array([[0.1]]), np.array([[100.0]]), lambda x, v: 40.0 * v)
    t = np.linspace(0, 20, 401)
    f = SampledForce(t, np.zeros((t.size, 1)))
    for method in ("exact", "report-rk45", "rk45", "central-difference"):
        with pytest.raises(SolverDivergedError, match=method):
            solve(sys, f, t, method=method, x0=[1e-3])


def test_modal_truncation_converges_in_relative_coordinates():
    """Base excitation written relative to the input (force -M 1 z''): the error of keeping only the
    lowest modes falls steadily with their number (the first mode carries most of the mass)."""
    n, k = 40, 1e8
    sys, omega = driven_ring(n, k, 2.0, 0.13)
    period = 2 * np.pi / omega[0]
    t = np.linspace(0.0, 4 * period, 401)
    u = np.clip(t / (2 * period), 0.0, 1.0)
    zdd = 0.1 / (2 * period) ** 2 * 2 * np.pi * np.sin(2 * np.pi * u) * (t < 2 * period)
    f = SampledForce(t, -np.outer(zdd, sys.mass @ np.ones(n)))
    ref = solve(sys, f, t, method="exact")
    errs = [rel_err(solve(sys, f, t, method="modal", n_modes=r), ref) for r in (1, 3, 10, 30, 40)]
    assert all(a > b for a, b in zip(errs, errs[1:]))
    assert errs[2] < 0.05 and errs[-1] < 1e-10


def test_modal_truncation_stalls_in_absolute_coordinates():
    """The same chain forced through the drive spring (absolute coordinates): the static response of
    the cut modes is lost, so keeping half the modes still leaves a large error."""
    n, k = 40, 1e8
    sys, omega = driven_ring(n, k, 2.0, 0.13)
    t, f = cycloidal_drive(n, k, omega[0], 401)
    ref = solve(sys, f, t, method="exact")
    assert rel_err(solve(sys, f, t, method="modal", n_modes=20), ref) > 1e-3


def test_modal_refuses_non_classical_damping():
    sys = SecondOrderSystem(
        np.diag([1.0, 2.0]), np.array([[1.0, 0.0], [0.0, 0.0]]), np.array([[2.0, -1.0], [-1.0, 1.0]])
    )
    t = np.linspace(0, 1, 5)
    with pytest.raises(DynamicsError, match="classical damping"):
        solve(sys, SampledForce(t, np.zeros((5, 2))), t, method="modal")


def test_hht_alpha_damps_high_modes_and_checks_its_range():
    """HHT with alpha < 0 dissipates a mode at w h = 10; Newmark (alpha 0) keeps its amplitude."""
    sys = SecondOrderSystem(np.eye(1), np.zeros((1, 1)), np.array([[1e4]]))
    t = np.linspace(0, 0.1 * 200, 201)  # w h = 100 * 0.1 = 10
    f = SampledForce(t, np.zeros((t.size, 1)))
    newmark = solve(sys, f, t, method="newmark", x0=[1.0])
    hht = solve(sys, f, t, method="hht", alpha=-0.3, x0=[1.0])
    energy = lambda r: 0.5 * r.v[-1, 0] ** 2 + 0.5 * 1e4 * r.x[-1, 0] ** 2
    assert energy(newmark) == pytest.approx(0.5e4, rel=1e-9)  # trapezoidal rule conserves energy
    assert energy(hht) < 1e-3 * 0.5e4
    with pytest.raises(DynamicsError, match="alpha"):
        solve(sys, f, t, method="hht", alpha=-0.5)


def test_central_difference_needs_even_outputs():
    sys = SecondOrderSystem(np.eye(1), np.zeros((1, 1)), np.eye(1))
    t = np.array([0.0, 0.1, 0.3])
    with pytest.raises(DynamicsError, match="equally spaced"):
        solve(sys, SampledForce(t, np.zeros((3, 1))), t, method="central-difference")


def test_central_difference_reports_its_limit_in_diagnostics():
    sys, _, t, f, _ = setup(8, 1e8, 0.13)
    _, diag = solve_with_diagnostics(sys, f, t, method="central-difference", dt=0.5 * stability_limit(sys))
    assert diag["stability_limit"] == pytest.approx(stability_limit(sys))


@pytest.mark.parametrize(
    "method, opts, rel_tol",
    [
        ("rk45", {}, 1e-6),  # rtol 1e-8, tolerance-bounded (measured 2e-8)
        ("dop853", {}, 1e-6),
        ("radau", {}, 1e-6),
        ("bdf", {}, 1e-6),  # measured 8e-8
        ("lsoda", {}, 1e-6),
        ("report-rk45", {}, 1e-8),  # MaxStep 0.1 h: w h = 0.02 per step (measured 1e-10)
        ("central-difference", {"dt": 1e-4}, 5e-6),  # second order: measured 1.6e-6, 4.1e-7 at half dt
    ],
)
def test_nonlinear_force_methods_agree_on_a_duffing_oscillator(method, opts, rel_tol):
    """Hardening spring g = -4e4 x^3 with damping under a step force. Reference: the exact method's
    second-order splitting at 128 and 64 sub-steps, Richardson-extrapolated (changes by 8e-11 of
    the response when both step counts double)."""
    sys = SecondOrderSystem(np.array([[1.0]]), np.array([[0.5]]), np.array([[400.0]]), lambda x, v: -4e4 * x**3)
    t = np.linspace(0, 1, 101)
    f = SampledForce(t, np.full((t.size, 1), 10.0))
    ref = (4 * solve(sys, f, t, substeps=128).x - solve(sys, f, t, substeps=64).x) / 3
    r = solve(sys, f, t, method=method, **opts)
    assert np.max(np.abs(r.x - ref)) < rel_tol * np.max(np.abs(ref))
