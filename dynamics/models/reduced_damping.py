"""The global damping law at O(N) cost per product, every mode's damping ratio kept (issue 24).

The chain's modal damping C = M Phi diag(2 zeta omega_j) Phi^T M is, with M = m I, the matrix function
C = 2 zeta m sqrt(X), X = K / m: dense (N^2 multiply-adds per product, N^2 storage, a dense eigensolve
to build it). Here sqrt(X) is applied without forming it, from

    sqrt(x) = (2 / pi) integral over s of x e^s / (x + e^(2 s)) ds = X (2 / pi) sum_j h t_j (X + t_j^2)^-1,

the trapezoidal rule in s = ln t (nodes t_j = e^(s_j), spacing h). The integrand is
sqrt(x) / (2 cosh(s - ln sqrt x)), the same bump shifted for every eigenvalue x, so the rule's relative
error is the same for every mode: about 2 exp(-pi^2 / h) from the spacing (the bump's poles lie pi/2
off the real axis) plus what the nodes beyond the last ones kept would add. Those tails are taken in
closed form (`nodes_for`): far below sqrt(x) the integrand is e^s, far above it x e^-s, so the
missing nodes sum to a + b x, an identity and a K term (Rayleigh's, no solves), to a relative
(2 / pi) h e^(-3 L) / (e^(3 h) - 1) (0.044 e^(-3 L) at 1e-4), L the distance from ln sqrt of the
extreme eigenvalues to the last nodes. So
`nodes_for(tolerance)` takes h = pi^2 / ln(8 / tolerance) and L about ln(1 / tolerance) / 3 (2.5 at
1e-4, where untreated tails would need ln(4 / tolerance) = 10.6): each mode's damping ratio is
zeta (1 +- tolerance) (measured: 0.53 tolerance at N = 85 and 400). Each node is one solve with
X + t_j^2 I, the chain's ring of springs plus the drive spring: cyclic tridiagonal, solved in O(N)
(Thomas on the tridiagonal part, Sherman-Morrison for the ring's corner), factors precomputed. So a
product costs about 10 N per node (12-17 nodes for 1e-4 from 85 to 10,000 links) and storage is 3 N
per node: linear in N. Every term is a positive function of X, so C stays symmetric positive
semi-definite; the top mode's ratio, which sets the explicit step's limit, is zeta (1 +- tolerance).
Rayleigh damping needs no nodes: a0 M + a1 K.
With a tight tolerance (1e-13) the form equals the dense C to round-off (tests/test_reduced_damping.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from dynamics.models.chain import ChainModel
from dynamics.models.lanczos import lanczos_start

# Relative error of every mode's damping ratio in the default reduced form (the dense form's own
# eigensolve is exact to ~1e-13; 1e-4 is far below what the 1e-3 station metrics can see).
DEFAULT_DAMPING_TOLERANCE = 1e-4


def nodes_for(tolerance: float, x_min: float, x_max: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(tau_j = t_j^2, c_j = (2 / pi) h t_j, a, b) of the trapezoidal rule for sqrt(x) on [x_min, x_max]
    with its tails in closed form: sqrt(x) = a + b x + x sum_j c_j / (x + tau_j) to `tolerance`
    relative, for every x in the range.

    The rule's nodes beyond the last ones kept, s_lo - i h and s_hi + i h (i >= 1), would add
    (2 / pi) h sum x t / (x + t^2): far below sqrt(x) each term is t (1 - t^2 / x + ...), far above
    x / t (1 - x / t^2 + ...), so their sums are a = (2 / pi) h t_lo / (e^h - 1) and b = (2 / pi) h /
    (t_hi (e^h - 1)) to a relative error of (2 / pi) h / (e^(3 h) - 1) e^(-3 L) at most, L the
    distance (in ln t) from the range's ends to the last nodes. That is one identity term and one K
    term (Rayleigh's), no solves, and L falls from ln(4 / tolerance) (10.6 at 1e-4) to about a third of
    it: about half the nodes at 1,000 links."""
    h = math.pi**2 / math.log(8.0 / tolerance)  # spacing error 2 exp(-pi^2 / h) = tolerance / 4
    tail_factor = (2.0 / math.pi) * h / math.expm1(3.0 * h)
    tail = max(math.log(4.0 * tail_factor / tolerance) / 3.0, 0.0)  # each tail's error tolerance / 4
    lo, hi = 0.5 * math.log(x_min) - tail, 0.5 * math.log(x_max) + tail
    s = lo + h * np.arange(int(math.ceil((hi - lo) / h)) + 1)
    t = np.exp(s)
    c = (2.0 / math.pi) * h
    return t * t, c * t, c * t[0] / math.expm1(h), c / (t[-1] * math.expm1(h))


# The best-fit rule's pole counts tried (more than the trapezoidal rule ever needs at 1e-4) and its
# check: the fitted sqrt's relative error on FIT_CHECK_POINTS log-spaced points of the range (its
# error oscillates p + 2 times over the range, smoothly in ln x: thousands of points resolve every
# extremum; the tests check it on 200,000).
ZOLOTAREV_MAX_POLES = 24
FIT_POINTS = 400
FIT_CHECK_POINTS = 4000
FIT_ITERATIONS = 12
# Below this tolerance the trapezoidal rule is taken (the fit's least squares reach about 1e-12)
FIT_TOLERANCE_FLOOR = 1e-10


def zolotarev_nodes_for(tolerance: float, x_min: float, x_max: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(tau_j, c_j, a, b) as `nodes_for` (sqrt(x) = a + b x + x sum_j c_j / (x + tau_j) to `tolerance`
    relative on [x_min, x_max]) with about half its nodes, or `nodes_for`'s own where this rule
    cannot reach `tolerance` (below about 1e-10: the fit's round-off).

    The poles are Zolotarev's for 1 / sqrt(y) on [1, kappa] (kappa = x_max / x_min, y = x / x_min):
    tau'_l = sn^2(u_l; m) / cn^2(u_l; m), u_l = (2 l - 1) K(m) / (2 p + 1), m = 1 - 1 / kappa (the best
    relative rational approximation's poles; its error falls by about exp(2 pi^2 / ln(16 kappa)) per
    pole, against exp(pi^2 / (ln(kappa) / 2 + 5)) for the trapezoidal rule with tails at 1e-4). The
    coefficients (a, b, c) are fitted to them by weighted least squares on the relative error with
    Lawson's reweighting toward the minimax fit, and the smallest p whose error, checked on
    FIT_CHECK_POINTS points, is at most `tolerance` is taken. The error is a function of the
    eigenvalue alone, so every mode's ratio is zeta (1 +- tolerance), and the fitted function is
    positive on the whole range (within `tolerance` of sqrt(x)), so C stays positive definite
    whatever the sign of a. Measured on the default wheels (12 teeth, six links seated on each wheel,
    fixed idler axle): at 1e-4, 8 poles at 1,000 links and 11 at 10,000 against the trapezoidal
    rule's 15 and 17; at the machine's 1e-5, 10 and 13 against 20 and 23."""
    from scipy.special import ellipj, ellipkm1

    from dynamics.solvers._common import serial_blas

    kappa = x_max / x_min
    if tolerance < FIT_TOLERANCE_FLOOR or kappa <= 1.0:
        return nodes_for(tolerance, x_min, x_max)
    y_fit = np.geomspace(1.0, kappa, FIT_POINTS)
    y_check = np.geomspace(1.0, kappa, FIT_CHECK_POINTS)
    # start a pole or two below the count the error's rate predicts
    first = max(1, int(math.log(1.0 / tolerance) * math.log(16.0 * kappa) / (2.0 * math.pi**2)) - 1)
    last = math.inf
    with serial_blas():  # small dense least squares: a threaded BLAS on a busy machine is many times slower
        for p in range(first, ZOLOTAREV_MAX_POLES + 1):
            u = np.arange(1, 2 * p + 1, 2) * ellipkm1(1.0 / kappa) / (2 * p + 1)
            sn, cn, _, _ = ellipj(u, 1.0 - 1.0 / kappa)
            poles = sn**2 / cn**2
            coefficients = _fitted_sqrt(y_fit, poles)
            error = float(np.max(np.abs(_sqrt_design(y_check, poles) @ coefficients - 1.0)))
            if error <= tolerance:
                scale = math.sqrt(x_min)
                a, b, c = coefficients[0], coefficients[1], coefficients[2:]
                return poles * x_min, c * scale, float(a * scale), float(b * scale / x_min)
            if error > 0.5 * last:  # no longer converging (the elliptic functions' or the fit's round-off)
                break
            last = error
    return nodes_for(tolerance, x_min, x_max)


def _sqrt_design(y: np.ndarray, poles: np.ndarray) -> np.ndarray:
    """Columns 1, y, y / (y + tau_l), each divided by sqrt(y) (the relative error's design)."""
    return np.column_stack([np.ones_like(y), y, y[:, None] / (y[:, None] + poles[None, :])]) / np.sqrt(y)[:, None]


def _fitted_sqrt(y: np.ndarray, poles: np.ndarray) -> np.ndarray:
    """(a, b, c_l): least squares of the relative error, reweighted by it (Lawson) toward the minimax."""
    design = _sqrt_design(y, poles)
    weights = np.full(y.size, 1.0 / y.size)
    for _ in range(FIT_ITERATIONS):
        root = np.sqrt(weights)
        coefficients = np.linalg.lstsq(design * root[:, None], root, rcond=None)[0]
        weights = weights * np.abs(design @ coefficients - 1.0)
        weights /= np.sum(weights)
    return coefficients


@dataclass(frozen=True, eq=False)
class ReducedDamping:
    """C w = a0 m w + a1 K w + 2 zeta K sum_j c_j (K / m + tau_j I)^-1 w, K the ring of N springs k plus
    the drive spring k_d on link 0 ((a0, a1) Rayleigh coefficients, 0 for modal damping)."""

    n_links: int
    mass_kg: float
    stiffness_N_per_m: float
    drive_stiffness_N_per_m: float
    rayleigh: tuple[float, float]  # (a0 1/s, a1 s)
    zeta: float
    taus: np.ndarray  # (p,)
    weights: np.ndarray  # (p,)

    @property
    def shape(self) -> tuple[int, int]:
        return self.n_links, self.n_links

    def stiffness_times(self, w: np.ndarray) -> np.ndarray:
        kw = self.stiffness_N_per_m * (2.0 * w - np.roll(w, 1) - np.roll(w, -1))
        kw[0] += self.drive_stiffness_N_per_m * w[0]
        return kw

    def __matmul__(self, w: np.ndarray) -> np.ndarray:
        w = np.asarray(w, dtype=float)
        a0, a1 = self.rayleigh
        out = a0 * self.mass_kg * w + a1 * self.stiffness_times(w)
        if self.taus.size:
            _, weights, factors, sm = self.packed()
            acc = weights @ cyclic_solves(factors, sm, -self.stiffness_N_per_m / self.mass_kg, w)
            out = out + 2.0 * self.zeta * self.stiffness_times(acc)
        return out

    def dense(self) -> np.ndarray:
        """The N x N matrix (for checks on short chains)."""
        return np.column_stack([self @ e for e in np.eye(self.n_links)])

    def packed(self):
        """(coefficients [a0 m, a1 k, a1 k_d, 2 zeta k, 2 zeta k_d, -k / m], weights (p,), factors (p, 3, N):
        per node the Thomas pivots' inverses, forward coefficients and Sherman-Morrison vector z, and
        sm (p, 2): per node 1 / (1 + v.z) and v's last entry) as the compiled step takes them; cached."""
        cached = self.__dict__.get("_packed")
        if cached is None:
            cached = self._pack()
            object.__setattr__(self, "_packed", cached)
        return cached

    def _pack(self):
        a0, a1 = self.rayleigh
        n, m, k, kd = self.n_links, self.mass_kg, self.stiffness_N_per_m, self.drive_stiffness_N_per_m
        coefficients = np.array([a0 * m, a1 * k, a1 * kd, 2.0 * self.zeta * k, 2.0 * self.zeta * kd, -k / m])
        factors, sm = _factors(m, k, kd, np.asarray(self.taus, dtype=float), n)
        return coefficients, np.ascontiguousarray(self.weights, dtype=float), factors, sm


def _factors(m, k, kd, taus, n):
    """Factors of A_j = K / m + tau_j I = T_j + u v^T for every node (Numerical Recipes' cyclic form,
    gamma = -A_00): u = (gamma, 0.., e), v = (1, 0.., e / gamma), e = -k / m the off-diagonal and
    corner entries; T tridiagonal, factored by Thomas, the recurrences over the links with the nodes
    as the vector. Returns (p, 3, N) (inverse pivots, forward coefficients, z = T^-1 u) and (p, 2)
    (1 / (1 + v.z), e / gamma)."""
    e = -k / m
    p = taus.size
    diag = np.broadcast_to(2.0 * k / m + taus[:, None], (p, n)).copy()
    diag[:, 0] += kd / m
    gamma = -diag[:, 0]
    t = diag
    t[:, 0] -= gamma
    t[:, -1] -= e * e / gamma
    inv, cp = np.empty((p, n)), np.empty((p, n))
    inv[:, 0] = 1.0 / t[:, 0]
    cp[:, 0] = e * inv[:, 0]
    for i in range(1, n):
        inv[:, i] = 1.0 / (t[:, i] - e * cp[:, i - 1])
        cp[:, i] = e * inv[:, i]
    u = np.zeros((p, n))
    u[:, 0], u[:, -1] = gamma, e
    z = _thomas_stacked(inv, cp, e, u)
    ratio = e / gamma
    return np.stack([inv, cp, z], axis=1), np.column_stack([1.0 / (1.0 + z[:, 0] + ratio * z[:, -1]), ratio])


def _thomas_stacked(inv, cp, e, b):
    """T_j^-1 b_j for every node (rows)."""
    y = np.empty(b.shape)
    y[:, 0] = b[:, 0] * inv[:, 0]
    for i in range(1, b.shape[1]):
        y[:, i] = (b[:, i] - e * y[:, i - 1]) * inv[:, i]
    for i in range(b.shape[1] - 2, -1, -1):
        y[:, i] -= cp[:, i] * y[:, i + 1]
    return y


def cyclic_solves(factors, sm, e, b):
    """(p, N): A_j^-1 b for every node (`_factor`'s parts stacked), the recurrences run over the links
    with the nodes as the vector: Thomas, then Sherman-Morrison."""
    inv, cp, z = factors[:, 0], factors[:, 1], factors[:, 2]
    n = b.shape[0]
    y = np.empty(inv.shape)
    y[:, 0] = b[0] * inv[:, 0]
    for i in range(1, n):
        y[:, i] = (b[i] - e * y[:, i - 1]) * inv[:, i]
    for i in range(n - 2, -1, -1):
        y[:, i] -= cp[:, i] * y[:, i + 1]
    return y - (sm[:, 0] * (y[:, 0] + sm[:, 1] * y[:, -1]))[:, None] * z


def eigenvalue_bounds(chain: ChainModel) -> tuple[float, float]:
    """(smallest, largest) eigenvalue of K / m from the sparse K (no N x N array)."""
    from scipy.sparse.linalg import eigsh

    from dynamics.response.sweep import stiffness_matrix_sparse

    x = (stiffness_matrix_sparse(chain) / chain.link_mass_kg).tocsc()
    if chain.n_links <= 64:
        lam = np.linalg.eigvalsh(x.toarray())
        return float(lam[0]), float(lam[-1])
    start = lanczos_start(chain.n_links)
    top = eigsh(x, k=1, which="LA", v0=start, return_eigenvectors=False, tol=1e-10)[0]
    bottom = eigsh(x, k=1, sigma=0.0, which="LM", v0=start, return_eigenvectors=False, tol=1e-10)[0]
    return float(bottom), float(top)


@lru_cache(maxsize=16)
def reduced_damping(chain: ChainModel, tolerance: float = DEFAULT_DAMPING_TOLERANCE) -> ReducedDamping:
    """The chain's global damping law in the O(N) form, each mode's ratio within `tolerance`; Rayleigh
    damping exactly, without nodes."""
    n, m, k, kd = chain.n_links, chain.link_mass_kg, chain.stiffness_N_per_m, chain.drive_stiffness
    if chain.rayleigh_coefficients is not None:
        return ReducedDamping(n, m, k, kd, tuple(chain.rayleigh_coefficients), 0.0, np.zeros(0), np.zeros(0))
    x_min, x_max = eigenvalue_bounds(chain)
    taus, weights, a, b = nodes_for(tolerance, x_min, x_max)
    # the tails a + b X of sqrt(X): 2 zeta m (a I + b K / m) = Rayleigh (2 zeta a, 2 zeta b)
    zeta = chain.damping_ratio
    return ReducedDamping(n, m, k, kd, (2.0 * zeta * a, 2.0 * zeta * b), zeta, taus, weights)
