"""scipy.integrate.solve_ivp on the first-order form y' = A y + B f(t) + [0; M^-1 g(t, x, v)].

One call over the whole span (no restarts), the force evaluated by first-order hold at each stage.
The implicit methods get the linear part's constant Jacobian A (the nonlinear force's slope is left
to the method's own updates). Accuracy is bounded by rtol/atol; the explicit ones (rk45, dop853) are
stability-limited on stiff chains and become slow there, the implicit ones are not.
"""

from __future__ import annotations

import numpy as np

from dynamics.errors import DynamicsError, SolverFailedError
from dynamics.solvers._common import Problem, check_finite, divergence_bounds, force_at, state_matrices

LABELS = {
    "rk45": "RK45 (Dormand-Prince 5(4), explicit)",
    "dop853": "DOP853 (Dormand-Prince 8(5,3), explicit)",
    "radau": "Radau IIA order 5 (implicit)",
    "bdf": "BDF orders 1-5 (implicit)",
    "lsoda": "LSODA (Adams / BDF switching)",
}
_SCIPY_NAME = {"rk45": "RK45", "dop853": "DOP853", "radau": "Radau", "bdf": "BDF", "lsoda": "LSODA"}

OPTIONS = {
    "rtol": "relative tolerance (default 1e-8)",
    "atol": "absolute tolerance (default 1e-12, in the model's displacement/velocity units)",
    "max_step": "largest step (default: unbounded)",
}


def solve(
    problem: Problem, name: str, *, rtol: float = 1e-8, atol: float = 1e-12, max_step: float = np.inf
) -> tuple[np.ndarray, np.ndarray, None, dict]:
    for opt, val in (("rtol", rtol), ("atol", atol), ("max_step", max_step)):
        if not (val > 0):
            raise DynamicsError(f"{opt}: expected a positive number, got {val!r}")
    n = problem.n
    a, b = state_matrices(problem.system)
    m_inv = b[n:, :]
    force = problem.force
    g = problem.extra_force

    def rhs(t, y):
        dy = a @ y + b @ force_at(force, t)[0]
        if g is not None:
            dy[n:] += m_inv @ g(t, y[:n], y[n:])
        return dy

    # imported here: scipy.integrate brings scipy.optimize, scipy.sparse.linalg and scipy.fft (0.35-0.4
    # CPU s), which a run with another method never uses (pipeline.py imports this module at start-up)
    from scipy.integrate import solve_ivp

    t = problem.t_eval_s
    kwargs = {"jac": lambda t, y: a} if name in ("radau", "bdf", "lsoda") else {}
    sol = solve_ivp(
        rhs,
        (t[0], t[-1]),
        np.concatenate([problem.x0, problem.v0]),
        method=_SCIPY_NAME[name],
        t_eval=t,
        rtol=rtol,
        atol=atol,
        max_step=max_step,
        **kwargs,
    )
    bounds = divergence_bounds(problem)
    if not sol.success or sol.y.shape[1] != t.size:
        last = sol.y[:, -1] if sol.y.size else np.full(2 * n, np.nan)
        check_finite(
            name,
            np.array([sol.t[-1] if sol.t.size else t[0]]),
            last[None, :n],
            last[None, n:],
            bounds,
            f"rtol {rtol:g}, atol {atol:g}",
        )
        raise SolverFailedError(f"{name}: solve_ivp stopped at t = {sol.t[-1]:.6g}: {sol.message}")
    y = sol.y.T
    check_finite(name, t, y[:, :n], y[:, n:], bounds, f"rtol {rtol:g}, atol {atol:g}")
    return y[:, :n], y[:, n:], None, {"n_rhs_evaluations": int(sol.nfev), "n_jacobians": int(sol.njev)}
