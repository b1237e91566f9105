"""Periodic steady state of a one-period map by Anderson-accelerated fixed-point iteration (issue 24).

The plain search steps the map x -> P(x) (one cam period) until the state changes by less than `tol`
per period. Its error falls by the slowest mode's decay per period, exp(-zeta omega_1 T): on long
chains omega_1 is small (about 0.64 per period at 1,000 links), so it needs 60 periods and more.
Anderson acceleration (Walker & Ni, SIAM J. Numer. Anal. 49, 2011, "type II") takes the next state
as the combination of the last `depth` images P(x_i) whose residuals f_i = P(x_i) - x_i combine to
the least-squares smallest one: on the few slowly decaying directions it acts like GMRES on the
linearised map, so the slow modes are removed in a few periods, whatever their decay; the fast ones
decay by themselves in each period. It needs no Jacobian, only the periods already stepped, and
O(depth N) memory. It is applied to the map preconditioned by the linear chain's Newton step on its
slow modes (`slow_mode_newton`: x + (I - Phi_T)^-1 (P(x) - x) on the modes that keep more than
SLOW_DECAY of themselves per period, plain elsewhere), which removes the linear part of the slow
directions in one step and leaves Anderson the part the impacts change.

Its result keeps the plain search's meaning: a state is accepted only when one period from it
changes it by at most `tol` (relative to the scale of the period's motion), and the state returned
is that period's end. Where the map is not smooth enough for the extrapolation to help (no steady
state, a subharmonic) the residual stops falling; after `stall` periods without halving the best
residual the search goes on with plain periods, so that a subharmonic settles and is found as before.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from dynamics.errors import SolverDivergedError

# Residuals kept for the extrapolation: enough for the slow low modes of a 2,000-link chain
# (measured: fewer periods to 1e-6 than depth 4 or 6 on 1,000 and 2,000 links), small next to N.
DEFAULT_DEPTH = 8
# Periods without halving the best residual after which the search gives the extrapolation up.
DEFAULT_STALL = 8
# The linear Newton step is taken on the modes that keep more than this fraction of themselves over
# one period (the rest decay in the plain period itself): measured on the default link, 0.094 mm,
# 180 rpm, from the linear chain's periodic state, with depth 8: 12 periods instead of 15 to 1e-6
# at 1,000 links, 18 instead of 25 at 2,000.
SLOW_DECAY = 1e-2
# Up to this many links the slow modes come from one dense eigensolve (faster there than the sparse
# shift-invert one).
DENSE_EIGENSOLVE_UP_TO = 400
# Least-squares columns below this fraction of the largest singular value are dropped (a
# near-dependent history would only amplify noise in the extrapolation).
RCOND = 1e-10


@dataclass(frozen=True)
class FixedPointSearch:
    """What the search returns: the state after the last period stepped, and how it got there."""

    state: np.ndarray  # P(x) of the last period
    converged: bool  # the last period changed its start by <= tol
    periods: int  # one-period maps evaluated
    residual: float  # the last period's change, relative to its scale
    plain_ends: list  # period ends of the final plain stretch (for a subharmonic search); [x0, P(x0), ...]
    plain_scale: np.ndarray | None  # the scale of the last period


def accelerated_fixed_point(
    one_period,
    x0: np.ndarray,
    *,
    tol: float,
    max_periods: int,
    depth: int = DEFAULT_DEPTH,
    stall: int = DEFAULT_STALL,
    precondition=None,
) -> FixedPointSearch:
    """Fixed point of `one_period(x) -> (P(x), scale)` (scale: per-component positive scale of the
    residual, from that period's motion), by Anderson acceleration with plain periods as the
    fallback (module docstring)."""
    x = np.array(x0, dtype=float)
    d_f: deque = deque(maxlen=depth)  # differences of scaled residuals
    d_g: deque = deque(maxlen=depth)  # differences of images
    f_prev = g_prev = None
    best = math.inf
    since_best = 0
    accelerating = depth > 0
    plain_ends = [x.copy()]
    residual, scale, image = math.inf, None, x
    last_image = None  # the last period end the chain reached: a state the extrapolation may fall back to
    for period in range(1, max_periods + 1):
        try:
            image, scale = one_period(x)
        except SolverDivergedError:
            if last_image is None or x is last_image:
                raise
            # an extrapolated start the step cannot take (far outside the motion seen): restart the
            # history from the last period end reached
            x, f_prev, g_prev = last_image, None, None
            d_f.clear()
            d_g.clear()
            continue
        last_image = image
        f = (image - x) / scale
        residual = float(np.max(np.abs(f)))
        if residual <= tol:
            plain_ends.append(image)
            return FixedPointSearch(image, True, period, residual, plain_ends, scale)
        if residual < 0.5 * best:
            best, since_best = residual, 0
        else:
            since_best += 1
        if accelerating and since_best >= stall:
            accelerating = False  # give the extrapolation up: plain periods from here
            plain_ends = [x.copy()]
        if not accelerating:
            plain_ends.append(image)
            x = image
            continue
        g = image if precondition is None else x + precondition(image - x)
        f = (g - x) / scale
        if f_prev is not None:
            d_f.append(f - f_prev)
            d_g.append(g - g_prev)
        f_prev, g_prev = f, g
        x = g - _extrapolation(d_f, d_g, f) if d_f else g
    return FixedPointSearch(image, False, max_periods, residual, plain_ends, scale)


def _extrapolation(d_f, d_g, f) -> np.ndarray:
    """Sum of gamma_i dG_i with gamma the least-squares solution of dF gamma = f."""
    df = np.column_stack(d_f)
    gamma = np.linalg.lstsq(df, f, rcond=RCOND)[0]
    return np.column_stack(d_g) @ gamma


def slow_mode_newton(stiffness, mass_kg: float, damping_ratio_at, period_s: float, decay: float):
    """r -> the Newton step (I - Phi)^-1 r of the linear chain's one-period map on its slowly decaying
    modes (per period decay exp(-zeta omega T) above `decay`), r itself on the others (a plain period).

    stiffness: the chain's sparse K (N x N), mass matrix mass_kg I; damping_ratio_at(omega) the
    modes' damping ratios. The state is (y, w, anything else): the first 2N entries are the links'.
    In the orthonormal modes phi_j of K / m each mode's period map is the 2 x 2 exponential of its
    damped oscillator over T, so (I - Phi)^-1 is 2 x 2 blocks: O(N m) per step, no N x N array."""
    from scipy.linalg import expm
    from scipy.sparse.linalg import eigsh

    x = (stiffness / mass_kg).tocsc()
    n = x.shape[0]
    count = 0
    while True:  # widen until the last mode found decays fast enough, or all are found
        if n <= DENSE_EIGENSOLVE_UP_TO:
            count = n
            lam, vec = np.linalg.eigh(x.toarray())
        else:
            count = min(max(2 * count, 8), n - 2)
            lam, vec = eigsh(x, k=count, sigma=0.0, which="LM")
            order = np.argsort(lam)
            lam, vec = lam[order], vec[:, order]
        omega = np.sqrt(np.maximum(lam, 0.0))
        slow = np.exp(-np.array([damping_ratio_at(o) * o for o in omega]) * period_s) > decay
        if not slow[-1] or count >= n - 2 or n <= DENSE_EIGENSOLVE_UP_TO:
            break
    omega, vec = omega[slow], np.ascontiguousarray(vec[:, slow])
    blocks = np.empty((omega.size, 2, 2))
    for j, o in enumerate(omega):
        a = np.array([[0.0, 1.0], [-o * o, -2.0 * damping_ratio_at(o) * o]])
        one_minus = np.eye(2) - expm(a * period_s)
        # an undamped mode whose period divides T has no Newton step (I - Phi singular): plain there
        blocks[j] = np.linalg.inv(one_minus) if np.linalg.cond(one_minus) < 1e8 else np.eye(2)

    def newton_step(r: np.ndarray) -> np.ndarray:
        q = np.stack([vec.T @ r[:n], vec.T @ r[n : 2 * n]], axis=1)  # (m, 2)
        dq = np.einsum("jab,jb->ja", blocks, q) - q
        out = r.copy()
        out[:n] += vec @ dq[:, 0]
        out[n : 2 * n] += vec @ dq[:, 1]
        return out

    return newton_step
