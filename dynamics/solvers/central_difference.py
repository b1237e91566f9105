"""Explicit central difference, fixed step: here to show where explicit methods fail.

    (M / h^2 + C / 2h) x_n+1 = f_n + g_n - (K - 2 M / h^2) x_n - (M / h^2 - C / 2h) x_n-1,
    v_n = (x_n+1 - x_n-1) / 2h.

With damping in this centred form the stability limit is h <= 2 / omega_max (omega_max the largest
undamped natural frequency of (K, M)); damping does not lower it. A step above the limit is refused
before any work with SolverDivergedError naming the step and the limit; a run that still blows up
(a stiff nonlinear force) is caught by the divergence check. The nonlinear force at step n uses the
backward velocity (x_n - x_n-1) / h, which keeps the scheme explicit. The step must be uniform:
output times must be equally spaced, each interval split into ceil(h / dt) steps.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.solvers._common import Problem, check_finite, divergence_bounds, force_at, max_frequency
from dynamics.solvers.newmark import fixed_step_grid

OPTIONS = {"dt": "largest step (default: the output interval); must be below 2 / omega_max"}


def stability_limit(system) -> float:
    """Largest stable step 2 / omega_max."""
    w = max_frequency(system)
    return np.inf if w == 0.0 else 2.0 / w


def solve(problem: Problem, *, dt: float | None = None) -> tuple[np.ndarray, np.ndarray, None, dict]:
    t_eval = problem.t_eval_s
    h_out = np.diff(t_eval)
    if np.max(np.abs(h_out - h_out[0])) > 1e-9 * h_out[0]:
        raise DynamicsError("t_eval_s: central-difference needs equally spaced output times")
    grid, out = fixed_step_grid(t_eval, dt)
    h = float(np.mean(np.diff(grid)))
    limit = stability_limit(problem.system)
    if h > limit:
        raise SolverDivergedError(
            f"central-difference: step {h:.6g} exceeds the stability limit 2/omega_max = {limit:.6g}"
        )
    sys = problem.system
    m, c, k = sys.mass, sys.damping, sys.stiffness
    f = force_at(problem.force, grid)
    g = problem.extra_force
    lu = lu_factor(m / h**2 + c / (2 * h))
    a_now = 2 * m / h**2 - k
    a_prev = -(m / h**2 - c / (2 * h))
    n = problem.n
    x = np.empty((grid.size + 1, n))
    x[0] = problem.x0
    f0 = f[0] + (g(grid[0], x[0], problem.v0) if g is not None else 0.0)
    acc0 = np.linalg.solve(m, f0 - c @ problem.v0 - k @ x[0])
    x_prev = x[0] - h * problem.v0 + 0.5 * h * h * acc0
    v_back = problem.v0
    for i in range(grid.size):
        rhs = f[i] + a_now @ x[i] + a_prev @ (x[i - 1] if i > 0 else x_prev)
        if g is not None:
            rhs += g(grid[i], x[i], v_back)
        x[i + 1] = lu_solve(lu, rhs)
        v_back = (x[i + 1] - x[i]) / h
        if not np.all(np.isfinite(x[i + 1])):
            x[i + 2 :] = np.nan
            break
    x_m1 = np.vstack([x_prev, x[:-2]])
    v = (x[1:] - x_m1) / (2 * h)
    x = x[:-1]
    check_finite("central-difference", grid, x, v, divergence_bounds(problem), f"step {h:.3g}, limit {limit:.3g}")
    return x[out], v[out], None, {"n_steps": int(grid.size - 1), "step": h, "stability_limit": limit}
