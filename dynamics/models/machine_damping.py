"""The machine on its wheels' global damping at O(N) cost per product (issue #24).

MachineOnWheels.damping_matrix is modal ratio zeta on the chain's DOFs with the carriage held (or
Rayleigh alpha M + beta K there) plus the carriage's own dashpot c_t: dense, N^2 per product. Here
the chain-DOF block is applied without forming it. With M diagonal but not uniform (wheel groups,
idler) the modal C is C = 2 zeta M^(1/2) sqrt(S) M^(1/2), S = M^(-1/2) K M^(-1/2) (the same matrix:
M Phi diag(2 zeta omega) Phi^T M with Phi = M^(-1/2) V, S = V diag(omega^2) V^T), and sqrt(S) is
applied as in dynamics.models.reduced_damping: sqrt(x) = a + b x + x sum_j c_j / (x + tau_j), with
Zolotarev's poles and fitted coefficients (`reduced_damping.zolotarev_nodes_for`: about 60 % of the
nodes of the trapezoidal rule in ln t, `reduced_damping.nodes_for`, for the same tolerance), the
same relative error for every mode, so each mode's ratio is zeta (1 +- tolerance). The terms a + b S
are a Rayleigh term: 2 zeta M^(1/2) (a I + b S) M^(1/2) = 2 zeta (a M + b K), no solves.

The chain-DOF block of K is the places along the loop joined by spans plus the ground springs
(drive compliance): cyclic tridiagonal in loop order (tridiagonal when an end is held). Each node's
shifted solve (S + tau_j I) is Thomas on the tridiagonal part and Sherman-Morrison for the loop's
corner, factors precomputed. The product runs the recurrences over the places with the nodes as the
vector (factors stored (N, p) per part, place by place): the p solves are independent, so each place's
update is one short vector operation instead of p dependent scalar ones, the recurrence's latency
paid once per place, not once per place and node. Storage about 3 N p, a product about 10 N p
operations. Building the form is O(N p): the range of S from its Gershgorin bound (the top) and a
shift-invert Lanczos at 0 (the bottom), the factors' recurrences vectorised over the nodes. The carriage
is not in the block: its c_t acts as a dashpot on its own DOF, exactly as in the dense C.

The tooth model's wheels (MachineOnWheels with a finite tooth stiffness: each wheel a DOF of its own
after the links, held to its seated links by the tooth springs) are in the block too, as the dense C
has them (they move with the cam). They border the links' cyclic tridiagonal S: S = [[A, B], [B^T, D]],
B's column w the tooth springs -k_t / sqrt(m_i m_w) on wheel w's seated links (a run of places), D
diagonal (the wheels are joined to each other only through the links). Each node's solve is the
bordered one: with A_j = A + tau_j I (its factors as above) and Z_j = A_j^-1 B (stored with the
factors, n per wheel and node), x_w = G_j^-1 (r_w - B^T A_j^-1 r_l), G_j = D + tau_j I - B^T Z_j
(its inverse stored, a wheel count squared per node), and x_l = A_j^-1 r_l - Z_j x_w: O(N) still,
about 2 N p more per wheel. Rigid seating has no border and the same arithmetic as without it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from dynamics.errors import DynamicsError
from dynamics.models.lanczos import lanczos_start
from dynamics.models.reduced_damping import zolotarev_nodes_for

# Each mode's damping ratio to this relative error. The station metrics are about ten times as
# sensitive to it as to a uniform change of zeta (the impacts' peaks; measured at 1,000 links on the
# default wheels, 0.094 mm, 180 rpm, against the form at 1e-6: 1.1e-3 at 1e-4 with this rule, 3.6e-4
# with the trapezoidal rule at 1e-4 (14 nodes, its error 0.53 of the tolerance), 9e-5 at 1e-5 (10
# nodes)): 1e-5 keeps them well inside the 1e-3 output accuracy with fewer nodes than before.
DEFAULT_MACHINE_DAMPING_TOLERANCE = 1e-5
# Above LONG_MACHINE_DAMPING_ABOVE_LINKS links each mode's ratio to LONG_MACHINE_DAMPING_TOLERANCE
# instead: there the station metrics are far more sensitive to it. At 3,000 links (default wheels,
# 0.094 mm, 180 rpm) the slack side's RMS a was 8.3e-3 from the tight runs (each ratio to 1e-7, the
# step at the default safety / 5 and / 10) at 1e-5, 1.3e-3 at 1e-7 with nothing else changed
# (benchmarks/bench_long_accuracy.py, docs/performance.md "Long clearance chains on wheels"), for 2 %
# more CPU (20.8 against 20.3 s; 16 nodes against 12, 18 against 13 at 10,000 links). By length, not
# by the slowest mode's decay per cycle as the searches' settings (dynamics.machine_scene): the form is
# built with the machine, before any cam. Up to 2,000 links (where the factors are still stored in
# double) the default run's numbers stay as they were: 9e-5 from the form at 1e-6 at 1,000 links,
# 2.5e-4 from the tight run at 2,000.
LONG_MACHINE_DAMPING_TOLERANCE = 1e-7
LONG_MACHINE_DAMPING_ABOVE_LINKS = 2000
# The factors (3 n p numbers, the product's memory traffic) are stored in single precision above this
# many links (the recurrences still run in double): at 10,000 links they no longer fit in the core's
# share of L2 and the product is bound by their loads, 385 against 741 us a product (13 nodes, 10,000
# links; 98 against 142 us at 3,000, 90 against 97 us at 2,000); at 1,000 links the conversions cost
# more than the loads save (44 against 34 us). Each mode's ratio moves by under 4e-7 (measured at 400
# and 2,000 links against the dense (K, M) modes: worst ratio error 5.5e-6 and 6.9e-6, the rule's
# own 5.5e-6 and 6.8e-6), far inside the 1e-5 tolerance; up to this length (where the dense form's
# check runs) the factors stay in double.
SINGLE_PRECISION_FACTORS_ABOVE_LINKS = 2000
FACTOR_PRECISIONS = {"single": np.float32, "double": np.float64}


@dataclass(frozen=True, eq=False)
class MachineDamping:
    """The chain-DOF block of the machine's C as the compiled step takes it (module docstring).

    dofs: the chain's DOFs, the links' in loop order (n), then the tooth model's wheels' (nw, none
    with rigid seating); tri (n, 6): sqrt(m), m, S's diagonal, S's entry (i, i+1), K's diagonal, K's
    entry (i, i+1); scalars: S's corner (0, n-1), K's corner, 2 zeta, alpha, beta (alpha M + beta K:
    Rayleigh damping, or the modal rule's tails); factors (3 + nw, n, p): each node's Thomas pivots'
    inverses, forward coefficients and Sherman-Morrison vector, then Z = A^-1 B's column per wheel,
    place by place (single precision on long chains, SINGLE_PRECISION_FACTORS_ABOVE_LINKS); sm
    (p, 2 + nw^2): (1 / (1 + v.z), corner / gamma, G^-1 row by row); weights (p,); border (nw, 8)
    per wheel: its first seated place, their count, sqrt(m_w), m_w, S's and K's diagonal, S's and K's
    entry to each of its seated places."""

    dofs: np.ndarray
    tri: np.ndarray
    scalars: np.ndarray
    factors: np.ndarray
    sm: np.ndarray
    weights: np.ndarray
    border: np.ndarray

    def scratch(self) -> np.ndarray:
        """The work array `chain_damping_into` takes: (6, max(n p, n + nw, (2 + nw) p)); rows 4 and 5
        are the caller's."""
        n, p, nw = self.tri.shape[0], self.weights.shape[0], self.border.shape[0]
        return np.zeros((6, max(n * p, n + nw, (2 + nw) * p)))

    def times(self, w: np.ndarray) -> np.ndarray:
        """C_chain w on the chain's DOFs (w and the result in `dofs` order)."""
        out = np.zeros(w.shape[0])
        chain_damping_into(
            self.tri, self.scalars, self.factors, self.sm, self.weights, self.border, w, out, self.scratch()
        )
        return out


def default_factor_precision(n_links: int) -> str:
    """The factors' precision (FACTOR_PRECISIONS) for a machine of `n_links` links."""
    return "single" if n_links > SINGLE_PRECISION_FACTORS_ABOVE_LINKS else "double"


def default_tolerance(n_links: int) -> float:
    """Each mode's damping ratio's relative error in the O(N) form of a machine of `n_links` links:
    DEFAULT_MACHINE_DAMPING_TOLERANCE, LONG_MACHINE_DAMPING_TOLERANCE above LONG_MACHINE_DAMPING_ABOVE_LINKS."""
    if n_links > LONG_MACHINE_DAMPING_ABOVE_LINKS:
        return LONG_MACHINE_DAMPING_TOLERANCE
    return DEFAULT_MACHINE_DAMPING_TOLERANCE


def of_machine(machine, tolerance: float | None = None, factor_precision: str | None = None) -> MachineDamping:
    """The O(N) form of `machine.damping_matrix()`'s chain-DOF block (modal or Rayleigh), each mode's
    ratio to `tolerance` (None: `default_tolerance`), its factors in `factor_precision` (None:
    `default_factor_precision`)."""
    tolerance = default_tolerance(machine.n_links) if tolerance is None else tolerance
    precision = default_factor_precision(machine.n_links) if factor_precision is None else factor_precision
    if precision not in FACTOR_PRECISIONS:
        raise DynamicsError(f"factor_precision: expected one of {sorted(FACTOR_PRECISIONS)}, got {factor_precision!r}")
    topo = machine.topology
    dofs = np.array([d for d, carried in enumerate(topo.links) if carried], dtype=np.int64)
    wheels = np.asarray(topo.wheel_dofs, dtype=np.int64)
    k_all = topo.stiffness_matrix_sparse()
    k = k_all[dofs][:, dofs].tocsr()
    masses = np.asarray(topo.masses_kg, dtype=float)
    m = masses[dofs]
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
    border = _border(k_all, masses, dofs, wheels)
    chain = machine.chain
    if chain.rayleigh_coefficients is not None:
        alpha, beta = chain.rayleigh_coefficients
        taus, weights, two_zeta = np.zeros(0), np.zeros(0), 0.0
    else:
        two_zeta = 2.0 * chain.damping_ratio
        if wheels.size:
            everything = np.concatenate([dofs, wheels])
            scale = sp.diags(1.0 / np.sqrt(masses[everything]))
            x_min, x_max = _bounds_of((scale @ k_all[everything][:, everything] @ scale).tocsc())
        else:
            x_min, x_max = eigenvalue_bounds(sd, soff, scorner)
        taus, weights, a, b = zolotarev_nodes_for(tolerance, x_min, x_max)
        alpha, beta = two_zeta * a, two_zeta * b  # the rule's tails: 2 zeta (a M + b K)
    taus = np.ascontiguousarray(taus, dtype=float)
    factors, sm = _factors(sd, soff, scorner, taus)
    factors, sm = _bordered(factors, sm, border, taus, soff)
    factors = np.ascontiguousarray(factors, dtype=FACTOR_PRECISIONS[precision])
    tri = np.ascontiguousarray(np.column_stack([rm, m, sd, soff, kd, koff]))
    scalars = np.array([scorner, kcorner, two_zeta, alpha, beta])
    return MachineDamping(
        np.concatenate([dofs, wheels]), tri, scalars, factors, sm, np.ascontiguousarray(weights, dtype=float), border
    )


def _border(k_all, masses, dofs, wheels) -> np.ndarray:
    """(nw, 8) per wheel DOF (the tooth model's): its first seated place, their count, sqrt(m_w), m_w,
    S_ww, K_ww, S and K to each seated place (the tooth springs: one value for the wheel's run of
    places, its seated links of one mass and one k_t). Refused where the wheels do not border the
    links so (coupled to each other, or to places not in one run of equal springs)."""
    border = np.zeros((wheels.size, 8))
    place = np.full(masses.size, -1, dtype=np.int64)
    place[dofs] = np.arange(dofs.size)
    for i, w in enumerate(wheels):
        column = k_all[:, [w]].tocoo()
        others = [(int(r), float(v)) for r, v in zip(column.row, column.data) if r != w and v != 0.0]
        places = np.array([place[r] for r, _ in others], dtype=np.int64)
        values = np.array([v for _, v in others])
        first = int(places.min()) if places.size else 0
        if (
            not places.size
            or np.any(places < 0)
            or not np.array_equal(np.sort(places), np.arange(first, first + places.size))
            or not np.all(values == values[0])
            or not np.all(masses[dofs[places]] == masses[dofs[first]])
        ):
            raise DynamicsError(
                "machine damping: a wheel's DOF does not border the chain's places as a run of equal tooth springs"
            )
        m_w, k_ww, k_lw = masses[w], float(k_all[w, w]), float(values[0])
        s_lw = k_lw / np.sqrt(m_w * masses[dofs[first]])
        border[i] = (first, places.size, np.sqrt(m_w), m_w, k_ww / m_w, k_ww, s_lw, k_lw)
    return border


def _bordered(factors, sm, border, taus, soff):
    """The factors and Sherman-Morrison data with the wheels' border (module docstring): Z_j = A_j^-1 B
    after the three factors, G_j^-1 after sm's two columns. No border: both as they are."""
    nw = border.shape[0]
    if nw == 0:
        return factors, sm
    n, p = factors.shape[1], factors.shape[2]
    z_cols = np.empty((nw, n, p))
    for w in range(nw):
        first, count = int(border[w, 0]), int(border[w, 1])
        rhs = np.zeros((n, p))
        rhs[first : first + count] = border[w, 6]
        z_cols[w] = _cyclic_solve(factors, sm, soff, rhs)
    g = np.zeros((p, nw, nw))
    for w in range(nw):
        g[:, w, w] = border[w, 4] + taus
        for v in range(nw):
            first, count = int(border[w, 0]), int(border[w, 1])
            g[:, w, v] -= border[w, 6] * z_cols[v, first : first + count].sum(axis=0)
    g_inv = np.linalg.inv(g).reshape(p, nw * nw)
    return np.concatenate([factors, z_cols]), np.ascontiguousarray(np.column_stack([sm, g_inv]))


def _cyclic_solve(factors, sm, soff, rhs):
    """(S_ll + tau_j I)^-1 rhs[:, j] for every node j from the factors (`_factors`): Thomas, then
    Sherman-Morrison for the corner."""
    inv, cp, z = factors[0], factors[1], factors[2]
    n = rhs.shape[0]
    y = np.empty_like(rhs)
    y[0] = rhs[0] * inv[0]
    for i in range(1, n):
        y[i] = (rhs[i] - soff[i - 1] * y[i - 1]) * inv[i]
    for i in range(n - 2, -1, -1):
        y[i] -= cp[i] * y[i + 1]
    return y - z * (sm[:, 0] * (y[0] + sm[:, 1] * y[-1]))[None, :]


def eigenvalue_bounds(sd, soff, scorner) -> tuple[float, float]:
    """(smallest eigenvalue, an upper bound of the largest) of S from its cyclic tridiagonal form, no
    N x N array for long chains. The top is Gershgorin's bound (the rule only needs the range covered:
    on a chain of equal links it is the top eigenvalue's limit 4 k / m, at most a few percent above it);
    the bottom is found by shift-invert Lanczos at 0 (S is positive definite: the drive grounds it)."""
    n = sd.size
    s = sp.diags([soff[:-1], sd, soff[:-1]], [-1, 0, 1], format="csc")
    if n > 2:
        s = (s + sp.csc_matrix(([scorner, scorner], ([0, n - 1], [n - 1, 0])), shape=(n, n))).tocsc()
    return _bounds_of(s)


def _bounds_of(s) -> tuple[float, float]:
    """(smallest eigenvalue, Gershgorin's bound of the largest) of the sparse symmetric positive
    definite S (`eigenvalue_bounds`); dense eigenvalues on small ones."""
    from scipy.sparse.linalg import eigsh

    n = s.shape[0]
    if n <= 64:
        lam = np.linalg.eigvalsh(s.toarray())
        return float(lam[0]), float(lam[-1])
    top = float(np.max(np.asarray(abs(s).sum(axis=1)).reshape(-1)))
    bottom = eigsh(s, k=1, sigma=0.0, which="LM", v0=lanczos_start(n), return_eigenvectors=False, tol=1e-10)[0]
    return float(bottom), top


def _factors(sd, soff, scorner, taus):
    """Factors of A_j = S + tau_j I = T_j + u_j v_j^T for every node (gamma_j = -A_j[0, 0],
    u = (gamma, 0.., corner), v = (1, 0.., corner / gamma)): (3, n, p) inverse pivots, forward
    coefficients and z = T^-1 u, place by place, and (p, 2) (1 / (1 + v.z), corner / gamma)."""
    n, p = sd.size, taus.size
    diag0 = sd[0] + taus
    gamma = -diag0
    inv, cp, z = np.empty((n, p)), np.empty((n, p)), np.empty((n, p))
    t = sd[0] + taus - gamma
    inv[0] = 1.0 / t
    cp[0] = soff[0] * inv[0]
    for i in range(1, n):
        t = sd[i] + taus
        if i == n - 1:
            t = t - scorner * scorner / gamma
        inv[i] = 1.0 / (t - soff[i - 1] * cp[i - 1])
        cp[i] = soff[i] * inv[i]
    # z = T^-1 u, u = (gamma, 0.., corner)
    z[0] = gamma * inv[0]
    for i in range(1, n):
        u_i = scorner if i == n - 1 else 0.0
        z[i] = (u_i - soff[i - 1] * z[i - 1]) * inv[i]
    for i in range(n - 2, -1, -1):
        z[i] -= cp[i] * z[i + 1]
    ratio = scorner / gamma
    sm = np.column_stack([1.0 / (1.0 + z[0] + ratio * z[-1]), ratio])
    return np.ascontiguousarray(np.stack([inv, cp, z])), np.ascontiguousarray(sm)


def _cyclic_times_into(diag, off, corner, x, y):
    """y = A x, A symmetric cyclic tridiagonal (diagonal, off[i] at (i, i+1), corner at (0, n-1)),
    on the first diag.shape[0] entries."""
    n = diag.shape[0]
    for i in range(n):
        y[i] = diag[i] * x[i]
    for i in range(n - 1):
        y[i] += off[i] * x[i + 1]
        y[i + 1] += off[i] * x[i]
    y[0] += corner * x[n - 1]
    y[n - 1] += corner * x[0]


def chain_damping_into(tri, scalars, factors, sm, weights, border, w, out, scratch):
    """out = C_chain w (module docstring) on the first n + nw entries of w and out (n = tri.shape[0]
    places, then nw = border.shape[0] wheels); scratch (6, >= max(n p, n + nw, (2 + nw) p)), rows 0-3
    used. Rayleigh part alpha M w + beta K w (Rayleigh damping, or the modal rule's tails), then
    2 zeta M^(1/2) S sum_j c_j (S + tau_j I)^-1 M^(1/2) w, the p solves' recurrences run over the
    places with the nodes as the inner vector, the wheels' border by its Schur complement."""
    n = tri.shape[0]
    p = weights.shape[0]
    nw = border.shape[0]
    if nw == 0 and p > 0 and n > 2:
        _unbordered_damping_into(tri, scalars, factors, sm, weights, w, out, scratch)
        return
    two_zeta, alpha, beta = scalars[2], scalars[3], scalars[4]
    ys, acc, prod, wg = scratch[0], scratch[1], scratch[2], scratch[3]
    _cyclic_times_into(tri[:, 4], tri[:, 5], scalars[1], w, prod)
    _border_times_into(border, 5, 7, n, w, prod)  # K's border
    for i in range(n):
        out[i] = alpha * tri[i, 1] * w[i] + beta * prod[i]
    for k in range(nw):
        out[n + k] = alpha * border[k, 3] * w[n + k] + beta * prod[n + k]
    if p == 0:
        return
    inv, cp, z = factors[0], factors[1], factors[2]
    # each place's nodes as a slice of ys (no index arithmetic in the inner loops: about 20 % faster
    # than indexing ys[i * p + j], measured at 1,000 and 10,000 links)
    b = tri[0, 0] * w[0]
    for j in range(p):
        ys[j] = b * inv[0, j]
    for i in range(1, n):
        b = tri[i, 0] * w[i]
        o = tri[i - 1, 3]
        row, before, pivots = ys[i * p : (i + 1) * p], ys[(i - 1) * p : i * p], inv[i]
        for j in range(p):
            row[j] = (b - o * before[j]) * pivots[j]
    last = (n - 1) * p
    s = 0.0
    for j in range(p):
        s += weights[j] * ys[last + j]
        # Sherman-Morrison's v.y = y[0] + (corner / gamma) y[n-1]: the y[n-1] part now (the back
        # substitution leaves it), the y[0] part after it
        wg[j] = weights[j] * sm[j, 0] * sm[j, 1] * ys[last + j]
    acc[n - 1] = s
    for i in range(n - 2, -1, -1):
        row, after, coefficients = ys[i * p : (i + 1) * p], ys[(i + 1) * p : (i + 2) * p], cp[i]
        s = 0.0
        for j in range(p):
            y = row[j] - coefficients[j] * after[j]
            row[j] = y
            s += weights[j] * y
        acc[i] = s
    for j in range(p):
        wg[j] += weights[j] * sm[j, 0] * ys[j]
    if nw > 0:
        _border_solve_into(tri, factors, sm, weights, border, w, ys, acc, wg)
    _minus_rows_times_into(z, wg[:p], acc)
    _cyclic_times_into(tri[:, 2], tri[:, 3], scalars[0], acc, prod)
    _border_times_into(border, 4, 6, n, acc, prod)  # S's border
    for i in range(n):
        out[i] += two_zeta * tri[i, 0] * prod[i]
    for k in range(nw):
        out[n + k] += two_zeta * border[k, 2] * prod[n + k]


def _unbordered_damping_into(tri, scalars, factors, sm, weights, w, out, scratch):
    """`chain_damping_into` without wheels' border (rigid seating), n > 2 places, p > 0 nodes: the
    same arithmetic in three passes over the places instead of eight, each place's row of `tri` and
    of one factor read once per pass (at 10,000 links none of them stays in the core's cache between
    passes). Forward: the Rayleigh part (K w from w's neighbours) and the forward recurrence into
    ys; back: the back substitution keeping only the row after the place (in `scratch[3]`, beyond
    the p Sherman-Morrison weights), its nodes' weighted sum into acc; last: acc's Sherman-Morrison
    correction, S times it from the corrected neighbours (the loop's corner first) and out's modal
    part."""
    n = tri.shape[0]
    p = weights.shape[0]
    kcorner, two_zeta, alpha, beta = scalars[1], scalars[2], scalars[3], scalars[4]
    ys, acc, wg = scratch[0], scratch[1], scratch[3]
    inv, cp, z = factors[0], factors[1], factors[2]
    after = wg[p : 2 * p]
    kw = (tri[0, 4] * w[0] + tri[0, 5] * w[1]) + kcorner * w[n - 1]
    out[0] = alpha * tri[0, 1] * w[0] + beta * kw
    b = tri[0, 0] * w[0]
    for j in range(p):
        ys[j] = b * inv[0, j]
    for i in range(1, n):
        ahead = tri[i, 5] * w[i + 1] if i < n - 1 else kcorner * w[0]
        out[i] = alpha * tri[i, 1] * w[i] + beta * ((tri[i, 4] * w[i] + tri[i - 1, 5] * w[i - 1]) + ahead)
        b = tri[i, 0] * w[i]
        o = tri[i - 1, 3]
        row, before, pivots = ys[i * p : (i + 1) * p], ys[(i - 1) * p : i * p], inv[i]
        for j in range(p):
            row[j] = (b - o * before[j]) * pivots[j]
    last = (n - 1) * p
    s = 0.0
    for j in range(p):
        y = ys[last + j]
        s += weights[j] * y
        after[j] = y
        wg[j] = weights[j] * sm[j, 0] * sm[j, 1] * y  # Sherman-Morrison's y[n-1] part (`chain_damping_into`)
    acc[n - 1] = s
    for i in range(n - 2, -1, -1):
        row, coefficients = ys[i * p : (i + 1) * p], cp[i]
        s = 0.0
        for j in range(p):
            y = row[j] - coefficients[j] * after[j]
            after[j] = y
            s += weights[j] * y
        acc[i] = s
    for j in range(p):
        wg[j] += weights[j] * sm[j, 0] * after[j]  # and its y[0] part
    first = acc[0] - _row_dot(z[0], wg, p)
    previous = acc[n - 1] - _row_dot(z[n - 1], wg, p)
    here = first
    for i in range(n):
        ahead = acc[i + 1] - _row_dot(z[i + 1], wg, p) if i < n - 1 else first
        # S's row i times the corrected acc: the loop's corner (0, n-1) in rows 0 and n-1
        behind = tri[i - 1, 3] * previous if i > 0 else tri[0, 3] * ahead
        beyond = tri[i, 3] * ahead if 0 < i < n - 1 else scalars[0] * (previous if i == 0 else first)
        out[i] += two_zeta * tri[i, 0] * ((tri[i, 2] * here + behind) + beyond)
        previous, here = here, ahead


def _row_dot(row, coefficients, p):
    """row . coefficients[:p] (`_minus_rows_times_into`'s sum for one place)."""
    s = 0.0
    for j in range(p):
        s += coefficients[j] * row[j]
    return s


def _border_solve_into(tri, factors, sm, weights, border, w, ys, acc, wg):
    """The wheels' part of the p bordered solves (module docstring), given ys = T_j^-1 r_l (the back
    substitution done), acc the nodes' weighted sum of it and wg[:p] the Sherman-Morrison weights
    c_j (v.y_j) / (1 + v.z_j): per node x_w = G_j^-1 (r_w - B^T A_j^-1 r_l); acc[n + k] = sum_j c_j
    x_w,j[k] and acc[i] -= sum_j c_j Z_j[i] x_w,j over the places (every wheel's column of Z)."""
    n, p, nw = tri.shape[0], weights.shape[0], border.shape[0]
    z = factors[2]
    # wg[p:2p] the Sherman-Morrison coefficient (v.y_j) / (1 + v.z_j) alone, wg[2p:] x_w per node
    last = (n - 1) * p
    for j in range(p):
        wg[p + j] = sm[j, 0] * (ys[j] + sm[j, 1] * ys[last + j])
    xw = wg[2 * p : (2 + nw) * p]
    for j in range(p):
        for k in range(nw):
            first, count = int(border[k, 0]), int(border[k, 1])
            s = 0.0
            for i in range(first, first + count):
                s += ys[i * p + j] - z[i, j] * wg[p + j]
            xw[k * p + j] = border[k, 2] * w[n + k] - border[k, 6] * s  # r_w - B^T A^-1 r_l
        for k in range(nw):  # G^-1 (nw x nw, row by row after sm's two columns) in place, via acc's tail
            s = 0.0
            for m in range(nw):
                s += sm[j, 2 + k * nw + m] * xw[m * p + j]
            acc[n + k] = s
        for k in range(nw):
            xw[k * p + j] = acc[n + k]
    for k in range(nw):
        coefficients = xw[k * p : (k + 1) * p]
        s = 0.0
        for j in range(p):
            coefficients[j] *= weights[j]  # c_j x_w,j[k], in place
            s += coefficients[j]
        acc[n + k] = s
        _minus_rows_times_into(factors[3 + k], coefficients, acc)


def _border_times_into(border, diagonal, coupling, n, x, y):
    """The wheels' rows and columns of a bordered matrix (K's or S's: `border`'s columns `diagonal`
    and `coupling`) times x, with y[:n] already the links' block times x[:n]: each wheel's coupling
    added to its run of seated places, and its own row y[n + k]."""
    for k in range(border.shape[0]):
        first, count, xw = int(border[k, 0]), int(border[k, 1]), x[n + k]
        s = 0.0
        for i in range(first, first + count):
            s += x[i]
            y[i] += border[k, coupling] * xw
        y[n + k] = border[k, diagonal] * xw + border[k, coupling] * s


def _minus_rows_times_into(rows, coefficients, acc):
    """acc[i] -= rows[i] . coefficients for every place i (a node-wise factor's rows, e.g. the
    Sherman-Morrison vector z or a wheel's column of Z, weighted by the nodes' coefficients)."""
    for i in range(rows.shape[0]):
        row = rows[i]
        s = 0.0
        for j in range(coefficients.shape[0]):
            s += coefficients[j] * row[j]
        acc[i] -= s


try:
    import numba
except ImportError:  # pragma: no cover
    numba = None

if numba is not None:
    # the nodes' sums are reassociated (SIMD over the nodes); the form's error is its tolerance, not round-off
    _cyclic_times_into = numba.njit(cache=True)(_cyclic_times_into)
    _border_times_into = numba.njit(cache=True, fastmath={"reassoc", "contract", "nsz"})(_border_times_into)
    _minus_rows_times_into = numba.njit(cache=True, fastmath={"reassoc", "contract", "nsz"})(_minus_rows_times_into)
    _row_dot = numba.njit(cache=True, fastmath={"reassoc", "contract", "nsz"}, inline="always")(_row_dot)
    _unbordered_damping_into = numba.njit(cache=True, fastmath={"reassoc", "contract", "nsz"})(_unbordered_damping_into)
    _border_solve_into = numba.njit(cache=True, fastmath={"reassoc", "contract", "nsz"})(_border_solve_into)
    chain_damping_into = numba.njit(cache=True, fastmath={"reassoc", "contract", "nsz"})(chain_damping_into)
