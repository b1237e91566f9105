"""Newmark average acceleration and HHT-alpha, fixed step, for the linear model.

HHT-alpha (Hilber, Hughes, Taylor 1977), alpha in [-1/3, 0], gamma = 1/2 - alpha,
beta = (1 - alpha)^2 / 4, balances the equation at t_n+1+alpha:

    M a_n+1 + (1 + alpha)(C v_n+1 + K x_n+1) - alpha (C v_n + K x_n) = (1 + alpha) f_n+1 - alpha f_n.

alpha = 0 is Newmark's average acceleration (trapezoidal) rule: unconditionally stable, no
amplitude error, second-order period error (relative period elongation about (w h)^2 / 12).
alpha < 0 adds numerical damping of the high modes. Each output interval is split into equal
steps no longer than `dt`, so outputs fall on steps.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from dynamics.errors import DynamicsError
from dynamics.solvers._common import Problem, check_finite, divergence_bounds, force_at

NEWMARK_OPTIONS = {"dt": "largest step (default: the largest output interval)"}
HHT_OPTIONS = {**NEWMARK_OPTIONS, "alpha": "HHT alpha in [-1/3, 0] (default -0.05)"}


def fixed_step_grid(t_eval: np.ndarray, dt: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Output intervals split into ceil(h / dt) equal steps; returns the grid and output indices."""
    h = np.diff(t_eval)
    if dt is None:
        dt = float(h.max())
    if not (np.isfinite(dt) and dt > 0):
        raise DynamicsError(f"dt: expected a positive step, got {dt!r}")
    counts = np.maximum(np.ceil(h / dt * (1 - 1e-12)).astype(int), 1)
    pieces = [t_eval[i] + h[i] * np.arange(counts[i]) / counts[i] for i in range(h.size)]
    grid = np.append(np.concatenate(pieces), t_eval[-1])
    out = np.concatenate([[0], np.cumsum(counts)])
    return grid, out


def solve_newmark(problem: Problem, *, dt: float | None = None) -> tuple[np.ndarray, np.ndarray, None, dict]:
    return _hht(problem, dt, 0.0, "newmark")


def solve_hht(
    problem: Problem, *, dt: float | None = None, alpha: float = -0.05
) -> tuple[np.ndarray, np.ndarray, None, dict]:
    if not (-1.0 / 3.0 <= alpha <= 0.0):
        raise DynamicsError(f"alpha: expected a value in [-1/3, 0], got {alpha!r}")
    return _hht(problem, dt, float(alpha), "hht")


def _hht(problem: Problem, dt, alpha: float, name: str):
    sys = problem.system
    m, c, k = sys.mass, sys.damping, sys.stiffness
    gamma = 0.5 - alpha
    beta = (1.0 - alpha) ** 2 / 4.0
    grid, out = fixed_step_grid(problem.t_eval_s, dt)
    f = force_at(problem.force, grid)
    steps = np.diff(grid)
    key = np.round(steps / steps.max(), 12)
    uniq, which = np.unique(key, return_inverse=True)
    factors = []
    for j in range(uniq.size):
        h = steps[which == j].mean()
        factors.append((h, lu_factor(m + (1 + alpha) * (gamma * h * c + beta * h * h * k))))
    n = problem.n
    x = np.empty((grid.size, n))
    v = np.empty((grid.size, n))
    x[0], v[0] = problem.x0, problem.v0
    acc = np.linalg.solve(m, f[0] - c @ v[0] - k @ x[0])
    for i in range(grid.size - 1):
        h, lu = factors[which[i]]
        x_pred = x[i] + h * v[i] + h * h * (0.5 - beta) * acc
        v_pred = v[i] + h * (1 - gamma) * acc
        rhs = (1 + alpha) * (f[i + 1] - c @ v_pred - k @ x_pred) - alpha * (f[i] - c @ v[i] - k @ x[i])
        acc = lu_solve(lu, rhs)
        x[i + 1] = x_pred + beta * h * h * acc
        v[i + 1] = v_pred + gamma * h * acc
    h_max = float(steps.max())
    check_finite(name, grid, x, v, divergence_bounds(problem), f"step {h_max:.3g}")
    return x[out], v[out], None, {"n_steps": int(steps.size), "step": h_max}
