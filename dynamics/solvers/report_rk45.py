"""The 2012 report's scheme (Appendix C): Dormand-Prince 5(4) restarted at every output step.

Each output interval [t1, t2] is a fresh MATLAB `ode45` call from the previous output state, with
the force linearly interpolated between its values at t1 and t2. The integrator reproduces
MATLAB's ode45 step control, not scipy's, because the replica must match the report's numbers:
- defaults RelTol 1e-3, AbsTol 1e-6, MaxStep = 0.1 * (t2 - t1);
- error measured in the max norm, weighted by max(|y|, |y_new|, AbsTol/RelTol);
- first step min(MaxStep, span of the first output sub-interval), cut by the derivative's size;
- a step within 10 % of the remaining span is stretched to land on t2;
- growth after a success: divide by 1.25 (err/RelTol)^(1/5), at most 5x; first rejection shrinks by
  max(0.1, 0.8 (RelTol/err)^(1/5)), later ones halve.
`nip` is the number of sub-intervals the script asks ode45 to report (tspan = t1:(t2-t1)/nip:t2);
it only sets the first step (MATLAB derives it from tspan(2) - tspan(1)), outputs are interpolated.
The nonlinear force is evaluated inside every stage, as the script does with its sign friction.
"""

from __future__ import annotations

import numpy as np

from dynamics.errors import DynamicsError, SolverFailedError
from dynamics.solvers._common import Problem, check_finite, divergence_bounds, force_at, state_matrices

OPTIONS = {
    "rtol": "relative tolerance per restart (default 1e-3, MATLAB's RelTol)",
    "atol": "absolute tolerance per restart (default 1e-6, MATLAB's AbsTol)",
    "max_step_fraction": "MaxStep as a fraction of each output interval (default 0.1, MATLAB's)",
    "nip": "output sub-intervals per restart as in the script (default 3); sets the first step only",
}

_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
_A = [
    [],
    [1 / 5],
    [3 / 40, 9 / 40],
    [44 / 45, -56 / 15, 32 / 9],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
    [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
]
_A = [np.array(row) for row in _A]
_E = np.array([71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])
_POW = 1 / 5


def solve(
    problem: Problem, *, rtol: float = 1e-3, atol: float = 1e-6, max_step_fraction: float = 0.1, nip: int = 3
) -> tuple[np.ndarray, np.ndarray, None, dict]:
    for name, val in (("rtol", rtol), ("atol", atol), ("max_step_fraction", max_step_fraction)):
        if not (np.isfinite(val) and val > 0):
            raise DynamicsError(f"{name}: expected a positive number, got {val!r}")
    if not (isinstance(nip, (int, np.integer)) and nip >= 1):
        raise DynamicsError(f"nip: expected an integer >= 1, got {nip!r}")
    n = problem.n
    a, b = state_matrices(problem.system)
    t_out = problem.t_eval_s
    f_out = force_at(problem.force, t_out) @ b.T  # B f at the output times; linear in between
    g = problem.extra_force
    m_inv = b[n:, :]

    def rhs_factory(t1, t2, bf1, bf2):
        span = t2 - t1

        def rhs(t, y):
            dy = a @ y + bf1 + (bf2 - bf1) * ((t - t1) / span)
            if g is not None:
                dy[n:] += m_inv @ g(t, y[:n], y[n:])
            return dy

        return rhs

    y = np.empty((t_out.size, 2 * n))
    y[0] = np.concatenate([problem.x0, problem.v0])
    n_steps = n_rejected = 0
    for i in range(t_out.size - 1):
        t1, t2 = t_out[i], t_out[i + 1]
        rhs = rhs_factory(t1, t2, f_out[i], f_out[i + 1])
        y[i + 1], steps, rejected = _ode45(rhs, t1, t2, y[i], rtol, atol, max_step_fraction, nip)
        n_steps += steps
        n_rejected += rejected
        if not np.all(np.isfinite(y[i + 1])):
            y[i + 2 :] = np.nan
            break
    check_finite("report-rk45", t_out, y[:, :n], y[:, n:], divergence_bounds(problem), f"rtol {rtol:g}")
    return y[:, :n], y[:, n:], None, {"n_steps": n_steps, "n_rejected": n_rejected}


def _ode45(rhs, t0, tfinal, y0, rtol, atol, max_step_fraction, nip):
    """One MATLAB ode45 call from t0 to tfinal; returns y(tfinal), accepted and rejected steps."""
    threshold = atol / rtol
    span = tfinal - t0
    hmax = min(span, max_step_fraction * span)
    t, y = t0, y0.copy()
    f0 = rhs(t, y)
    absh = min(hmax, span / nip)
    rh = np.max(np.abs(f0) / np.maximum(np.abs(y), threshold)) / (0.8 * rtol**_POW)
    if absh * rh > 1:
        absh = 1.0 / rh
    absh = max(absh, 16 * np.spacing(t))
    k = np.empty((7, y.size))
    k[0] = f0
    steps = rejected = 0
    done = False
    while not done:
        hmin = 16 * np.spacing(t)
        absh = min(hmax, max(hmin, absh))
        h = absh
        if 1.1 * absh >= abs(tfinal - t):
            h = tfinal - t
            absh = abs(h)
            done = True
        nofailed = True
        while True:
            for s in range(1, 6):
                k[s] = rhs(t + _C[s] * h, y + h * (_A[s] @ k[:s]))
            tnew = tfinal if done else t + h
            ynew = y + h * (_A[6] @ k[:6])  # MATLAB uses the step before "purifying" h = tnew - t
            h = tnew - t
            k[6] = rhs(tnew, ynew)
            errwt = np.maximum(np.maximum(np.abs(y), np.abs(ynew)), threshold)
            err = absh * np.max(np.abs(_E @ k) / errwt)
            if not np.isfinite(err):
                return np.full_like(y, np.nan), steps, rejected
            if err > rtol:
                rejected += 1
                if absh <= hmin:
                    raise SolverFailedError(
                        f"report-rk45: step size fell below {hmin:.3g} at t = {t:.6g} (rtol {rtol:g})"
                    )
                if nofailed:
                    nofailed = False
                    absh = max(hmin, absh * max(0.1, 0.8 * (rtol / err) ** _POW))
                else:
                    absh = max(hmin, 0.5 * absh)
                h = absh
                done = False
            else:
                break
        steps += 1
        if done:
            return ynew, steps, rejected
        if nofailed:
            temp = 1.25 * (err / rtol) ** _POW
            absh = absh / temp if temp > 0.2 else 5.0 * absh
        t, y = tnew, ynew
        k[0] = k[6]
    return y, steps, rejected
