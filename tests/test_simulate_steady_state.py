"""periodic_initial_state on its own: linear closed form, input checks, non-convergence reported."""

import numpy as np
import pytest

from dynamics.errors import DynamicsError, SolverFailedError
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.solvers import solve
from dynamics.solvers.steady_state import periodic_initial_state


def sdof(nonlinear=None):
    return SecondOrderSystem(np.array([[1.0]]), np.array([[0.4]]), np.array([[100.0]]), nonlinear)


def test_linear_periodic_state_matches_the_harmonic_closed_form():
    """x'' + 0.4 x' + 100 x = cos(w t): steady state X cos(w t - phase), X = 1/|100 - w^2 + 0.4 i w|.
    The force is held linearly between 400 samples per period, so the state is right to the hold's
    O((w h)^2) error, 1e-4 here."""
    w = 7.0
    t = np.linspace(0, 2 * np.pi / w, 401)
    x0, v0, info = periodic_initial_state(sdof(), SampledForce(t, np.cos(w * t)[:, None]))
    h = 1.0 / (100 - w**2 + 0.4j * w)
    assert info["iterations"] == 0
    assert x0[0] == pytest.approx(h.real, rel=1e-4)
    assert v0[0] == pytest.approx(-w * h.imag, rel=1e-4)


def test_nonlinear_periodic_state_repeats_after_one_period():
    """Smoothed Coulomb friction on a forced oscillator: Newton shooting converges and one period
    from the returned state comes back to it."""
    friction = lambda x, v: -2.0 * np.tanh(v / 1e-2)
    w = 7.0
    t = np.linspace(0, 2 * np.pi / w, 401)
    force = SampledForce(t, 20 * np.cos(w * t)[:, None])
    x0, v0, info = periodic_initial_state(sdof(friction), force)
    assert 1 <= info["iterations"] <= 30
    r = solve(sdof(friction), force, t, x0=x0, v0=v0)
    scale = np.max(np.abs(r.x))
    assert abs(r.x[-1, 0] - x0[0]) < 1e-7 * scale  # tol 1e-8 of the linear scale, margin for friction


def test_force_must_repeat_over_the_period():
    t = np.linspace(0, 1, 11)
    with pytest.raises(DynamicsError, match="force_over_period"):
        periodic_initial_state(sdof(), SampledForce(t, t[:, None]))


def test_non_convergence_is_reported():
    friction = lambda x, v: -2.0 * np.tanh(v / 1e-2)
    t = np.linspace(0, 2 * np.pi / 7.0, 401)
    with pytest.raises(SolverFailedError, match="steady state"):
        periodic_initial_state(
            sdof(friction), SampledForce(t, 20 * np.cos(7.0 * t)[:, None]), max_iterations=1, tol=1e-15
        )
