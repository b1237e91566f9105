"""Pieces every solver shares: input checks, force sampling, the state equation, divergence checks.

Solvers are unit-agnostic: they never assume SI, only consistency between the system matrices,
the force and the times.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.solvers.cache import cached

# (t, x, v) -> force (n,). The contract's nonlinear force g(x, v) is wrapped into this form so that
# a force that also depends on time (friction seen from a moving frame) can share the same code.
TimedForce = Callable[[float, np.ndarray, np.ndarray], np.ndarray]

try:
    from threadpoolctl import ThreadpoolController
except ImportError:  # optional: without it the loops run with the BLAS's own threading
    ThreadpoolController = None

# A state this many times larger than every scale the inputs can justify is treated as divergence.
DIVERGENCE_FACTOR = 1e6


@dataclass(frozen=True)
class Problem:
    """A checked, solver-ready problem: matrices, the force, output times and the initial state."""

    system: SecondOrderSystem
    force: SampledForce
    t_eval_s: np.ndarray
    x0: np.ndarray
    v0: np.ndarray
    extra_force: TimedForce | None  # system.nonlinear_force and any time-dependent force, summed

    @property
    def n(self) -> int:
        return self.system.n_dof


def check_system(system: SecondOrderSystem) -> None:
    """Square, finite matrices and a positive-definite mass; checked once per system (cached)."""
    cached(("checked", *system.cache_key), lambda: _check_matrices(system))


def _check_matrices(system: SecondOrderSystem) -> None:
    n = system.mass.shape[0] if np.ndim(system.mass) == 2 else -1
    for name in ("mass", "damping", "stiffness"):
        mat = np.asarray(getattr(system, name))
        if mat.shape != (n, n) or n < 1:
            raise DynamicsError(f"system.{name}: expected a square (n, n) array, got shape {mat.shape}")
        if not np.all(np.isfinite(mat)):
            raise DynamicsError(f"system.{name}: expected finite entries")
    if is_diagonal(system.mass):
        positive = bool(np.all(np.diag(system.mass) > 0.0))
    else:
        try:
            np.linalg.cholesky(0.5 * (system.mass + system.mass.T))
            positive = True
        except np.linalg.LinAlgError:
            positive = False
    if not positive:
        raise DynamicsError("system.mass: expected a symmetric positive-definite matrix")


def make_problem(
    system: SecondOrderSystem,
    force: SampledForce,
    t_eval_s: np.ndarray,
    x0,
    v0,
    time_dependent_force: TimedForce | None,
) -> Problem:
    check_system(system)
    n = system.n_dof
    t = np.asarray(t_eval_s, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
        raise DynamicsError("t_eval_s: expected at least two finite, strictly increasing times")
    ft = np.asarray(force.t_s, dtype=float)
    fv = np.asarray(force.values, dtype=float)
    if ft.ndim != 1 or ft.size < 2 or np.any(np.diff(ft) <= 0.0):
        raise DynamicsError("force.t_s: expected at least two strictly increasing times")
    if fv.shape != (ft.size, n):
        raise DynamicsError(f"force.values: expected shape ({ft.size}, {n}), got {fv.shape}")
    if not np.all(np.isfinite(fv)):
        raise DynamicsError("force.values: expected finite values")
    x0 = _initial(x0, n, "x0")
    v0 = _initial(v0, n, "v0")
    return Problem(system, SampledForce(ft, fv), t, x0, v0, _combined_force(system, time_dependent_force))


def _initial(value, n: int, name: str) -> np.ndarray:
    if value is None:
        return np.zeros(n)
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise DynamicsError(f"{name}: expected {n} finite values, got shape {np.shape(value)}")
    return arr


class _CombinedForce:
    """g(t, x, v): the system's g(x, v) plus an optional time-dependent force. `batch` evaluates it
    at many samples at once, vectorised for a component that offers a `batch` method itself."""

    def __init__(self, state_force, timed):
        self.state_force = state_force
        self.timed = timed

    def __call__(self, t: float, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        out = 0.0
        if self.state_force is not None:
            out = out + np.asarray(self.state_force(x, v), dtype=float)
        if self.timed is not None:
            out = out + np.asarray(self.timed(t, x, v), dtype=float)
        return out

    def batch(self, t: np.ndarray, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        out = np.zeros_like(x)
        if self.state_force is not None:
            out += np.array([self.state_force(xi, vi) for xi, vi in zip(x, v)], dtype=float)
        if self.timed is not None:
            if hasattr(self.timed, "batch"):
                out += self.timed.batch(t, x, v)
            else:
                out += np.array([self.timed(ti, xi, vi) for ti, xi, vi in zip(t, x, v)], dtype=float)
        return out


def _combined_force(system: SecondOrderSystem, timed: TimedForce | None):
    if system.nonlinear_force is None and timed is None:
        return None
    if system.nonlinear_force is None and hasattr(timed, "batch"):
        return timed  # already has the combined form's interface; skip a call layer per step
    return _CombinedForce(system.nonlinear_force, timed)


def force_at(force: SampledForce, t: np.ndarray) -> np.ndarray:
    """Vectorised SampledForce.at: first-order hold inside, linear extrapolation outside. At the
    force's own sample times (the usual case) these are its values: returned as a read-only view."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.shape == force.t_s.shape and np.array_equal(t, force.t_s):
        values = force.values.view()
        values.flags.writeable = False
        return values
    i = np.clip(np.searchsorted(force.t_s, t, side="right") - 1, 0, len(force.t_s) - 2)
    w = (t - force.t_s[i]) / (force.t_s[i + 1] - force.t_s[i])
    return (1.0 - w)[:, None] * force.values[i] + w[:, None] * force.values[i + 1]


def state_matrices(system: SecondOrderSystem) -> tuple[np.ndarray, np.ndarray]:
    """A and B of y' = A y + B f with y = [x; v]."""
    n = system.n_dof
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    b = np.zeros((2 * n, n))
    if is_diagonal(system.mass):
        m_inv = 1.0 / np.diag(system.mass)
        a[n:, :n] = -m_inv[:, None] * system.stiffness
        a[n:, n:] = -m_inv[:, None] * system.damping
        b[n:, :] = np.diag(m_inv)
        return a, b
    a[n:, :n] = -np.linalg.solve(system.mass, system.stiffness)
    a[n:, n:] = -np.linalg.solve(system.mass, system.damping)
    b[n:, :] = np.linalg.inv(system.mass)
    return a, b


def accelerations(problem: Problem, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """a = M^-1 (f(t) + g(t, x, v) - C v - K x) at every output time."""
    sys = problem.system
    rhs = force_at(problem.force, problem.t_eval_s) - v @ sys.damping.T - x @ sys.stiffness.T
    if problem.extra_force is not None:
        rhs += problem.extra_force.batch(problem.t_eval_s, x, v)
    if is_diagonal(sys.mass):
        return rhs / np.diag(sys.mass)
    return np.linalg.solve(sys.mass, rhs.T).T


def divergence_bounds(problem: Problem) -> tuple[float, float]:
    """Largest |x| and |v| a stable solution could plausibly reach, times DIVERGENCE_FACTOR.

    Scales: the initial state, the free-mass response to the largest force over the whole span
    (an upper estimate for a spring-restrained, damped system), and the static deflection.
    """
    sys = problem.system
    span = problem.t_eval_s[-1] - problem.t_eval_s[0]
    m_min = _smallest_mass(sys.mass)
    f_max = float(np.max(np.abs(problem.force.values)))
    if problem.extra_force is not None:
        g0 = problem.extra_force(problem.t_eval_s[0], problem.x0, problem.v0)
        f_max = max(f_max, 10.0 * float(np.max(np.abs(g0))))
    x0 = float(np.max(np.abs(problem.x0)))
    v0 = float(np.max(np.abs(problem.v0)))
    omega_max = frequency_bound(sys)
    x_scale = x0 + v0 * span + f_max * span**2 / m_min + f_max / max(omega_max**2 * m_min, 1e-300)
    v_scale = v0 + x0 * omega_max + f_max * span / m_min
    tiny = np.finfo(float).tiny
    return DIVERGENCE_FACTOR * max(x_scale, tiny), DIVERGENCE_FACTOR * max(v_scale, tiny)


def is_diagonal(matrix: np.ndarray) -> bool:
    return np.count_nonzero(matrix) == np.count_nonzero(np.diagonal(matrix))


def _smallest_mass(mass: np.ndarray) -> float:
    if is_diagonal(mass):
        return float(np.min(np.diag(mass)))
    return float(np.min(np.linalg.eigvalsh(0.5 * (mass + mass.T))))


def frequency_bound(system: SecondOrderSystem) -> float:
    """Upper bound on the largest natural frequency: Gershgorin on M^-1 K (no eigensolve); cached."""
    return cached(("frequency bound", *system.cache_key), lambda: _gershgorin_frequency(system))


def _gershgorin_frequency(system: SecondOrderSystem) -> float:
    mass = system.mass
    if is_diagonal(mass):
        m_inv_k = system.stiffness / np.diag(mass)[:, None]
    else:
        m_inv_k = np.linalg.solve(mass, system.stiffness)
    return float(np.sqrt(np.max(np.sum(np.abs(m_inv_k), axis=1))))


def max_frequency(system: SecondOrderSystem) -> float:
    """Largest undamped natural frequency (rad per time unit) of (K, M)."""
    from scipy.linalg import eigh

    k = 0.5 * (system.stiffness + system.stiffness.T)
    m = 0.5 * (system.mass + system.mass.T)
    lam = eigh(k, m, eigvals_only=True)
    return float(np.sqrt(max(lam[-1], 0.0)))


def check_finite(method: str, t: np.ndarray, x: np.ndarray, v: np.ndarray, bounds, step: str) -> None:
    """Raise SolverDivergedError at the first non-finite or runaway sample."""
    x_bound, v_bound = bounds
    if np.abs(x).max() <= x_bound and np.abs(v).max() <= v_bound:  # False for nan: then find where
        return
    bad = ~np.isfinite(x).all(axis=1) | ~np.isfinite(v).all(axis=1)
    bad |= (np.abs(x) > x_bound).any(axis=1) | (np.abs(v) > v_bound).any(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        raise SolverDivergedError(
            f"{method}: solution diverged at t = {t[k]:.6g} ({step}); |x| or |v| exceeded "
            f"{x_bound:.3g} / {v_bound:.3g} or became non-finite"
        )


_controller = None


def serial_blas():
    """Context limiting BLAS to one thread around the solvers' step loops.

    The loops make thousands of small matrix-vector products; a threaded BLAS hands each to its
    threads, which on a 2-core machine busy with other jobs made the 85-link friction run 8x
    slower (0.72 s vs 0.09 s per cam; on an idle machine the two are equal, see bench_dynamics).
    Uses threadpoolctl when installed; otherwise does nothing.
    """
    global _controller
    if ThreadpoolController is None:
        return contextlib.nullcontext()
    if _controller is None:
        import scipy.linalg  # noqa: F401  (load scipy's BLAS too, so the controller sees it)

        _controller = ThreadpoolController()
    return _controller.limit(limits=1, user_api="blas")
