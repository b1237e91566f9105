"""The chain's topology: one description from which its linear matrices derive (issue #22).

A chain is a set of degrees of freedom (DOFs), each a path displacement in metres relative to the
cam (y = x - z 1, dynamics.models.chain): a free link, a wheel's group of seated links (they move together
with the wheel's pitch circle), or the idler carriage. Spans join the DOFs:

    stretch e = y[ahead] - y[behind] + carriage_gain * y[carriage]

(carriage_gain 2 where the idler carriage sits inside a span: moving it by u lengthens the loop by
2u; 1 for each of the two spans beside an idler wheel's seated group). Span force P + k e (tension
positive, preload P). Ground springs tie a DOF to the cam's frame: the drive (k_d on the driven
DOF) and the tensioner's spring (k_t on the carriage). So

    K = B^T diag(k) B + diag(ground) + couplings,    M = diag(masses),

with B the spans' incidence matrix (n_spans x n_dof) and the couplings springs between two DOFs (a
seated link held to its wheel's seat by the tooth flank, dynamics.models.machine's tooth model). `links` says which chain links each DOF
carries, so stations and relabelling know where every link is. Every linear matrix of the chain
(the dense K and M of dynamics.models.chain.ChainModel, the sparse K of dynamics.response.sweep, the tensioner's
full-contact K of dynamics.models.clearance, the machine on its wheels of dynamics.models.machine) is built from
this one object instead of each rebuilding the ring.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from dynamics.errors import DynamicsError


@dataclass(frozen=True)
class Span:
    """One span (a link's body between two pins): stretch y[ahead] - y[behind] + gain * y[carriage];
    an end of None is held to the cam (y = 0 there: a link seated on a sprocket that follows the cam)."""

    behind: int | None
    ahead: int | None
    carriage: int | None = None
    carriage_gain: float = 0.0


@dataclass(frozen=True)
class ChainTopology:
    """DOFs (masses and the links each carries), spans, ground springs; SI units."""

    masses_kg: tuple[float, ...]  # per DOF
    links: tuple[tuple[int, ...], ...]  # per DOF: the 0-based chain links it carries (() for a carriage)
    spans: tuple[Span, ...]
    span_stiffness_N_per_m: float
    preload_N: float
    ground: tuple[tuple[int, float], ...] = ()  # (DOF, stiffness N/m): springs to the cam's frame
    held_links: tuple[int, ...] = ()  # links that move with the cam (seated on a sprocket that follows it)
    # (DOF a, DOF b, stiffness N/m): springs between two DOFs, force k (y_a - y_b) on b, no preload
    # (a tooth flank holding a seated link, a, to its wheel's seat, b: dynamics.models.machine)
    couplings: tuple[tuple[int, int, float], ...] = ()
    wheel_dofs: tuple[int, ...] = ()  # DOFs of wheels that carry no link (they move with the cam)

    def __post_init__(self) -> None:
        n = len(self.masses_kg)
        if len(self.links) != n:
            raise DynamicsError(f"links: got {len(self.links)} entries; expected one per DOF ({n})")
        for s in self.spans:
            ends = tuple(d for d in (s.behind, s.ahead, s.carriage) if d is not None)
            if not all(0 <= d < n for d in ends):
                raise DynamicsError(f"spans: got {s!r}; expected DOF indices in 0..{n - 1}")
        for dof, stiffness in self.ground:
            if not (0 <= dof < n and np.isfinite(stiffness) and stiffness >= 0):
                raise DynamicsError(
                    f"ground: got ({dof!r}, {stiffness!r}); expected a DOF in 0..{n - 1} and a stiffness >= 0"
                )
        for a, b, stiffness in self.couplings:
            if not (0 <= a < n and 0 <= b < n and a != b and np.isfinite(stiffness) and stiffness > 0):
                raise DynamicsError(
                    f"couplings: got ({a!r}, {b!r}, {stiffness!r}); expected two DOFs in 0..{n - 1} and a stiffness > 0"
                )

    @property
    def n_dof(self) -> int:
        return len(self.masses_kg)

    @property
    def n_links(self) -> int:
        return sum(len(c) for c in self.links) + len(self.held_links)

    def incidence(self) -> sp.csr_matrix:
        """B (n_spans x n_dof): the spans' stretches are B y."""
        rows, cols, vals = [], [], []
        for r, s in enumerate(self.spans):
            for dof, value in ((s.ahead, 1.0), (s.behind, -1.0), (s.carriage, s.carriage_gain)):
                if dof is not None:
                    rows.append(r)
                    cols.append(dof)
                    vals.append(value)
        return sp.csr_matrix((vals, (rows, cols)), shape=(len(self.spans), self.n_dof))

    def span_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The spans as both compiled steps pack them: (ends, gains), ends (n_spans, 3) int64 the
        behind, ahead and carriage DOFs (-1: none, or held to the cam), gains (n_spans,) the carriage
        gains (dynamics.models.clearance_machine.ClearanceMachine.arrays, and the ring's scalars read
        from them by dynamics.solvers.clearance_verlet.ring_packing)."""
        ends = np.array(
            [[-1 if d is None else d for d in (s.behind, s.ahead, s.carriage)] for s in self.spans], dtype=np.int64
        ).reshape(-1, 3)
        gains = np.array([s.carriage_gain for s in self.spans], dtype=float)
        return ends, gains

    def ground_vector(self) -> np.ndarray:
        g = np.zeros(self.n_dof)
        for dof, stiffness in self.ground:
            g[dof] += stiffness
        return g

    def moves_with_cam(self) -> np.ndarray:
        """1 for every DOF that moves with the chain (carries links, or a wheel), 0 for a carriage."""
        wheels = set(self.wheel_dofs)
        return np.array([1.0 if (carried or d in wheels) else 0.0 for d, carried in enumerate(self.links)])

    def coupling_matrix_sparse(self) -> sp.csr_matrix:
        """The couplings' stiffness, sum k (e_a - e_b)(e_a - e_b)^T."""
        rows, cols, vals = [], [], []
        for a, b, k in self.couplings:
            rows += [a, b, a, b]
            cols += [a, b, b, a]
            vals += [k, k, -k, -k]
        return sp.csr_matrix((vals, (rows, cols)), shape=(self.n_dof, self.n_dof))

    def coupling_energy_J(self, y_m: np.ndarray) -> float:
        return float(sum(0.5 * k * (y_m[a] - y_m[b]) ** 2 for a, b, k in self.couplings))

    def rayleigh_quotient(self, y: np.ndarray) -> float:
        """y^T K y / y^T M y with y^T K y summed term by term (k times each span's stretch squared, the
        ground springs', the couplings'): every term >= 0, so no cancellation between K's diagonal and
        off-diagonal entries. For a low mode's smooth y, y^T (K y) loses about eps x lambda_max / lambda
        of itself to that cancellation (1e-14 at 10,000 links); this form only the stretches' rounding,
        about eps relative to each (1e-16 of the quotient, measured to 10,000 links)."""
        y = np.asarray(y, dtype=float)
        e = self.incidence() @ y
        elastic = self.span_stiffness_N_per_m * float(e @ e) + float(self.ground_vector() @ (y * y))
        elastic += float(sum(k * (y[a] - y[b]) ** 2 for a, b, k in self.couplings))
        return elastic / float(np.asarray(self.masses_kg, dtype=float) @ (y * y))

    def stiffness_matrix_sparse(self) -> sp.csr_matrix:
        """K = k B^T B + diag(ground) + the couplings, sparse."""
        b = self.incidence()
        k = self.span_stiffness_N_per_m * (b.T @ b) + sp.diags(self.ground_vector())
        return (k + self.coupling_matrix_sparse() if self.couplings else k).tocsr()

    def stiffness_matrix(self) -> np.ndarray:
        return self.stiffness_matrix_sparse().toarray()

    def mass_matrix(self) -> np.ndarray:
        return np.diag(np.asarray(self.masses_kg, dtype=float))

    def stretches_m(self, y_m: np.ndarray) -> np.ndarray:
        """Span stretches (..., n_spans) from DOF displacements (..., n_dof)."""
        return np.asarray(y_m, dtype=float) @ self.incidence().T.toarray()

    def link_dof(self) -> np.ndarray:
        """For every chain link (0-based), the DOF that carries it (-1: held to the cam)."""
        out = np.full(self.n_links, -1, dtype=int)
        for dof, carried in enumerate(self.links):
            out[list(carried)] = dof
        return out


def ring_topology(
    n_links: int,
    link_mass_kg: float,
    stiffness_N_per_m: float,
    preload_N: float,
    drive_stiffness_N_per_m: float,
    carriage: tuple[int, float, float] | None = None,
) -> ChainTopology:
    """Today's chain: N free links in a loop, span j from link j to link j + 1 (the last closes the
    loop), the drive spring on link 0. `carriage` = (span, rate N/m, mass kg) adds the idler carriage
    as DOF N inside that span (gain 2), tied to the frame by its spring."""
    spans = [Span(j, (j + 1) % n_links) for j in range(n_links)]
    masses = [float(link_mass_kg)] * n_links
    links = [(j,) for j in range(n_links)]
    ground = [(0, float(drive_stiffness_N_per_m))]
    if carriage is not None:
        span, rate, mass = carriage
        spans[span] = Span(span, (span + 1) % n_links, n_links, 2.0)
        masses.append(float(mass))
        links.append(())
        ground.append((n_links, float(rate)))
    return ChainTopology(
        tuple(masses), tuple(links), tuple(spans), float(stiffness_N_per_m), float(preload_N), tuple(ground)
    )
