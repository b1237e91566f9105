"""Periodic steady state computed directly, not by integrating until the transient dies.

For a periodic force over one period T, the state y = [x; v] after one period is
P(y0) = Phi_T y0 + r for the linear model (Phi_T the exact one-period propagator, the product of the
first-order-hold step matrices; r the response from rest). The periodic state solves
(I - Phi_T) y0 = r: one linear solve. I - Phi_T is invertible whenever every mode is damped and
none is a rigid-body mode (the chain's drive spring grounds it).

With a nonlinear force (friction), or a method other than `exact`, P is evaluated by that method
and the state found by Newton shooting with the linear monodromy as the Jacobian:

    y0 <- y0 + (I - Phi_T)^-1 (P(y0) - y0),

started from the periodic state of the linear model under the nonlinear force evaluated along the
linear model's periodic motion (a cheap, vectorised first correction). For the linear model and
`exact` this stops at once; for a friction force that is small next to the elastic forces each
iteration cuts the residual by roughly the ratio of the friction's effect to the elastic response
(3-4 period runs for the 85-link chain at mu = 0.35). Converged when the period residual is
below `tol` times the state's scale (largest |x| and |v| over the period); otherwise
SolverFailedError.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from dynamics.errors import DynamicsError, SolverFailedError
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.solvers import solve_with_diagnostics
from dynamics.solvers._common import _combined_force, serial_blas
from dynamics.solvers.cache import cached
from dynamics.solvers.exact import _steps, foh_matrices, propagate


def monodromy(system: SecondOrderSystem, grid: np.ndarray) -> np.ndarray:
    """Exact one-period propagator of the linear model over the steps of `grid`."""
    reps, which = _steps(grid)
    if reps.size == 1:
        return np.linalg.matrix_power(foh_matrices(system, reps[0])[0], grid.size - 1)
    out = np.eye(2 * system.n_dof)
    for k in range(grid.size - 1):
        out = foh_matrices(system, reps[which[k]])[0] @ out
    return out


def _periodic_lu(system: SecondOrderSystem, grid: np.ndarray):
    """LU of I - Phi_T, cached per system and step pattern: every cam on one chain and one period
    grid shares it."""
    key = ("periodic LU", *system.cache_key, np.diff(grid).round(15).tobytes())
    return cached(key, lambda: lu_factor(np.eye(2 * system.n_dof) - monodromy(system, grid)))


def periodic_initial_state(
    system: SecondOrderSystem,
    force_over_period: SampledForce,
    *,
    method: str = "exact",
    time_dependent_force=None,
    tol: float = 1e-8,
    max_iterations: int = 30,
    **options,
) -> tuple[np.ndarray, np.ndarray, dict]:
    """(x0, v0, info) at force_over_period.t_s[0] such that the response repeats after one period,
    the period being the span of force_over_period.t_s (the force must take equal values at both
    ends)."""
    grid = np.asarray(force_over_period.t_s, dtype=float)
    f = np.asarray(force_over_period.values, dtype=float)
    scale_f = np.max(np.abs(f)) if f.size else 0.0
    if np.max(np.abs(f[-1] - f[0])) > 1e-6 * max(scale_f, np.finfo(float).tiny):
        raise DynamicsError("force_over_period: expected equal force at both ends of the period")
    n = system.n_dof
    lu = _periodic_lu(system, grid)
    with serial_blas(), np.errstate(over="ignore", invalid="ignore"):
        r = propagate(system, grid, f, np.zeros(2 * n))[-1]
    y0 = lu_solve(lu, r)
    linear_exact = method == "exact" and system.nonlinear_force is None and time_dependent_force is None
    info = {"iterations": 0, "residual": 0.0}
    if linear_exact:
        return y0[:n], y0[n:], info
    with serial_blas(), np.errstate(over="ignore", invalid="ignore"):
        y_lin = propagate(system, grid, f, y0)
    scale = np.concatenate([np.full(n, np.max(np.abs(y_lin[:, :n]))), np.full(n, np.max(np.abs(y_lin[:, n:])))])
    scale = np.maximum(scale, np.finfo(float).tiny)
    kwargs = dict(options)
    if time_dependent_force is not None:
        kwargs["time_dependent_force"] = time_dependent_force
    extra = _combined_force(system, time_dependent_force)
    if extra is not None:
        # cheap first correction: the nonlinear force along the linear periodic motion, applied as a
        # known force, gives a periodic state that already carries most of its effect
        g = extra.batch(grid, y_lin[:, :n], y_lin[:, n:])
        g[-1] = g[0]
        with serial_blas(), np.errstate(over="ignore", invalid="ignore"):
            y0 = lu_solve(lu, propagate(system, grid, f + g, np.zeros(2 * n))[-1])
    for it in range(1, max_iterations + 1):
        residual = _one_period(system, force_over_period, method, y0, kwargs) - y0
        err = float(np.max(np.abs(residual) / scale))
        info = {"iterations": it, "residual": err}
        if err <= tol:
            return y0[:n], y0[n:], info
        y0 = y0 + lu_solve(lu, residual)
    raise SolverFailedError(
        f"steady state ({method}): period residual {err:.3g} above tol {tol:g} after {max_iterations} iterations"
    )


def _one_period(system, force: SampledForce, method: str, y0: np.ndarray, options: dict) -> np.ndarray:
    """State after one period from y0 with the chosen method."""
    n = system.n_dof
    resp, _ = solve_with_diagnostics(system, force, force.t_s, method=method, x0=y0[:n], v0=y0[n:], **options)
    return np.concatenate([resp.x[-1], resp.v[-1]])
