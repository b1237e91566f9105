"""Modal superposition: x = Phi_r q with the n_modes lowest mass-normalised modes of (K, M).

Each mode obeys q'' + 2 zeta w q' + w^2 q = phi^T f(t) and is stepped exactly under the
first-order-hold force (a 4x4 Van Loan exponential per mode, batched; by blocks on a uniform grid,
see dynamics.solvers.mode_scan). Requires classical damping (Phi^T C Phi diagonal), which modal and
Rayleigh damping are; anything else is refused rather than silently decoupled.

Truncation converges only if the force excites mostly low modes. A base-excited chain written in
absolute coordinates (force k_d z on the driven link) does not: the static response of the cut modes
is lost. Written relative to the cam (x = z 1 + y, force -M 1 z''), it does: that is how
dynamics.solvers.simulate calls this method.
"""

from __future__ import annotations

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.solvers._common import Problem, check_finite, divergence_bounds, force_at
from dynamics.solvers.exact import _steps, integration_grid, modal_states, system_modes

OPTIONS = {"n_modes": "number of lowest modes kept (default: all)"}


def solve(problem: Problem, *, n_modes: int | None = None) -> tuple[np.ndarray, np.ndarray, None, dict]:
    n = problem.n
    if n_modes is None:
        n_modes = n
    if not (isinstance(n_modes, (int, np.integer)) and 1 <= n_modes <= n):
        raise DynamicsError(f"n_modes: expected an integer in 1..{n}, got {n_modes!r}")
    system = problem.system
    modes = system_modes(system)
    if modes is None:
        raise DynamicsError("system.damping: modal superposition needs classical damping (Phi^T C Phi diagonal)")
    r = int(n_modes)
    shapes = modes.shapes[:, :r]
    grid, out = integration_grid(problem.t_eval_s, problem.force.t_s, 1)
    p = force_at(problem.force, grid) @ shapes  # modal forces (steps, r)
    s0 = np.stack([modes.to_modal[:r] @ problem.x0, modes.to_modal[:r] @ problem.v0])
    s = modal_states(modes, _steps(grid), p, s0)
    x = s[out, 0] @ shapes.T
    v = s[out, 1] @ shapes.T
    check_finite("modal", problem.t_eval_s, x, v, divergence_bounds(problem), f"{r} modes")
    return x, v, None, {"n_modes": r, "omega_max_kept": float(np.sqrt(max(modes.omega2[r - 1], 0.0)))}
