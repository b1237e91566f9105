"""Modal superposition: x = Phi_r q with the n_modes lowest mass-normalised modes of (K, M).

Each mode obeys q'' + 2 zeta w q' + w^2 q = phi^T f(t) and is stepped exactly under the
first-order-hold force (a 4x4 Van Loan exponential per mode, batched). Requires classical damping
(Phi^T C Phi diagonal), which modal and Rayleigh damping are; anything else is refused rather than
silently decoupled.

Truncation converges only if the force excites mostly low modes. A base-excited chain written in
absolute coordinates (force k_d z on the driven link) does not: the static response of the cut modes
is lost. Written relative to the cam (x = z 1 + y, force -M 1 z''), it does: that is how
dynamics.simulate calls this method.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import eigh, expm

from dynamics.errors import DynamicsError
from dynamics.solvers._common import Problem, check_finite, divergence_bounds, force_at
from dynamics.solvers.exact import integration_grid

OPTIONS = {"n_modes": "number of lowest modes kept (default: all)"}

# Off-diagonal modal damping above this fraction of the largest diagonal term means C is not classical.
_CLASSICAL_TOL = 1e-8


def modes(system) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(omega, modal damping coefficients 2 zeta omega, mass-normalised mode shapes as columns)."""
    k = 0.5 * (system.stiffness + system.stiffness.T)
    m = 0.5 * (system.mass + system.mass.T)
    lam, phi = eigh(k, m)
    omega = np.sqrt(np.clip(lam, 0.0, None))
    cm = phi.T @ system.damping @ phi
    diag = np.diag(cm).copy()
    off = cm - np.diag(diag)
    if np.max(np.abs(off)) > _CLASSICAL_TOL * max(np.max(np.abs(diag)), np.finfo(float).tiny):
        raise DynamicsError("system.damping: modal superposition needs classical damping (Phi^T C Phi diagonal)")
    return omega, diag, phi


def _mode_matrices(omega: np.ndarray, c: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r = omega.size
    aug = np.zeros((r, 4, 4))
    aug[:, 0, 1] = 1.0
    aug[:, 1, 0] = -(omega**2)
    aug[:, 1, 1] = -c
    aug[:, 1, 2] = 1.0
    aug[:, 2, 3] = 1.0 / h
    e = np.array([expm(block * h) for block in aug])  # a loop: scipy's batched expm is far slower here
    return e[:, :2, :2], e[:, :2, 2] - e[:, :2, 3], e[:, :2, 3]


def solve(problem: Problem, *, n_modes: int | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    n = problem.n
    if n_modes is None:
        n_modes = n
    if not (isinstance(n_modes, (int, np.integer)) and 1 <= n_modes <= n):
        raise DynamicsError(f"n_modes: expected an integer in 1..{n}, got {n_modes!r}")
    omega, c, phi = modes(problem.system)
    omega, c, phi = omega[:n_modes], c[:n_modes], phi[:, :n_modes]
    grid, out = integration_grid(problem.t_eval_s, problem.force.t_s, 1)
    p = force_at(problem.force, grid) @ phi  # modal forces (steps, r)
    h = np.diff(grid)
    key = np.round(h / h.max(), 12)
    uniq, which = np.unique(key, return_inverse=True)
    mats = [_mode_matrices(omega, c, h[which == j].mean()) for j in range(uniq.size)]
    mass = problem.system.mass
    q = np.empty((grid.size, n_modes))
    qd = np.empty((grid.size, n_modes))
    q[0] = phi.T @ mass @ problem.x0
    qd[0] = phi.T @ mass @ problem.v0
    for k in range(grid.size - 1):
        e, g0, g1 = mats[which[k]]
        q[k + 1] = e[:, 0, 0] * q[k] + e[:, 0, 1] * qd[k] + g0[:, 0] * p[k] + g1[:, 0] * p[k + 1]
        qd[k + 1] = e[:, 1, 0] * q[k] + e[:, 1, 1] * qd[k] + g0[:, 1] * p[k] + g1[:, 1] * p[k + 1]
    x = q[out] @ phi.T
    v = qd[out] @ phi.T
    check_finite("modal", problem.t_eval_s, x, v, divergence_bounds(problem), f"{n_modes} modes")
    return x, v, {"n_modes": int(n_modes), "omega_max_kept": float(omega[-1])}
