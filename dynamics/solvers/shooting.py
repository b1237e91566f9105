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
import scipy.sparse as sp

from dynamics.errors import SolverDivergedError, SolverFailedError

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
# The sparse slow modes' block inverse iteration stops when every slow Ritz pair's residual
# |S v - lambda v| is below this fraction of the basis' largest Ritz value (the eigenvalues then to
# about its square, the shapes to about it: the Newton step is a preconditioner, Anderson does the rest)
SLOW_MODES_RTOL = 1e-7
SLOW_MODES_MAX_ITERATIONS = 60
# defect_corrected_fixed_point searches each corrected coarse map's fixed point to this fraction of
# the fine map's tolerance, so that the fine period's test there fails only by the defect's own change
DEFECT_INNER_TOL_FRACTION = 0.5
# Least-squares columns below this fraction of the largest singular value are dropped (a
# near-dependent history would only amplify noise in the extrapolation).
RCOND = 1e-10
# about this many outputs in a searching period: the search needs the period's end and the scale of
# its motion, not a fine history
SEARCH_OUTPUTS_PER_PERIOD = 90


@dataclass(frozen=True)
class FixedPointSearch:
    """What the search returns: the state after the last period stepped, and how it got there."""

    state: np.ndarray  # P(x) of the last period
    converged: bool  # the last period changed its start by <= tol
    periods: int  # one-period maps evaluated
    residual: float  # the last period's change, relative to its scale
    plain_ends: list  # period ends of the final plain stretch (for a subharmonic search); [x0, P(x0), ...]
    plain_scale: np.ndarray | None  # the scale of the last period
    start: np.ndarray | None = None  # the last period's start (state = P(start))
    # the secant pairs (differences of scaled residuals, of images) the extrapolation held at the end,
    # the last period's among them; empty once the search went on with plain periods
    history: tuple = ((), ())


def search_out_every(n_steps: int) -> int:
    """Steps between the outputs of a searching period of n_steps: the largest divisor of n_steps at
    most n_steps // SEARCH_OUTPUTS_PER_PERIOD (at least 1), so the period ends on an output."""
    every = max(n_steps // SEARCH_OUTPUTS_PER_PERIOD, 1)
    while n_steps % every:
        every -= 1
    return every


def accelerated_fixed_point(
    one_period,
    x0: np.ndarray,
    *,
    tol: float,
    max_periods: int,
    depth: int = DEFAULT_DEPTH,
    stall: int = DEFAULT_STALL,
    precondition=None,
    history: tuple = ((), ()),
    first=None,
    on_period=None,
) -> FixedPointSearch:
    """Fixed point of `one_period(x) -> (P(x), scale)` (scale: per-component positive scale of the
    residual, from that period's motion), by Anderson acceleration with plain periods as the
    fallback (module docstring). `history`: secant pairs to start from (a FixedPointSearch's, of a map
    with the same differences); `first`: (P(x0), scale) already stepped, not stepped again nor counted.
    `on_period(residual)`: called after every period stepped with its residual, the measure the
    search accepts by (a progress line, dynamics.search_progress); it does not change the search."""
    x = np.array(x0, dtype=float)
    d_f: deque = deque(history[0], maxlen=depth)  # differences of scaled residuals
    d_g: deque = deque(history[1], maxlen=depth)  # differences of images
    f_prev = g_prev = None
    best = math.inf
    since_best = 0
    accelerating = depth > 0
    plain_ends = [x.copy()]
    residual, scale, image, start = math.inf, None, x, x
    last_image = None  # the last period end the chain reached: a state the extrapolation may fall back to

    def secant_step(image, x, scale):
        """The preconditioned image g and its scaled residual, their secant pair with the last period's
        taken into the history."""
        g = image if precondition is None else x + precondition(image - x)
        f = (g - x) / scale
        if f_prev is not None:
            d_f.append(f - f_prev)
            d_g.append(g - g_prev)
        return g, f

    stepped = 0 if first is None else -1
    while stepped < max_periods:
        stepped += 1
        try:
            image, scale = one_period(x) if stepped else first
        except SolverDivergedError:
            if last_image is None or x is last_image:
                raise
            # an extrapolated start the step cannot take (far outside the motion seen): restart the
            # history from the last period end reached
            x, f_prev, g_prev = last_image, None, None
            d_f.clear()
            d_g.clear()
            continue
        last_image, start = image, x
        f = (image - x) / scale
        residual = float(np.max(np.abs(f)))
        if stepped > 0 and on_period is not None:
            on_period(residual)
        if residual <= tol:
            plain_ends.append(image)
            if accelerating:
                # the accepted period's secant pair too: a search on from here (defect_corrected_fixed_point) takes it
                secant_step(image, x, scale)
            pairs = (tuple(d_f), tuple(d_g)) if accelerating else ((), ())
            return FixedPointSearch(image, True, stepped, residual, plain_ends, scale, start, pairs)
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
        g, f = secant_step(image, x, scale)
        f_prev, g_prev = f, g
        x = g - _extrapolation(d_f, d_g, f) if d_f else g
    pairs = (tuple(d_f), tuple(d_g)) if accelerating else ((), ())
    return FixedPointSearch(image, False, stepped, residual, plain_ends, scale, start, pairs)


@dataclass(frozen=True)
class DefectCorrectedSearch:
    """What defect_corrected_fixed_point returns: the fine map's search (its state, acceptance and
    residual as accelerated_fixed_point's; `periods` both maps' periods) and the periods of each map."""

    search: FixedPointSearch
    coarse_periods: int
    fine_periods: int


def defect_corrected_fixed_point(
    coarse_period,
    fine_period,
    found: FixedPointSearch,
    *,
    tol: float,
    max_periods: int,
    depth: int = DEFAULT_DEPTH,
    stall: int = DEFAULT_STALL,
    precondition=None,
    on_period=None,
) -> DefectCorrectedSearch:
    """Fixed point of the fine map `fine_period(x) -> (F_d(x), scale)` searched with the coarse map
    `coarse_period` (the same period at a coarser step, whose accelerated search `found` converged),
    by defect correction: at the current start x one fine period gives the defect d = F_d(x) - F_c(x)
    (F_c(x) already known), then the fixed point of G(y) = F_c(y) + d is searched with coarse periods.
    G's secant pairs are F_c's (d is constant), so the coarse search's history carries over and its
    first step already applies about (I - J_c)^-1 to the defect along the slow directions. A start is
    accepted by the fine map's own test: one fine period from it changes it by at most `tol`, and the
    state returned is that period's end. The defect is renewed at each G fixed point (searched to
    DEFECT_INNER_TOL_FRACTION of `tol`); the outer iteration contracts by about
    |(I - J_c)^-1 (J_d - J_c)|, small where both maps remove the fast directions in a period.
    `max_periods` bounds both maps' periods together. `on_period(residual)`: after every period of
    either map, with the residual its search accepts by (the fine map's; G's for the coarse periods)."""
    x, coarse_image, history = found.start, found.state, found.history
    coarse_periods = fine_periods = 0
    while True:
        image, scale = fine_period(x)
        fine_periods += 1
        residual = float(np.max(np.abs((image - x) / scale)))
        if on_period is not None:
            on_period(residual)
        converged = residual <= tol
        # the corrected search keeps one period of the budget for the fine test at its fixed point
        left = max_periods - coarse_periods - fine_periods - 1
        if converged or left <= 0:
            fine = FixedPointSearch(
                image, converged, coarse_periods + fine_periods, residual, [x, image], scale, x, history
            )
            return DefectCorrectedSearch(fine, coarse_periods, fine_periods)
        defect = image - coarse_image

        def corrected(y, defect=defect):
            coarse, coarse_scale = coarse_period(y)
            return coarse + defect, coarse_scale

        inner = accelerated_fixed_point(
            corrected,
            x,
            tol=DEFECT_INNER_TOL_FRACTION * tol,
            max_periods=left,
            depth=depth,
            stall=stall,
            precondition=precondition,
            history=history,
            first=(image, scale),
            on_period=on_period,
        )
        coarse_periods += inner.periods
        x, coarse_image, history = inner.start, inner.state - defect, inner.history


def _extrapolation(d_f, d_g, f) -> np.ndarray:
    """Sum of gamma_i dG_i with gamma the least-squares solution of dF gamma = f."""
    df = np.column_stack(d_f)
    gamma = np.linalg.lstsq(df, f, rcond=RCOND)[0]
    return np.column_stack(d_g) @ gamma


def slow_modes(x, is_slow) -> tuple[np.ndarray, np.ndarray]:
    """(omega, shapes) of the symmetric positive semi-definite sparse x's lowest eigenpairs
    (omega = sqrt(lambda), orthonormal shapes as columns) that `is_slow(omega)` accepts: a
    vectorised predicate, true up to some omega and false above it. O(N m) memory.

    A chain's x (K / m, or M^(-1/2) K M^(-1/2) of the machine in its places) is tridiagonal but for
    a few rows (the loop's closing corners, a carriage). The slow modes' count in the tridiagonal
    part (a Sturm count at the slow limit's frequency) bounds x's within the number of those rows
    (the rest is a symmetric perturbation of at most that rank); a basis twice that wide, started
    from the lowest Fourier shapes along the DOFs (the long waves of a loop), is refined by block
    inverse iteration with x's sparse LU and Rayleigh-Ritz until every slow pair's residual is below
    SLOW_MODES_RTOL of the basis' largest Ritz value. Widening shift-invert Lanczos (ARPACK,
    k = 8, 16, ..., 256) took 71 s at 10,000 links and 1-2 s at 1,000 on a loaded machine; this 5 s
    and 0.1 s, the same eigenvalues to 1e-13 and shapes to 1e-14 (measured at 1,000 and 2,000)."""
    from scipy.linalg import eigh
    from scipy.sparse.linalg import splu

    from dynamics.solvers._common import serial_blas

    x = sp.csr_matrix(x)
    n = x.shape[0]
    diag, off = x.diagonal(), x.diagonal(1)
    rest = (x - sp.diags([off, diag, off], [-1, 0, 1])).tocsr()
    rest.eliminate_zeros()
    rank_bound = int(np.count_nonzero(np.diff(rest.indptr)))
    limit = _slow_limit(is_slow, float(np.max(np.abs(diag))) * 4.0)
    width = min(n, 2 * (_count_below(diag, off, limit**2) + rank_bound) + 8)
    shift = -1e-9 * float(np.max(np.abs(diag)))
    lu = splu((x - shift * sp.identity(n, format="csr")).tocsc())
    place = 2.0 * np.pi * np.arange(n)[:, None] / n
    waves = np.arange(1, width // 2 + 1)[None, :]
    basis = np.hstack([np.ones((n, 1)), np.cos(place * waves), np.sin(place * waves)])[:, :width]
    with serial_blas():  # small dense products: a threaded BLAS on a busy machine is many times slower
        for _ in range(SLOW_MODES_MAX_ITERATIONS):
            # the columns stay near orthogonal shapes, so after scaling each to unit length the Gram
            # matrix is well conditioned and the generalised Rayleigh-Ritz needs no QR
            basis = lu.solve(basis)
            basis /= np.linalg.norm(basis, axis=0)
            lam, rotation = eigh(basis.T @ (x @ basis), basis.T @ basis)
            basis = basis @ rotation
            slow = is_slow(np.sqrt(np.maximum(lam, 0.0)))
            residual = np.linalg.norm(x @ basis[:, slow] - basis[:, slow] * lam[slow], axis=0)
            if np.all(residual <= SLOW_MODES_RTOL * lam[-1]):
                break
    if slow[-1] and width < n:
        raise SolverFailedError("slow modes: the basis holds no mode above the slow ones; widen it")
    return np.sqrt(np.maximum(lam[slow], 0.0)), np.ascontiguousarray(basis[:, slow])


def _slow_limit(is_slow, lam_max: float) -> float:
    """The omega where is_slow turns false (bisection in [0, sqrt(lam_max)], to 1e-6 of it)."""
    low, high = 0.0, float(np.sqrt(lam_max))
    if is_slow(np.array([high]))[0]:
        return high
    while high - low > 1e-6 * high:
        mid = 0.5 * (low + high)
        low, high = (mid, high) if is_slow(np.array([mid]))[0] else (low, mid)
    return high


def _count_below(diag: np.ndarray, off: np.ndarray, lam: float) -> int:
    """The number of eigenvalues below lam of the symmetric tridiagonal matrix (diag, off): the
    negative pivots of its LDL^T shifted by lam (Sturm)."""
    count, pivot = 0, 1.0
    tiny = np.finfo(float).tiny
    for i in range(diag.size):
        pivot = diag[i] - lam - (off[i - 1] ** 2 / pivot if i else 0.0)
        if pivot == 0.0:
            pivot = tiny
        count += pivot < 0.0
    return int(count)


def slow_mode_newton(stiffness, mass_kg: float, damping_ratio_at, period_s: float, decay: float):
    """r -> the Newton step (I - Phi)^-1 r of the linear chain's one-period map on its slowly decaying
    modes (per period decay exp(-zeta omega T) above `decay`), r itself on the others (a plain period).

    stiffness: the chain's sparse K (N x N), mass matrix mass_kg I; damping_ratio_at(omega) the
    modes' damping ratios. The state is (y, w, anything else): the first 2N entries are the links'.
    In the orthonormal modes phi_j of K / m each mode's period map is the 2 x 2 exponential of its
    damped oscillator over T, so (I - Phi)^-1 is 2 x 2 blocks: O(N m) per step, no N x N array."""
    from scipy.linalg import expm

    x = (stiffness / mass_kg).tocsc()
    n = x.shape[0]

    def is_slow(omega):
        return np.exp(-np.array([damping_ratio_at(o) * o for o in omega]) * period_s) > decay

    if n <= DENSE_EIGENSOLVE_UP_TO:
        lam, vec = np.linalg.eigh(x.toarray())
        omega = np.sqrt(np.maximum(lam, 0.0))
        slow = is_slow(omega)
    else:
        omega, vec = slow_modes(x, is_slow)
        slow = np.ones(omega.size, dtype=bool)
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
