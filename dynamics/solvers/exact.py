"""Exact discretisation of the linear model under a first-order-hold (piecewise linear) force.

Over a step h with f linear from f_k to f_k+1, the state y = [x; v] obeys

    y_k+1 = Phi y_k + (P - Q) f_k + Q f_k+1,

where Phi, P and Q are blocks of one matrix exponential (Van Loan's augmented matrix):

    expm(h [[A, B, 0], [0, 0, I/h], [0, 0, 0]]) = [[Phi, P, Q], [0, I, I], [0, 0, I]].

This is exact (to rounding) for any stiffness: there is no stability limit, so k = 1e10 N/m is as
easy as 1e5. When the damping is classical (Phi_m^T C Phi_m diagonal in the mass-normalised modes
Phi_m, as for the default chain's modal damping) the same matrices are built mode by mode: one
symmetric eigensolve and N 4x4 exponentials (one vectorised Pade approximant, expm_stack) instead
of one (3N)x(3N) exponential (set-up per material at N = 85: 0.72 ms in bench_dynamics; equal to
rounding, tested), and a linear run on a uniform grid is stepped in those modes by blocks
(dynamics.solvers.mode_scan), so the dense matrices are never built (180 steps of the 85-link
chain: 0.39 ms against 0.82 ms for the dense loop in bench_dynamics, a ratio that moves with page
faults; see docs/performance.md, Dynamics: solvers). Other systems (the report replica's asymmetric damping) take the
augmented-matrix route and the step loop; for a linear run its B keeps only the DOFs the force
acts on. The matrices are cached per system and step (dynamics.solvers.cache), so a speed sweep
or a set of cams on one chain computes them once.

Nonlinear forces g(t, x, v) (friction) are handled by a documented splitting: the linear part stays
exact, g enters as an extra first-order-hold force whose end-of-step value comes from a predictor
(Heun): predict with g held at its start value, evaluate g at the prediction, then redo the step
with g linear between the two values. Second-order accurate in the step for smooth g; stable while
h * L_g / m < 2 (L_g the slope of g in v); `substeps` splits every interval to keep it there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh, expm

from dynamics.errors import DynamicsError
from dynamics.models.system import SecondOrderSystem
from dynamics.solvers import mode_scan
from dynamics.solvers._common import (
    Problem,
    check_finite,
    divergence_bounds,
    force_at,
    frequency_bound,
    is_diagonal,
    state_matrices,
)
from dynamics.solvers.cache import cached

OPTIONS = {
    "substeps": "int >= 1 (default 1): equal sub-intervals per output interval (nonlinear force)",
}


def system_modes(system: SecondOrderSystem):
    """`classical_modes` of the system (None if not classical), cached per system."""
    return cached(("modes", *system.cache_key), lambda: classical_modes(system))


def _step_key(h: float) -> float:
    # 12 significant digits: a period grid and an output grid with the same nominal step
    # (differing in the last bits) share one exponential
    return float(f"{h:.12e}")


def foh_matrices(system: SecondOrderSystem, h: float, inputs: tuple[int, ...] | None = None):
    """(Phi, G0, G1) with y_k+1 = Phi y_k + G0 f_k + G1 f_k+1 over a step h; cached. With `inputs`
    (DOF indices) G0 and G1 keep only those DOFs' columns: y_k+1 = Phi y_k + G0 f_k[inputs] + ..."""

    def compute():
        modes = system_modes(system)
        if modes is None:
            return _van_loan(system, h, inputs)
        if inputs is not None:  # every column costs the same mode by mode: slice the full set
            phi, g0, g1 = foh_matrices(system, h)
            return phi, g0[:, list(inputs)], g1[:, list(inputs)]
        return _modal_foh(modes, _mode_steps(modes, h))

    return cached(("foh", *system.cache_key, _step_key(h), inputs), compute)


def _van_loan(system: SecondOrderSystem, h: float, inputs: tuple[int, ...] | None = None):
    """The augmented exponential over the columns of B for `inputs` only (all when None): a force on
    3 of 85 DOFs (the report's model) needs a 176-square exponential instead of a 255-square one.
    Positions are scaled by a bound on the highest frequency first, which balances the blocks of A
    (K / M against 1: their norms differ by omega^2) and so spares the exponential the squarings
    that the unbalanced norm would ask for; the result is scaled back."""
    a, b = state_matrices(system)
    if inputs is not None:
        b = b[:, list(inputs)]
    n2, n_in = b.shape
    n = n2 // 2
    scale = np.ones(n2)
    scale[:n] = max(frequency_bound(system), np.finfo(float).tiny)
    aug = np.zeros((n2 + 2 * n_in, n2 + 2 * n_in))
    aug[:n2, :n2] = (scale[:, None] * h) * a / scale[None, :]
    aug[:n2, n2 : n2 + n_in] = (scale[:, None] * h) * b
    aug[n2 : n2 + n_in, n2 + n_in :] = np.eye(n_in)
    e = expm(aug)
    phi = e[:n2, :n2] / scale[:, None] * scale[None, :]
    p = e[:n2, n2 : n2 + n_in] / scale[:, None]
    q = e[:n2, n2 + n_in :] / scale[:, None]
    return phi, p - q, q


@dataclass(frozen=True, eq=False)
class ClassicalModes:
    """Mass-normalised modes of a classically damped system: x = shapes q, q = to_modal x.
    Compared and hashed by identity: the cache keys what is derived from it by the object itself
    (one per system, cached)."""

    shapes: np.ndarray  # (n, n), columns; shapes^T M shapes = I
    omega2: np.ndarray  # (n,) squared natural frequencies
    damping: np.ndarray  # (n,) modal damping coefficients (2 zeta omega)
    to_modal: np.ndarray  # (n, n) = shapes^-1 = shapes^T M


def classical_modes(system: SecondOrderSystem, rtol: float = 1e-10) -> ClassicalModes | None:
    """The modes when M, C, K are symmetric and C is diagonal in the mass-normalised modes of (K, M);
    None otherwise."""
    m, c, k = system.mass, system.damping, system.stiffness
    if not all(np.abs(a - a.T).max() <= rtol * np.abs(a).max(initial=1e-300) for a in (m, c, k)):
        return None
    omega2, shapes = _mass_normalised_modes(k, m)
    modal_c = shapes.T @ c @ shapes
    diag = np.diag(modal_c).copy()
    off = modal_c - np.diag(diag)
    if np.abs(off).max(initial=0.0) > rtol * max(np.abs(diag).max(initial=0.0), 1e-300):
        return None
    return ClassicalModes(shapes, omega2, diag, shapes.T @ m)  # shapes^T M shapes = I


def _mass_normalised_modes(k: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of (K, M) with shapes^T M shapes = I; a diagonal M (every lumped chain) takes the
    standard symmetric eigensolver on M^-1/2 K M^-1/2, cheaper than the generalised one."""
    if not is_diagonal(m):
        return eigh(k, m)
    d = 1.0 / np.sqrt(np.diag(m))
    omega2, v = np.linalg.eigh(d[:, None] * k * d[None, :])
    return omega2, d[:, None] * v


def _mode_steps(modes: ClassicalModes, h: float) -> mode_scan.ModeSteps:
    return cached(("mode steps", modes, _step_key(h)), lambda: mode_scan.mode_steps(modes.omega2, modes.damping, h))


def _modal_foh(modes: ClassicalModes, steps: mode_scan.ModeSteps):
    """The physical (Phi, G0, G1) from the per-mode step matrices: x = shapes q, v = shapes q'."""
    shapes, to_modal = modes.shapes, modes.to_modal
    phi = np.block([[shapes @ (steps.e[:, i, j, None] * to_modal) for j in (0, 1)] for i in (0, 1)])
    g0 = np.vstack([shapes @ (steps.g0[:, i, None] * shapes.T) for i in (0, 1)])
    g1 = np.vstack([shapes @ (steps.g1[:, i, None] * shapes.T) for i in (0, 1)])
    return phi, g0, g1


def integration_grid(t_eval: np.ndarray, force_t: np.ndarray, substeps: int) -> tuple[np.ndarray, np.ndarray]:
    """Grid holding every output time and every force knot inside the span, each interval split
    into `substeps`; returns the grid and the indices of the output times in it."""
    if np.array_equal(force_t, t_eval):  # force sampled at the outputs (the usual case)
        base = t_eval
    else:
        base = np.union1d(t_eval, force_t[(force_t > t_eval[0]) & (force_t < t_eval[-1])])
    if substeps > 1:
        frac = np.arange(substeps) / substeps
        base = np.append((base[:-1, None] + np.diff(base)[:, None] * frac).ravel(), base[-1])
    return base, np.searchsorted(base, t_eval)


def _steps(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct step lengths (rounded to 12 digits so a uniform grid uses one matrix set) and the
    index of each interval's step among them."""
    h = np.diff(grid)
    if h.max() - h.min() <= 1e-12 * h.max():  # uniform (the usual case): skip the sort
        return np.array([h.mean()]), np.zeros(h.size, dtype=np.intp)
    key = np.round(h / h.max(), 12)
    uniq, inv = np.unique(key, return_inverse=True)
    reps = np.array([h[inv == j].mean() for j in range(uniq.size)])
    return reps, inv


def propagate(system, grid: np.ndarray, forces: np.ndarray, y0: np.ndarray, extra=None) -> np.ndarray:
    """States on `grid` from y0 under FOH forces sampled on the grid; extra(t, x, v) optional."""
    reps, which = grid_steps = _steps(grid)
    n = system.n_dof
    modes = _modes_for_blocks(system, grid_steps, extra)
    if modes is not None:
        return modal_response(modes, grid_steps, forces, y0, accelerations=False)[0]
    if extra is not None and all(is_diagonal(a) for a in (system.mass, system.damping, system.stiffness)):
        return _propagate_uncoupled(system, grid, grid_steps, forces, y0, extra)
    inputs = _force_support(forces) if extra is None else None
    if inputs is not None:
        forces = forces[:, list(inputs)]
    mats = [foh_matrices(system, h, inputs) for h in reps]
    y = np.empty((grid.size, 2 * n))
    y[0] = y0
    lin = np.empty((grid.size - 1, 2 * n))  # G0 f_k + G1 f_k+1, all steps at once
    for j, (_, g0, g1) in enumerate(mats):
        sel = which == j
        lin[sel] = forces[:-1][sel] @ g0.T + forces[1:][sel] @ g1.T
    if extra is None:
        phi_t = [phi.T.copy() for phi, _, _ in mats]
        for k in range(grid.size - 1):
            y[k + 1] = y[k] @ phi_t[which[k]] + lin[k]
        return y
    # u = Phi y_k + G0 (f_k + g_k) + G1 f_k+1 in one product with [Phi | G0] (the loop is
    # overhead-bound); the predictor adds G1 g_k, the corrector G1 g*
    stacked = [np.hstack([phi, g0]).T.copy() for phi, g0, _ in mats]
    g1s = [g1.T.copy() for _, _, g1 in mats]
    state = np.empty(3 * n)
    state[: 2 * n] = y0
    state[2 * n :] = extra(grid[0], y0[:n], y0[n:])
    for k in range(grid.size - 1):
        j = which[k]
        g1 = g1s[j]
        u = state @ stacked[j] + lin[k]
        pred = u + state[2 * n :] @ g1
        u += extra(grid[k + 1], pred[:n], pred[n:]) @ g1
        y[k + 1] = u
        state[: 2 * n] = u
        state[2 * n :] = extra(grid[k + 1], u[:n], u[n:])
    return y  # a runaway turns into inf/nan, which propagates to the end and is caught there


def _propagate_uncoupled(system, grid, grid_steps, forces, y0, extra) -> np.ndarray:
    """`propagate` with a nonlinear force on an uncoupled system (diagonal M, C, K: a long chain in
    its modal basis, dynamics.models.reduction). Each DOF's exact step is its own 2 x 2
    (mode_scan.mode_steps), so a step costs O(n) instead of the dense [Phi | G0] product's 6 n^2
    (400 modes: 1e6 multiply-adds per step). The same splitting as the dense loop, term by term."""
    reps, which = grid_steps
    n = system.n_dof
    mass = np.diag(system.mass)
    steps = [
        cached(
            ("uncoupled steps", *system.cache_key, _step_key(h)),
            lambda h=h: mode_scan.mode_steps(np.diag(system.stiffness) / mass, np.diag(system.damping) / mass, h),
        )
        for h in reps
    ]
    p = forces / mass
    y = np.empty((grid.size, 2 * n))
    y[0] = y0
    x, v = y0[:n], y0[n:]
    g = extra(grid[0], x, v) / mass
    for k in range(grid.size - 1):
        s = steps[which[k]]
        e, g0, g1 = s.e, s.g0, s.g1
        held = p[k] + g
        x1 = e[:, 0, 0] * x + e[:, 0, 1] * v + g0[:, 0] * held + g1[:, 0] * p[k + 1]
        v1 = e[:, 1, 0] * x + e[:, 1, 1] * v + g0[:, 1] * held + g1[:, 1] * p[k + 1]
        corrected = extra(grid[k + 1], x1 + g1[:, 0] * g, v1 + g1[:, 1] * g) / mass
        x = x1 + g1[:, 0] * corrected
        v = v1 + g1[:, 1] * corrected
        y[k + 1, :n] = x
        y[k + 1, n:] = v
        g = extra(grid[k + 1], x, v) / mass
    return y  # a runaway turns into inf/nan, which propagates to the end and is caught there


def _modes_for_blocks(system, grid_steps, extra) -> ClassicalModes | None:
    """The system's modes when a run can be stepped in them by blocks: linear, classically damped,
    equal steps."""
    if extra is not None or grid_steps[0].size != 1:
        return None
    return system_modes(system)


def modal_response(modes: ClassicalModes, grid_steps, forces: np.ndarray, y0: np.ndarray, accelerations: bool):
    """[x | v] (G, 2n) of a classically damped linear system stepped in its modes, and, when asked,
    its accelerations (G, n) from the modal equations q'' = p - c q' - w^2 q, which are the
    equation of motion's M^-1 (f - C v - K x) without its two dense products (else None)."""
    n = modes.shapes.shape[0]
    p = forces @ modes.shapes
    s = modal_states(modes, grid_steps, p, np.stack([modes.to_modal @ y0[:n], modes.to_modal @ y0[n:]]))
    # rows [q; q'] -> [x | v]: one product for positions and velocities at every step
    y = (s.reshape(-1, n) @ modes.shapes.T).reshape(p.shape[0], 2 * n)
    if not accelerations:
        return y, None
    return y, (p - modes.damping * s[:, 1] - modes.omega2 * s[:, 0]) @ modes.shapes.T


def _force_support(forces: np.ndarray) -> tuple[int, ...] | None:
    """The DOFs a force history ever acts on; None when that is every DOF."""
    support = np.flatnonzero(np.any(forces != 0.0, axis=0))
    return None if support.size == forces.shape[1] else tuple(int(i) for i in support)


def mode_stepping(modes: ClassicalModes, h: float, n_steps: int):
    """(ModeSteps, BlockKernel) of every mode for n_steps steps of length h; cached."""
    length = mode_scan.block_length(n_steps)

    def compute():
        steps = _mode_steps(modes, h)
        return steps, mode_scan.block_kernel(steps.e, length)

    return cached(("mode stepping", modes, _step_key(h), length), compute)


def modal_states(modes: ClassicalModes, grid_steps, p: np.ndarray, s0: np.ndarray) -> np.ndarray:
    """States (T, 2, r) of the r = p.shape[1] lowest modes from s0 (2, r) under modal forces p
    (T, r), on a grid whose steps are `grid_steps` = `_steps(grid)`: by blocks when they are all
    equal (mode_scan), step by step otherwise."""
    r = p.shape[1]
    reps, which = grid_steps
    if reps.size == 1:
        steps, kernel = mode_stepping(modes, reps[0], p.shape[0] - 1)
        return mode_scan.propagate_modes(steps.lowest(r), kernel.lowest(r), p, s0)
    steps = [_mode_steps(modes, h).lowest(r) for h in reps]
    return mode_scan.propagate_modes_stepwise(steps, which, p, s0)


def solve(problem: Problem, *, substeps: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, dict]:
    if not (isinstance(substeps, (int, np.integer)) and substeps >= 1):
        raise DynamicsError(f"substeps: expected an integer >= 1, got {substeps!r}")
    grid, out = integration_grid(problem.t_eval_s, problem.force.t_s, int(substeps))
    forces = force_at(problem.force, grid)
    y0 = np.concatenate([problem.x0, problem.v0])
    grid_steps = _steps(grid)
    modes = _modes_for_blocks(problem.system, grid_steps, problem.extra_force)
    if modes is None:
        y, a = propagate(problem.system, grid, forces, y0, problem.extra_force), None
    else:
        y, a = modal_response(modes, grid_steps, forces, y0, accelerations=True)
    n = problem.n
    h_max = float(np.max(np.diff(grid)))
    step = f"step {h_max:.3g}"
    if problem.extra_force is not None:
        step += "; the nonlinear splitting is stable for h * |dg/dv| / m < 2: raise `substeps`"
    check_finite("exact", grid, y[:, :n], y[:, n:], divergence_bounds(problem), step)
    if out.size != grid.size:  # steps between the outputs: keep the outputs' rows
        y = y[out]
        a = None if a is None else a[out]
    return y[:, :n], y[:, n:], a, {"n_steps": grid.size - 1, "max_step": h_max}
