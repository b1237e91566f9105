"""The default physical model: a closed chain of N lumped links driven by a cam, SI throughout.

Topology. Links 1..N (array index 0..N-1) form a loop in the direction of travel; spring j
(index j) joins link j to link j+1, and the last joins link N to link 1. Link 1 is pushed by the cam
through the drive spring k_d (the follower/turret compliance; defaults to the link stiffness).
Positive displacement is the direction of travel, so link 2 leads link 1: spring j's stretch is
x_j+1 - x_j, and when the cam pushes link 1 forward the springs behind it (N -> 1, the tight side)
stretch while those ahead (1 -> 2, the slack side) compress.

Coordinates. The motion is written relative to the cam: x = z(t) 1 + y. The rigid translation with
the cam stores no energy (K 1 = k_d e_1), so

    M y'' + C y' + K y = -M 1 z''(t) + g(z' 1 + y'),

with g the friction. This is exact, keeps modal truncation convergent, and makes the periodic
steady state of continuous indexing a plain periodic problem in y.

Damping. Either a modal damping ratio zeta on every mode of (K, M), C = M Phi diag(2 zeta w) Phi^T M
(default zeta = dynamics.options.DEFAULT_DAMPING_RATIO, the sponsor's figure), or Rayleigh C = alpha M + beta K. Damping acts on y,
the motion relative to the cam: rigid translation with the cam is not damped, so the drive's damper
is the part of C that couples link 1 to the cam (consistent with the modal damping, not a separate
dashpot).

Tension. Each spring carries the preload (the idler tensioner's static tension, uniform around the
loop) plus its dynamic force k (y_j+1 - y_j). With realistic link stiffness the dynamic forces are
tens of times the preload, so the linear model puts parts of the chain into compression: a real
chain would go slack there. The response flags it; nothing is clipped.

Friction. Coulomb friction mu m g per link against the guide, opposing the link's absolute
velocity, regularised (dynamics.models.friction): F = -mu m g tanh(v / v_s) with
v_s = `friction_velocity_scale_m_s` (default 5 mm/s, about 0.1 % of the report cam's 5.4 m/s peak
indexing velocity). Below v_s the force ramps linearly; above ~2 v_s it is the full Coulomb force.
Sticking is represented by this steep viscous branch rather than by an event-driven switch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh

from dynamics.errors import DynamicsError
from dynamics.models.friction import regularised_coulomb_N
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.models.topology import ChainTopology, ring_topology
from dynamics.options import DEFAULT_DAMPING_RATIO, DEFAULT_PRELOAD_N


@dataclass(frozen=True)
class ChainModel:
    n_links: int
    link_mass_kg: float  # lumped: link body + hardware + nest
    stiffness_N_per_m: float  # one link's axial stiffness (FEA)
    drive_stiffness_N_per_m: float | None = None  # None: the link stiffness
    damping_ratio: float = DEFAULT_DAMPING_RATIO  # modal, on every mode; ignored when rayleigh_coefficients is set
    rayleigh_coefficients: tuple[float, float] | None = None  # (alpha 1/s, beta s): C = alpha M + beta K
    preload_N: float = DEFAULT_PRELOAD_N
    friction_coefficient: float = 0.0
    friction_velocity_scale_m_s: float = 5e-3
    gravity_m_s2: float = 9.80665

    def __post_init__(self) -> None:
        if not (isinstance(self.n_links, (int, np.integer)) and self.n_links >= 2):
            raise DynamicsError(f"n_links: expected an integer >= 2, got {self.n_links!r}")
        _positive("link_mass_kg", self.link_mass_kg)
        _positive("stiffness_N_per_m", self.stiffness_N_per_m)
        if self.drive_stiffness_N_per_m is not None:
            _positive("drive_stiffness_N_per_m", self.drive_stiffness_N_per_m)
        if not (np.isfinite(self.damping_ratio) and 0.0 <= self.damping_ratio < 1.0):
            raise DynamicsError(f"damping_ratio: expected 0 <= zeta < 1, got {self.damping_ratio!r}")
        if self.rayleigh_coefficients is not None:
            coeffs = tuple(self.rayleigh_coefficients)
            if len(coeffs) != 2 or not all(np.isfinite(c) and c >= 0 for c in coeffs):
                raise DynamicsError(
                    f"rayleigh_coefficients: expected (alpha, beta) >= 0, got {self.rayleigh_coefficients!r}"
                )
        if not (np.isfinite(self.preload_N) and self.preload_N >= 0):
            raise DynamicsError(f"preload_N: expected a finite value >= 0, got {self.preload_N!r}")
        if not (np.isfinite(self.friction_coefficient) and 0.0 <= self.friction_coefficient <= 1.0):
            raise DynamicsError(f"friction_coefficient: expected 0 <= mu <= 1, got {self.friction_coefficient!r}")
        _positive("friction_velocity_scale_m_s", self.friction_velocity_scale_m_s)
        _positive("gravity_m_s2", self.gravity_m_s2)

    @property
    def drive_stiffness(self) -> float:
        return float(self.stiffness_N_per_m if self.drive_stiffness_N_per_m is None else self.drive_stiffness_N_per_m)

    def topology(self) -> ChainTopology:
        """The ring (dynamics.models.topology): N links, N spans, the drive spring on link 1."""
        return ring_topology(
            self.n_links, self.link_mass_kg, self.stiffness_N_per_m, self.preload_N, self.drive_stiffness
        )

    def mass_matrix(self) -> np.ndarray:
        return self.topology().mass_matrix()

    def stiffness_matrix(self) -> np.ndarray:
        """Ring of springs k plus the drive spring on link 1."""
        return self.topology().stiffness_matrix()

    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies (rad/s, ascending) and mass-normalised mode shapes of (K, M)."""
        lam, phi = eigh(self.stiffness_matrix(), self.mass_matrix())
        return np.sqrt(lam), phi

    def damping_matrix(self) -> np.ndarray:
        m = self.mass_matrix()
        if self.rayleigh_coefficients is not None:
            alpha, beta = self.rayleigh_coefficients
            return alpha * m + beta * self.stiffness_matrix()
        omega, phi = self.modes()
        c = m @ phi @ np.diag(2.0 * self.damping_ratio * omega) @ phi.T @ m
        return 0.5 * (c + c.T)

    def system(self) -> SecondOrderSystem:
        """The linear model M y'' + C y' + K y = f in coordinates relative to the cam."""
        return SecondOrderSystem(self.mass_matrix(), self.damping_matrix(), self.stiffness_matrix())

    def natural_frequencies_Hz(self, *, driven_link_held: bool = False) -> np.ndarray:
        """Undamped natural frequencies, ascending. With the driven link held (x_1 = z) there are
        N - 1, the closed form 2 sqrt(k/m) sin(j pi / 2N) / 2 pi; otherwise N, drive spring included."""
        if driven_link_held:
            k = self.stiffness_matrix()[1:, 1:]
            lam = eigh(k, self.mass_matrix()[1:, 1:], eigvals_only=True)
            return np.sqrt(lam) / (2 * np.pi)
        return self.modes()[0] / (2 * np.pi)

    def base_excitation_force(self, zddot_m_s2: np.ndarray) -> np.ndarray:
        """-M 1 z''(t) at each sample: (n_times, N) newtons."""
        return -np.outer(np.asarray(zddot_m_s2, dtype=float), self.mass_matrix() @ np.ones(self.n_links))

    @property
    def coulomb_force_N(self) -> float:
        """mu m g: the friction force on one sliding link."""
        return self.friction_coefficient * self.link_mass_kg * self.gravity_m_s2

    def base_excitation(self, cam, t_s: np.ndarray) -> SampledForce:
        """The relative-coordinate force -M 1 z''(t) of `cam` sampled at t_s, held linearly between."""
        t = np.asarray(t_s, dtype=float)
        return SampledForce(t, self.base_excitation_force(cam.svaj(t)[2]))

    def friction_force_N(self, v_abs_m_s: np.ndarray) -> np.ndarray:
        """Regularised Coulomb friction on every link from its absolute velocity (N)."""
        return regularised_coulomb_N(v_abs_m_s, self.coulomb_force_N, self.friction_velocity_scale_m_s)

    def friction_slope_per_s(self) -> float:
        """Largest |dF/dv| / m of the friction law (1/s): sets the step the splitting needs."""
        return self.friction_coefficient * self.gravity_m_s2 / self.friction_velocity_scale_m_s

    def tension_N(self, x_m: np.ndarray) -> np.ndarray:
        """Tension of every spring: column j is spring j (link j to j+1; the last closes the loop),
        preload plus k times the stretch. Works on absolute or relative displacements alike."""
        x = np.asarray(x_m, dtype=float)
        return self.preload_N + self.stiffness_N_per_m * (np.roll(x, -1, axis=-1) - x)

    def drive_force_N(self, x1_m: np.ndarray, z_m: np.ndarray) -> np.ndarray:
        """Drive spring force on link 1, k_d (z - x_1) (positive pushing forward)."""
        return self.drive_stiffness * (np.asarray(z_m) - np.asarray(x1_m))


def _positive(name: str, value) -> None:
    if not (np.isfinite(value) and value > 0):
        raise DynamicsError(f"{name}: expected a positive finite number, got {value!r}")
