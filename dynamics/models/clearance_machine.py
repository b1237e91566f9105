"""The clearance chain on its wheels (issue #22): the machine of dynamics.models.machine (seated groups,
drive compliance, wheel inertias, idler wheel, carriage, polygonal feed) with the span law of
dynamics.models.clearance (pin free play, loss of contact, impacts) in every span between places.

Everything derives from the machine's topology (dynamics.models.topology): a span's stretch is

    e_j = y[ahead] - y[behind] + gain y[carriage] + s_j d_w(a_w)

(a held end has y = 0; s_j = +1 for the span running onto wheel w, -1 for the span it feeds, 0
elsewhere; d_w the wheel's polygonal feed departure at its angle a_w = (z - z_dwell + u_w) / R_m since
the dwell, 0 without the polygonal action). Span force T_j = the clearance law of P + k e_j; the forces
go back through the transposed incidence, -T_j de_j/dq (the wheel's share through
dd/du = R cos(gamma) / R_m - 1), plus the preload's static balance P B^T 1 (2P on the carriage of
today's idler point, 0 elsewhere), so the static state q = 0 is at rest.

Damping laws as the clearance chain's: "global" is the machine's own damping matrix
(MachineOnWheels.damping_matrix: modal zeta or Rayleigh on the chain's DOFs, the carriage's c_t)
on q'; "kelvin-voigt" a dashpot beta k per span in contact plus beta k_ground on the drive, c_t on
the carriage. Friction (regularised Coulomb, dynamics.models.friction) acts on the free links of the
strands only: the seated links ride on their wheel, not on the guide.

With clearance 0 and friction 0 the model is MachineOnWheels exactly (tested against
dynamics.solvers.machine_steady and machine_ivp).

Seating through a tooth contact stiffness (MachineOnWheels.tooth_stiffness_N_per_m finite): the tooth
springs k_t (y - u - s) from each seated link to its wheel's seat (held to the cam's frame on a held
sprocket), s the link's seat offset, a state entry after the DOFs (`n_state`, `seats`) without mass
or force, carried and closed by the seat change (dynamics.solvers.tooth_transfer); tested against the
DOP853 reference and for its energy (tests/test_tooth_seating.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.models.clearance import (
    DEFAULT_PIN_CLEARANCE_M,
    SPAN_DAMPING_LAWS,
    damping_ratio_at,
    kelvin_voigt_beta_s,
    span_energy_J,
    span_force_N,
)
from dynamics.models.lanczos import lanczos_start
from dynamics.models.machine import MachineOnWheels
from dynamics.models.machine_damping import of_machine
from dynamics.models.reduction import DENSE_LINK_LIMIT
from dynamics.solvers import cache
from dynamics.solvers._common import serial_blas
from dynamics.solvers.clearance_verlet import _padded


@dataclass(frozen=True)
class MachineArrays:
    """The topology and parameters as the compiled step takes them (dynamics.solvers.machine_verlet)."""

    span_int: np.ndarray  # (n_spans, 4) int64: behind, ahead, carriage, wheel (-1: none / held)
    span_float: np.ndarray  # (n_spans, 2): carriage gain, polygon sign
    # (n_state, 10): 1/mass, inertial load / mass, ground k, ground c, friction links, f0, mass, and the tooth
    # spring of a seated link (tooth model): its wheel's DOF (-1: held to the cam), k_t (0: none), the state
    # index of its seat offset. The seat offsets are state entries after the DOFs (`n_state`), frozen
    # (no mass, no force: constant between seat changes)
    dof_float: np.ndarray
    wheel_float: np.ndarray  # (n_wheels, 4): R, R_m, gamma at the dwell, DOF (-1 held) as float
    par: np.ndarray  # k, P, k g, beta k, kv flag, F_c, 1 / v_s, m (one link), tooth springs flag
    # the global law's C, padded for the four-row product (clearance_verlet._padded); zeros for Kelvin-Voigt
    cmat: np.ndarray
    # the O(N) global law above DENSE_LINK_LIMIT links: (chain DOFs, tri, scalars, factors, sm,
    # weights, scratch (6, >= n + nw), border) of dynamics.models.machine_damping; empty DOFs: the dense cmat
    reduced: tuple


@dataclass(frozen=True)
class ClearanceMachine:
    """MachineOnWheels (its chain's friction and the tensioner included) with pin free play `clearance_m`."""

    machine: MachineOnWheels
    clearance_m: float = DEFAULT_PIN_CLEARANCE_M
    span_damping: str = "global"
    kv_beta_s: float | None = None
    friction_chain: object = None  # the chain with its friction (`of`); None: the machine's own (friction 0)

    def __post_init__(self) -> None:
        if not (self.clearance_m >= 0 and not np.isnan(self.clearance_m)):
            raise DynamicsError(f"clearance_m: expected a free play >= 0 m (inf allowed), got {self.clearance_m!r}")
        if self.span_damping not in SPAN_DAMPING_LAWS:
            raise DynamicsError(
                f"span_damping: expected one of {', '.join(SPAN_DAMPING_LAWS)}, got {self.span_damping!r}"
            )

    @classmethod
    def of(cls, chain, layout, tensioner, clearance_m, span_damping="global", kv_beta_s=None) -> ClearanceMachine:
        """The clearance machine of one material's chain (a ChainModel, friction allowed) on a layout
        (dynamics.models.layout.MachineLayout). The machine's matrices do not depend on friction, so it
        is built on the friction-free chain and the friction kept here."""
        frictionless = replace(chain, friction_coefficient=0.0)
        return cls(layout.machine(frictionless, tensioner), clearance_m, span_damping, kv_beta_s, chain)

    @property
    def chain(self):
        return self.friction_chain if self.friction_chain is not None else self.machine.chain

    @property
    def tensioner(self):
        return self.machine.tensioner

    @property
    def topology(self):
        return self.machine.topology

    @property
    def n_links(self) -> int:
        return self.machine.n_links

    @cached_property
    def seats(self) -> tuple[tuple[int | None, tuple[int, ...]], ...]:
        """Tooth model: per wheel (in `wheel_ends` order) its DOF (None: held to the cam) and its seated
        links in place order; () with rigid seating."""
        mach = self.machine
        if mach.rigid_seating:
            return ()
        return tuple((ends.dof, seated) for ends, (_, seated) in zip(mach.wheel_ends, mach.seated_blocks()))

    @property
    def n_state(self) -> int:
        """Entries of the compiled step's state q: the DOFs, then (tooth model) one seat offset per
        seated link, in `seats` order: where the link seated relative to its wheel's seat, which its
        tooth spring pulls it to (k_t (y - u - offset)); carried through the relabelling
        (dynamics.solvers.tooth_transfer)."""
        return self.topology.n_dof + sum(len(seated) for _, seated in self.seats)

    @property
    def beta_s(self) -> float:
        """The Kelvin-Voigt dashpot factor, the ring's (dynamics.models.clearance.kelvin_voigt_beta_s)."""
        return kelvin_voigt_beta_s(self.chain, self.kv_beta_s)

    @property
    def reduced_damping(self) -> bool:
        """The global law in the O(N) form (dynamics.models.machine_damping, each mode's ratio to
        1e-5) above DENSE_LINK_LIMIT links; the dense C up to it (today's numbers unchanged)."""
        return self.machine.n_links > DENSE_LINK_LIMIT

    @property
    def damping_matrix(self) -> np.ndarray:
        """The machine's C (computed once per machine: the solvers' cache, read-only)."""
        return cache.cached(("machine-damping", self.machine), lambda: _damping_matrix(self.machine))

    @property
    def max_frequency_rad_s(self) -> float:
        """Highest full-contact frequency; with the polygonal action the wheel ends' stiffness is
        scaled by (R / R_m)^2 at most (dd/du <= R / R_m - 1), so the frequency is bounded by R / R_m times."""
        top = _top_frequency_sparse if self.reduced_damping else _top_frequency
        omega = cache.cached(("machine-top-frequency", self.machine), lambda: top(self.machine))
        if self.machine.polygonal:  # the single-link drive has no wheel: no polygonal action
            omega *= max((e.wheel.pitch_radius_m / e.wheel.feed_radius_m for e in self.machine.wheel_ends), default=1.0)
        return omega

    def damping_ratio_at(self, omega_rad_s: float) -> float:
        return damping_ratio_at(self.chain, self.span_damping, self.beta_s, omega_rad_s)

    @cached_property
    def _incidence(self):
        # sparse on long chains (memory linear in N); dense below, as the results were computed
        b = self.topology.incidence()
        return b if self.reduced_damping else b.toarray()

    @cached_property
    def arrays(self) -> MachineArrays:
        topo, mach, c = self.topology, self.machine, self.chain
        kv = self.span_damping == "kelvin-voigt"
        n_spans = len(topo.spans)
        span_int = np.full((n_spans, 4), -1, dtype=np.int64)
        span_float = np.zeros((n_spans, 2))
        span_int[:, :3], span_float[:, 0] = topo.span_arrays()
        wheels = mach.wheel_ends if mach.polygonal else ()
        wheel_float = np.zeros((len(wheels), 4))
        for i, ends in enumerate(wheels):
            w = ends.wheel
            wheel_float[i] = (
                w.pitch_radius_m,
                w.feed_radius_m,
                w.gamma_at_dwell_rad(),
                -1 if ends.dof is None else ends.dof,
            )
            for span, sign in ((ends.behind_span, 1.0), (ends.ahead_span, -1.0)):
                span_int[span, 3] = i
                span_float[span, 1] = sign
        masses = np.asarray(topo.masses_kg, dtype=float)
        moves = topo.moves_with_cam()  # the links' DOFs, and a tooth model's wheels
        ground = topo.ground_vector()
        tooth = self._tooth_columns()
        ground[tooth[:, 1] > 0] = 0.0  # a held seat's tooth spring is in the tooth columns (with its offset)
        ground_c = np.zeros(topo.n_dof)
        if mach.tensioner is not None:
            # the dense global law's C holds c_t; the O(N) form leaves it to the carriage's own dashpot
            own = kv or self.reduced_damping
            ground_c[-1] = mach.tensioner.damping_N_s_per_m if own else 0.0
            drive = [d for d, _ in topo.ground if d != topo.n_dof - 1]
        else:
            drive = [d for d, _ in topo.ground]
        if kv:
            for d in drive:
                ground_c[d] += self.beta_s * ground[d]
        wheel_dofs = {ends.dof for ends in mach.wheel_ends}
        friction_links = np.array(
            [1.0 if (carried and d not in wheel_dofs) else 0.0 for d, carried in enumerate(topo.links)]
        )
        friction_links[tooth[:, 1] > 0] = 0.0  # a tooth model's seated links ride on their wheel
        b = self._incidence
        f0 = topo.preload_N * np.asarray(b.sum(axis=0)).reshape(-1)
        dof_float = np.column_stack([1.0 / masses, moves, ground, ground_c, friction_links, f0, masses, tooth])
        frozen = np.zeros((self.n_state - topo.n_dof, dof_float.shape[1]))  # the seat offsets
        frozen[:, 7] = -1.0
        dof_float = np.vstack([dof_float, frozen])
        k = topo.span_stiffness_N_per_m
        par = np.array(
            [
                k,
                topo.preload_N,
                k * self.clearance_m,
                self.beta_s * k if kv else 0.0,
                1.0 if kv else 0.0,
                c.coulomb_force_N,
                1.0 / c.friction_velocity_scale_m_s,
                c.link_mass_kg,
                1.0 if self.seats else 0.0,
            ]
        )
        dense = not (kv or self.reduced_damping)
        cmat = _padded(_with_offsets(self.damping_matrix, self.n_state) if dense else np.zeros((1, 1)))
        reduced = _reduced_arrays(self.machine) if (self.reduced_damping and not kv) else _NO_REDUCED
        return MachineArrays(span_int, span_float, np.ascontiguousarray(dof_float), wheel_float, par, cmat, reduced)

    def _tooth_columns(self) -> np.ndarray:
        """(n_dof, 3): per DOF its tooth spring (the `arrays` dof_float columns 7-9): its wheel's DOF
        (-1: held to the cam, or none), k_t (0: none), the state index of its seat offset."""
        out = np.zeros((self.topology.n_dof, 3))
        out[:, 0] = -1.0
        offset = self.topology.n_dof
        for dof, seated in self.seats:
            for link in seated:  # the tooth topology's DOF j is link j
                out[link] = (-1.0 if dof is None else dof, self.machine.tooth_stiffness_N_per_m, offset)
                offset += 1
        return out

    def seat_offsets_m(self, q: np.ndarray) -> np.ndarray:
        """The seat offsets of states q (..., n_state): (..., n_state - n_dof), empty with rigid seating."""
        return np.asarray(q, dtype=float)[..., self.topology.n_dof :]

    def tooth_energy_J(self, q: np.ndarray) -> float:
        """The tooth springs' elastic energy 1/2 k_t (y - u - offset)^2 of one state (0: rigid seating)."""
        q = np.asarray(q, dtype=float)
        cols = self._tooth_columns()
        energy = 0.0
        for i in np.flatnonzero(cols[:, 1] > 0):
            wheel, k_t, offset = int(cols[i, 0]), cols[i, 1], int(cols[i, 2])
            gap = q[i] - (q[wheel] if wheel >= 0 else 0.0) - q[offset]
            energy += 0.5 * k_t * gap * gap
        return float(energy)

    # --- the span law on the machine -------------------------------------------------------------

    def stretches_m(self, q: np.ndarray, z_rel_m) -> np.ndarray:
        """Span stretches (..., n_spans) of DOF states (..., n_dof) at the cam's lift since the dwell."""
        q = np.atleast_2d(np.asarray(q, dtype=float))[:, : self.topology.n_dof]
        z_rel = np.broadcast_to(np.asarray(z_rel_m, dtype=float), q.shape[:1])
        b = self._incidence
        e = np.asarray((b @ q.T).T) if self.reduced_damping else q @ b.T
        arr = self.arrays
        for i, (r, rm, g0, dof) in enumerate(arr.wheel_float):
            u = q[:, int(dof)] if dof >= 0 else 0.0
            a = (z_rel + u) / rm
            d = r * (np.sin(g0 + a) - np.sin(g0)) - rm * a
            for j in np.flatnonzero(arr.span_int[:, 3] == i):
                e[:, j] += arr.span_float[j, 1] * d
        return e

    def tension_N(self, q: np.ndarray, z_rel_m) -> np.ndarray:
        c = self.chain
        return span_force_N(self.stretches_m(q, z_rel_m), c.preload_N, c.stiffness_N_per_m, self.clearance_m)

    def stored_energy_J(self, q, v, zdot_m_s: float, z_rel_m: float) -> float:
        """Kinetic + elastic energy (absolute frame) of one state: 1/2 sum M (q' + z')^2 (the carriage
        without z'), the spans' law energy (dynamics.models.clearance.span_energy_J, from the unstressed
        length), the ground springs, the tooth springs, and -2 P u of the carriage's preload balance
        (-f0 . q). The seat offsets (tooth model) carry no mass and no force of their own."""
        arr = self.arrays
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        masses, moves, ground, f0 = arr.dof_float[:, 6], arr.dof_float[:, 1], arr.dof_float[:, 2], arr.dof_float[:, 5]
        c = self.chain
        e = self.stretches_m(q, z_rel_m)[0]
        kinetic = 0.5 * float(np.sum(masses * (v + moves * zdot_m_s) ** 2))
        elastic = float(np.sum(span_energy_J(e, c.preload_N, c.stiffness_N_per_m, self.clearance_m)))
        energy = kinetic + elastic + 0.5 * float(np.sum(ground * q**2)) - float(f0 @ q)
        return energy + self.tooth_energy_J(q) if self.seats else energy


_NO_REDUCED = (
    np.zeros(0, dtype=np.int64),
    np.zeros((0, 6)),
    np.zeros(5),
    np.zeros((3, 0, 0)),
    np.zeros((0, 2)),
    np.zeros(0),
    np.zeros((6, 0)),
    np.zeros((0, 8)),
)


def _reduced_arrays(machine: MachineOnWheels) -> tuple:
    r = of_machine(machine)
    return (r.dofs, r.tri, r.scalars, r.factors, r.sm, r.weights, r.scratch(), r.border)


def _top_frequency_sparse(machine: MachineOnWheels) -> float:
    """As _top_frequency from the sparse K (no N x N array on long chains), by shift-invert Lanczos
    just above Gershgorin's bound of the spectrum: the top eigenvalues of a long chain crowd together,
    so plain Lanczos needs thousands of products there (45 s at 10,000 links), the shifted one a few."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigsh

    topo = machine.topology
    r = sp.diags(1.0 / np.sqrt(np.asarray(topo.masses_kg, dtype=float)))
    s = (r @ topo.stiffness_matrix_sparse() @ r).tocsc()
    bound = float(np.max(np.asarray(abs(s).sum(axis=1)).reshape(-1)))
    lam = eigsh(
        s, k=1, sigma=1.001 * bound, which="LM", v0=lanczos_start(s.shape[0]), return_eigenvectors=False, tol=1e-10
    )[0]
    return float(np.sqrt(max(lam, 0.0)))


def _with_offsets(c: np.ndarray, n_state: int) -> np.ndarray:
    """C on the compiled step's state: zero rows and columns for the seat offsets (none: C itself)."""
    n = c.shape[0]
    if n == n_state:
        return c
    out = np.zeros((n_state, n_state))
    out[:n, :n] = c
    return out


def _damping_matrix(machine: MachineOnWheels) -> np.ndarray:
    with serial_blas():
        c = np.ascontiguousarray(machine.damping_matrix())
    c.flags.writeable = False
    return c


def _top_frequency(machine: MachineOnWheels) -> float:
    k, m = machine.stiffness_matrix(), np.diag(machine.mass_matrix())
    with serial_blas():
        lam = np.linalg.eigvalsh(k / np.sqrt(np.outer(m, m)))
    return float(np.sqrt(max(lam[-1], 0.0)))
