"""The chain as it really is: pin joints with free play, loss of contact and impacts (issue #11).

Coordinates and topology are dynamics.models.chain's: links 0..N-1, y = x - z(t) 1 relative to the cam,
span j joins link j to link j+1 (span N-1 closes the loop to link 0), stretch e_j = y_j+1 - y_j.
Each span has an axial free play g >= 0 (metres, the total of its two pin joints). In the static
state every span rests on the tension side of its play and carries the preload P. Span force
(tension positive), link stiffness k:

    T = P + k e             e >= -P/k              pulling contact
    T = 0                   -P/k - g < e < -P/k    free play
    T = k (e + P/k + g)     e <= -P/k - g          pushing contact

g = 0 is the linear chain exactly; g = inf is a chain that can only pull. Equivalently
T = P + k e + clip(-(P + k e), 0, k g): the linear force plus a bounded correction.

Damping laws (`span_damping`):
- "global": the chain model's damping matrix C (modal zeta or Rayleigh) on y', acting always,
  as in the linear model: it stands for losses spread over the chain and its guide (rollers,
  lubricant, nests), which do not stop when a pin joint opens. In full contact this is today's model.
  Dense up to DENSE_LINK_LIMIT links; above, the same modal ratios (to `damping_tolerance`, 1e-4 by
  default) in the O(N) form of dynamics.models.reduced_damping (`damping_operator`).
- "kelvin-voigt": a dashpot beta k in each span, acting only while that span is in contact (the
  losses are in the loaded pin joints and link bodies); the drive spring gets beta k_d always. In
  full contact it equals Rayleigh (alpha, beta) = (0, beta). beta is `kv_beta_s`; by default it
  gives one span's contact oscillation (two links, omega_c = sqrt(2 k / m)) the chain's damping
  ratio zeta: beta = 2 zeta / omega_c.

Tensioner (optional): the idler carriage at span s = round(N/2) - 1 (0-based; links round(N/2) and
round(N/2) + 1 in 1-based numbering), displacement u (positive lengthens the loop): that span's
stretch is e_s + 2u and m_t u'' = 2P - k_t u - c_t u' - 2 T_s, so u = 0 in the static state.
Without it the idler is rigid (u = 0 always).

Energy (absolute frame): kinetic 1/2 m sum (z' + y')^2 + 1/2 m_t u'^2; span springs from their
unstressed length (the integral of T de, piecewise quadratic, continuous); drive 1/2 k_d y_0^2;
tensioner 1/2 k_t u^2 - 2P u.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.lanczos import lanczos_start
from dynamics.models.reduction import DENSE_LINK_LIMIT
from dynamics.models.system import SecondOrderSystem
from dynamics.models.tensioner import Tensioner
from dynamics.models.topology import ChainTopology, ring_topology
from dynamics.options import DEFAULT_PIN_CLEARANCE_M, SPAN_DAMPING_LAWS
from dynamics.response.metrics import matlab_round
from dynamics.solvers._common import serial_blas


@dataclass(frozen=True)
class ClearanceChain:
    """A ChainModel whose spans have free play `clearance_m` (0 to inf)."""

    chain: ChainModel
    clearance_m: float = DEFAULT_PIN_CLEARANCE_M
    span_damping: str = "global"
    kv_beta_s: float | None = None  # Kelvin-Voigt beta (s); None: 2 zeta / omega_c
    tensioner: Tensioner | None = None
    # the global law's O(N) form (dynamics.models.reduced_damping) with each mode's damping ratio to this
    # relative tolerance; None: the dense C up to DENSE_LINK_LIMIT links, the O(N) form at
    # DEFAULT_DAMPING_TOLERANCE above
    damping_tolerance: float | None = None

    def __post_init__(self) -> None:
        if not (self.clearance_m >= 0 and not np.isnan(self.clearance_m)):
            raise DynamicsError(f"clearance_m: expected a free play >= 0 m (inf allowed), got {self.clearance_m!r}")
        if self.span_damping not in SPAN_DAMPING_LAWS:
            raise DynamicsError(
                f"span_damping: expected one of {', '.join(SPAN_DAMPING_LAWS)}, got {self.span_damping!r}"
            )
        if self.kv_beta_s is not None and not (np.isfinite(self.kv_beta_s) and self.kv_beta_s >= 0):
            raise DynamicsError(f"kv_beta_s: expected a finite value >= 0, got {self.kv_beta_s!r}")
        if self.damping_tolerance is not None and not (0 < self.damping_tolerance < 1):
            raise DynamicsError(f"damping_tolerance: expected a fraction in (0, 1), got {self.damping_tolerance!r}")

    @property
    def n_links(self) -> int:
        return self.chain.n_links

    @property
    def idler_span(self) -> int:
        """0-based index of the span carrying the idler wheel."""
        return int(matlab_round(self.n_links / 2)) - 1

    @property
    def contact_frequency_rad_s(self) -> float:
        """One span closing on two free links: omega_c = sqrt(2 k / m)."""
        return contact_frequency_rad_s(self.chain)

    @property
    def beta_s(self) -> float:
        """The Kelvin-Voigt dashpot factor (s): dashpot beta k per span."""
        return kelvin_voigt_beta_s(self.chain, self.kv_beta_s)

    @property
    def topology(self) -> ChainTopology:
        """The ring's topology (dynamics.models.topology.ring_topology): N links, the drive spring on
        link 0, the carriage as one more DOF inside the idler span when a tensioner is modelled. The
        single-link drive of the machine (dynamics.models.machine, drive="link") is the same."""
        c, t = self.chain, self.tensioner
        carriage = None if t is None else (self.idler_span, t.rate_N_per_m, t.mass_kg)
        return ring_topology(
            c.n_links, c.link_mass_kg, c.stiffness_N_per_m, c.preload_N, c.drive_stiffness, carriage=carriage
        )

    @property
    def damping_matrix(self) -> np.ndarray:
        """The global law's C (N x N; cached per chain, read-only); unused by the Kelvin-Voigt law."""
        return _damping_matrix(self.chain)

    @property
    def damping_is_reduced(self) -> bool:
        """Whether the global law is applied in the reduced form (dynamics.models.reduced_damping)."""
        return self.damping_tolerance is not None or self.n_links > DENSE_LINK_LIMIT

    @property
    def damping_operator(self):
        """What the integrator multiplies w by: the dense C, or the ReducedDamping (`damping_is_reduced`)."""
        if not self.damping_is_reduced:
            return self.damping_matrix
        from dynamics.models.reduced_damping import DEFAULT_DAMPING_TOLERANCE, reduced_damping

        return reduced_damping(self.chain, self.damping_tolerance or DEFAULT_DAMPING_TOLERANCE)

    def full_contact_stiffness(self) -> tuple[np.ndarray, np.ndarray]:
        """(K, M) of the linearised chain with every span in contact, carriage included when present
        (the topology's: each entry a small integer times k, plus the ground springs, so exactly the
        former builder's, tests/test_chain_topology.py)."""
        topo = self.topology
        return topo.stiffness_matrix(), topo.mass_matrix()

    def max_frequency_rad_s(self) -> float:
        """Largest natural frequency with every span in contact (free play only softens the chain)."""
        return _max_frequency_rad_s(self.chain, self.tensioner)

    def _max_frequency_uncached(self) -> float:
        if self.n_links > DENSE_LINK_LIMIT:
            return _sparse_top_frequency(self)
        kk, mm = self.full_contact_stiffness()
        lam = np.linalg.eigvalsh(kk / np.sqrt(np.outer(np.diag(mm), np.diag(mm))))
        return float(np.sqrt(max(lam[-1], 0.0)))

    def damping_ratio_at(self, omega_rad_s: float) -> float:
        """Damping ratio the law gives a mode at omega (used to set the explicit step)."""
        return damping_ratio_at(self.chain, self.span_damping, self.beta_s, omega_rad_s)

    def system(self) -> SecondOrderSystem:
        """The clearance chain in the solvers' common form (dynamics.solvers.solve): the linear
        chain's M, C, K plus the span law's departure from it as the nonlinear force g(y), so every
        method that takes a nonlinear force (central-difference, rk45, radau, ...) can solve it. Only
        the global damping law without a tensioner maps onto that form (the Kelvin-Voigt dashpot
        switches with contact, the carriage is one more degree of freedom)."""
        if self.span_damping != "global" or self.tensioner is not None:
            raise DynamicsError(
                "system(): only the global damping law without a tensioner has the "
                "M, C, K + g(x) form; use dynamics.solvers.clearance_verlet"
            )
        c = self.chain
        return SecondOrderSystem(
            c.mass_matrix(),
            self.damping_matrix,
            c.stiffness_matrix(),
            nonlinear_force=SpanLawCorrection(c.preload_N, c.stiffness_N_per_m, self.clearance_m),
        )

    # --- the span law and its energy -------------------------------------------------------------

    def span_force_N(self, e_m: np.ndarray) -> np.ndarray:
        return span_force_N(e_m, self.chain.preload_N, self.chain.stiffness_N_per_m, self.clearance_m)

    def span_energy_J(self, e_m: np.ndarray) -> np.ndarray:
        return span_energy_J(e_m, self.chain.preload_N, self.chain.stiffness_N_per_m, self.clearance_m)

    def stretches_m(self, y_m: np.ndarray, u_m=None) -> np.ndarray:
        """Span stretches from relative (or absolute) link displacements (..., N), carriage u (...)."""
        y = np.asarray(y_m, dtype=float)
        e = np.roll(y, -1, axis=-1) - y
        if self.tensioner is not None and u_m is not None:
            e[..., self.idler_span] += 2.0 * np.asarray(u_m, dtype=float)
        return e

    def tension_N(self, y_m: np.ndarray, u_m=None) -> np.ndarray:
        """Elastic span forces (..., N), tension positive (the dashpot of the Kelvin-Voigt law not
        included, as the linear model's tension leaves out its damping)."""
        return self.span_force_N(self.stretches_m(y_m, u_m))

    def stored_energy_J(self, y, w, zdot, u=0.0, ud=0.0) -> float:
        """Kinetic + elastic energy of one state (absolute frame)."""
        c = self.chain
        y, w = np.asarray(y, dtype=float), np.asarray(w, dtype=float)
        kinetic = 0.5 * c.link_mass_kg * float(np.sum((zdot + w) ** 2))
        elastic = float(np.sum(self.span_energy_J(self.stretches_m(y, u))))
        drive = 0.5 * c.drive_stiffness * float(y[0]) ** 2
        if self.tensioner is None:
            return kinetic + elastic + drive
        t = self.tensioner
        carriage = 0.5 * t.mass_kg * ud**2 + 0.5 * t.rate_N_per_m * u**2 - 2.0 * c.preload_N * u
        return kinetic + elastic + drive + carriage


def _sparse_top_frequency(model: ClearanceChain) -> float:
    """`max_frequency_rad_s` from the topology's sparse K (long chains: no N x N array), carriage
    included, from ARPACK's fixed start (`lanczos_start`): the same in every call and process."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigsh

    topo = model.topology
    scale = sp.diags(1.0 / np.sqrt(np.asarray(topo.masses_kg, dtype=float)))
    kk = topo.stiffness_matrix_sparse()
    lam = eigsh(
        (scale @ kk @ scale).tocsc(),
        k=1,
        which="LA",
        v0=lanczos_start(kk.shape[0]),
        return_eigenvectors=False,
        tol=1e-12,
    )
    return float(np.sqrt(max(lam[0], 0.0)))


def contact_frequency_rad_s(chain: ChainModel) -> float:
    """One span closing on two free links: omega_c = sqrt(2 k / m)."""
    return float(np.sqrt(2.0 * chain.stiffness_N_per_m / chain.link_mass_kg))


def kelvin_voigt_beta_s(chain: ChainModel, kv_beta_s: float | None) -> float:
    """The Kelvin-Voigt dashpot factor beta (s) of a chain (the ring's and the machine's): the one
    given; else the Rayleigh beta; else the one that gives one span's contact oscillation (two links,
    `contact_frequency_rad_s`) the chain's damping ratio, 2 zeta / omega_c."""
    if kv_beta_s is not None:
        return float(kv_beta_s)
    if chain.rayleigh_coefficients is not None:
        return float(chain.rayleigh_coefficients[1])
    return 2.0 * chain.damping_ratio / contact_frequency_rad_s(chain)


def damping_ratio_at(chain: ChainModel, span_damping: str, beta_s: float, omega_rad_s: float) -> float:
    """The damping ratio a damping law gives a mode at omega (it sets the explicit step's stability
    limit): beta omega / 2 for the Kelvin-Voigt dashpots, Rayleigh's (alpha / omega + beta omega) / 2,
    or the modal zeta."""
    if span_damping == "kelvin-voigt":
        return 0.5 * beta_s * omega_rad_s
    if chain.rayleigh_coefficients is not None:
        alpha, beta = chain.rayleigh_coefficients
        return 0.5 * (alpha / omega_rad_s + beta * omega_rad_s)
    return chain.damping_ratio


@lru_cache(maxsize=16)
def _damping_matrix(chain: ChainModel) -> np.ndarray:
    with serial_blas():
        c = np.ascontiguousarray(chain.damping_matrix())
    c.flags.writeable = False
    return c


@lru_cache(maxsize=16)
def _max_frequency_rad_s(chain: ChainModel, tensioner: Tensioner | None) -> float:
    with serial_blas():
        return ClearanceChain(chain, 0.0, tensioner=tensioner)._max_frequency_uncached()


@dataclass(frozen=True)
class SpanLawCorrection:
    """g(y, y') = the span law's force minus the linear chain's: per span T - (P + k e) =
    clip(-(P + k e), 0, k g), +that on link j and -that on link j + 1 (a bounded force, zero in
    pulling contact)."""

    preload_N: float
    stiffness_N_per_m: float
    clearance_m: float

    def __call__(self, y: np.ndarray, _v: np.ndarray) -> np.ndarray:
        e = np.roll(y, -1) - y
        linear = self.preload_N + self.stiffness_N_per_m * e
        d = span_force_N(e, self.preload_N, self.stiffness_N_per_m, self.clearance_m) - linear
        return d - np.roll(d, 1)


def span_force_N(e_m, preload_N: float, stiffness_N_per_m: float, clearance_m: float) -> np.ndarray:
    """The span law above, element-wise."""
    d = preload_N + stiffness_N_per_m * np.asarray(e_m, dtype=float)
    kg = stiffness_N_per_m * clearance_m
    with np.errstate(invalid="ignore"):
        return np.where(d >= 0.0, d, np.where(d <= -kg, d + kg, 0.0))


def span_energy_J(e_m, preload_N: float, stiffness_N_per_m: float, clearance_m: float) -> np.ndarray:
    """Integral of the span law from the unstressed length: 1/2 T^2 / k in contact, 0 in free play."""
    return 0.5 * span_force_N(e_m, preload_N, stiffness_N_per_m, clearance_m) ** 2 / stiffness_N_per_m


def contact_state(e_m, preload_N: float, stiffness_N_per_m: float, clearance_m: float) -> np.ndarray:
    """+1 pulling contact, 0 free play, -1 pushing contact, element-wise."""
    d = preload_N + stiffness_N_per_m * np.asarray(e_m, dtype=float)
    kg = stiffness_N_per_m * clearance_m
    return np.where(d >= 0.0, 1, np.where(d <= -kg, -1, 0)).astype(np.int8)
