"""The machine on its wheels' global damping at O(N) cost per product (issue #24).

MachineOnWheels.damping_matrix is modal ratio zeta on the chain's DOFs with the carriage held (or
Rayleigh alpha M + beta K there) plus the carriage's own dashpot c_t: dense, N^2 per product. Here
the chain-DOF block is applied without forming it. With M diagonal but not uniform (wheel groups,
idler) the modal C is C = 2 zeta M^(1/2) sqrt(S) M^(1/2), S = M^(-1/2) K M^(-1/2) (the same matrix:
M Phi diag(2 zeta omega) Phi^T M with Phi = M^(-1/2) V, S = V diag(omega^2) V^T), and sqrt(S) is
applied as in dynamics.models.reduced_damping: sqrt(x) = x (2 / pi) sum_j h t_j / (x + t_j^2), the
trapezoidal rule in ln t, the same relative error for every mode (about 2 exp(-pi^2 / h) from the
spacing plus exp(-L) from the tails), so each mode's ratio is zeta (1 +- tolerance).

The chain-DOF block of K is the places along the loop joined by spans plus the ground springs
(drive compliance): cyclic tridiagonal in loop order (tridiagonal when an end is held). Each node's
shifted solve (S + tau_j I) is Thomas on the tridiagonal part and Sherman-Morrison for the loop's
corner, factors precomputed: storage about 3 N per node, a product about 10 N per node. The carriage
is not in the block: its c_t acts as a dashpot on its own DOF, exactly as in the dense C.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dynamics.errors import DynamicsError

DEFAULT_MACHINE_DAMPING_TOLERANCE = 1e-4


def sqrt_nodes(tolerance: float, x_min: float, x_max: float) -> tuple[np.ndarray, np.ndarray]:
    """(tau_j = t_j^2, c_j = (2 / pi) h t_j) of the trapezoidal rule for sqrt(x) on [x_min, x_max]:
    h = pi^2 / ln(8 / tolerance), tails ln(4 / tolerance) past ln sqrt of the bounds."""
    h = math.pi**2 / math.log(8.0 / tolerance)
    tail = math.log(4.0 / tolerance)
    lo, hi = 0.5 * math.log(x_min) - tail, 0.5 * math.log(x_max) + tail
    s = lo + h * np.arange(int(math.ceil((hi - lo) / h)) + 1)
    t = np.exp(s)
    return t * t, (2.0 / math.pi) * h * t


@dataclass(frozen=True, eq=False)
class MachineDamping:
    """The chain-DOF block of the machine's C as the compiled step takes it (module docstring).

    dofs: the chain's DOFs in loop order; tri (n, 6): sqrt(m), m, S's diagonal, S's entry (i, i+1),
    K's diagonal, K's entry (i, i+1); scalars: S's corner (0, n-1), K's corner, 2 zeta, alpha, beta;
    factors (p, 3, n) and sm (p, 2): each node's Thomas pivots' inverses, forward coefficients and
    Sherman-Morrison vector, and (1 / (1 + v.z), corner / gamma); weights (p,)."""

    dofs: np.ndarray
    tri: np.ndarray
    scalars: np.ndarray
    factors: np.ndarray
    sm: np.ndarray
    weights: np.ndarray

    def times(self, w: np.ndarray) -> np.ndarray:
        """C_chain w on the chain's DOFs (w and the result in loop order)."""
        out = np.zeros(w.shape[0])
        scratch = np.zeros((4, w.shape[0]))
        chain_damping_into(self.tri, self.scalars, self.factors, self.sm, self.weights, w, out, scratch)
        return out


def of_machine(machine, tolerance: float = DEFAULT_MACHINE_DAMPING_TOLERANCE) -> MachineDamping:
    """The O(N) form of `machine.damping_matrix()`'s chain-DOF block (modal or Rayleigh)."""
    topo = machine.topology
    dofs = np.array([d for d, carried in enumerate(topo.links) if carried], dtype=np.int64)
    k = topo.stiffness_matrix_sparse()[dofs][:, dofs].tocsr()
    m = np.asarray(topo.masses_kg, dtype=float)[dofs]
    n = dofs.size
    kd, koff = k.diagonal(), np.append(k.diagonal(1), 0.0)
    kcorner = float(k[0, n - 1]) if n > 2 else 0.0
    banded = np.count_nonzero(kd) + np.count_nonzero(koff) * 2 + (2 if kcorner else 0)
    if k.count_nonzero() != banded:
        raise DynamicsError("machine damping: the chain's stiffness is not cyclic tridiagonal in loop order")
    rm = np.sqrt(m)
    sd = kd / m
    soff = koff / np.append(rm[:-1] * rm[1:], 1.0)
    scorner = kcorner / (rm[0] * rm[-1])
    chain = machine.chain
    if chain.rayleigh_coefficients is not None:
        alpha, beta = chain.rayleigh_coefficients
        taus, weights, two_zeta = np.zeros(0), np.zeros(0), 0.0
    else:
        alpha, beta, two_zeta = 0.0, 0.0, 2.0 * chain.damping_ratio
        x_min, x_max = _eigenvalue_bounds(sd, soff, scorner)
        taus, weights = sqrt_nodes(tolerance, x_min, x_max)
    factors = np.zeros((taus.size, 3, n))
    sm = np.zeros((taus.size, 2))
    for j, tau in enumerate(taus):
        factors[j], sm[j] = _factor(sd + tau, soff, scorner)
    tri = np.ascontiguousarray(np.column_stack([rm, m, sd, soff, kd, koff]))
    scalars = np.array([scorner, kcorner, two_zeta, alpha, beta])
    return MachineDamping(dofs, tri, scalars, factors, sm, np.ascontiguousarray(weights, dtype=float))


def _eigenvalue_bounds(sd, soff, scorner) -> tuple[float, float]:
    """(smallest, largest) eigenvalue of S from its sparse form (no N x N array for long chains)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigsh

    n = sd.size
    s = sp.diags([soff[:-1], sd, soff[:-1]], [-1, 0, 1], format="lil")
    if n > 2:
        s[0, n - 1] = s[n - 1, 0] = scorner
    s = s.tocsc()
    if n <= 64:
        lam = np.linalg.eigvalsh(s.toarray())
        return float(lam[0]), float(lam[-1])
    top = eigsh(s, k=1, which="LA", return_eigenvectors=False, tol=1e-10)[0]
    bottom = eigsh(s, k=1, sigma=0.0, which="LM", return_eigenvectors=False, tol=1e-10)[0]
    return float(bottom), float(top)


def _factor(diag, off, corner):
    """Factors of A = T + u v^T (gamma = -A_00, u = (gamma, 0.., corner), v = (1, 0.., corner / gamma)),
    T tridiagonal with diagonal `diag` (T_00, T_nn corrected) and entries off[i] at (i, i+1)."""
    n = diag.size
    gamma = -diag[0]
    t = diag.copy()
    t[0] -= gamma
    t[-1] -= corner * corner / gamma
    inv, cp = np.empty(n), np.empty(n)
    inv[0] = 1.0 / t[0]
    cp[0] = off[0] * inv[0]
    for i in range(1, n):
        inv[i] = 1.0 / (t[i] - off[i - 1] * cp[i - 1])
        cp[i] = off[i] * inv[i]
    u = np.zeros(n)
    u[0], u[-1] = gamma, corner
    z = np.empty(n)
    _thomas_into(inv, cp, off, u, z)
    ratio = corner / gamma
    return np.array([inv, cp, z]), np.array([1.0 / (1.0 + z[0] + ratio * z[-1]), ratio])


def _thomas_into(inv, cp, off, b, y):
    """y = T^-1 b from the Thomas factors (T symmetric tridiagonal, off[i] at (i, i+1))."""
    n = b.shape[0]
    y[0] = b[0] * inv[0]
    for i in range(1, n):
        y[i] = (b[i] - off[i - 1] * y[i - 1]) * inv[i]
    for i in range(n - 2, -1, -1):
        y[i] -= cp[i] * y[i + 1]


def _cyclic_times_into(diag, off, corner, x, y):
    """y = A x, A symmetric cyclic tridiagonal (diagonal, off[i] at (i, i+1), corner at (0, n-1))."""
    n = x.shape[0]
    for i in range(n):
        y[i] = diag[i] * x[i]
    for i in range(n - 1):
        y[i] += off[i] * x[i + 1]
        y[i + 1] += off[i] * x[i]
    y[0] += corner * x[n - 1]
    y[n - 1] += corner * x[0]


def chain_damping_into(tri, scalars, factors, sm, weights, w, out, scratch):
    """out = C_chain w (module docstring); scratch (4, n). Modal: 2 zeta M^(1/2) S sum_j c_j
    (S + tau_j I)^-1 M^(1/2) w; Rayleigh: alpha M w + beta K w."""
    n = w.shape[0]
    two_zeta, alpha, beta = scalars[2], scalars[3], scalars[4]
    y, acc, sol, prod = scratch[0], scratch[1], scratch[2], scratch[3]
    for i in range(n):
        out[i] = 0.0
    if alpha != 0.0 or beta != 0.0:
        _cyclic_times_into(tri[:, 4], tri[:, 5], scalars[1], w, prod)
        for i in range(n):
            out[i] = alpha * tri[i, 1] * w[i] + beta * prod[i]
    if weights.shape[0] == 0:
        return
    for i in range(n):
        y[i] = tri[i, 0] * w[i]
        acc[i] = 0.0
    for j in range(weights.shape[0]):
        _thomas_into(factors[j, 0], factors[j, 1], tri[:, 3], y, sol)
        g = sm[j, 0] * (sol[0] + sm[j, 1] * sol[n - 1])
        for i in range(n):
            acc[i] += weights[j] * (sol[i] - g * factors[j, 2, i])
    _cyclic_times_into(tri[:, 2], tri[:, 3], scalars[0], acc, prod)
    for i in range(n):
        out[i] += two_zeta * tri[i, 0] * prod[i]


try:
    import numba
except ImportError:  # pragma: no cover
    numba = None

if numba is not None:
    for _name in ("_thomas_into", "_cyclic_times_into", "chain_damping_into"):
        globals()[_name] = numba.njit(cache=True)(globals()[_name])
