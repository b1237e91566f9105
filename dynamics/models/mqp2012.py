"""Preset `mqp2012`: a faithful replica of the 2012 report's n-DOF MATLAB script (Appendix C).

It reproduces the report's Tables 1 and 2, so it keeps the script's quirks. Each is listed here;
none of them belongs in the default model (dynamics.models.chain), which is SI throughout.

Inputs
- Link stiffness and lumped mass per material from the report's script: al6061-t6 k = 92696969.7
  N/m, m = 2.03 kg; ti-grade2 k = 143884892.1 N/m, m = 2.28 kg (link body + hardware + 0.93 kg nest).
  Damping ratio zeta = 0.13.
- The cam input is what Dynacam exported: angle, s, v, a at every degree from 0 to 180 deg, in mm,
  for the program rise 112.5 mm / 45 deg, dwell 45 deg, rise, dwell (`dynacam_table`). Dynacam's
  velocities come out 2.36e-5 larger than ds/dtheta * 2 pi rpm / 60 gives: it works with the cam
  speed rounded to 0.01 rad/s (18.85 rad/s at 180 rpm). With that rounding the table's RMS column
  (report Table 1, "Program Dynacam") is reproduced to every printed digit; without it the
  velocities miss the last digit for all five cams.

Model (units: the cam data are in mm while k is in N/m and m in kg, so displacements are mm,
velocities mm/s, accelerations mm/s^2, and k x is in mN. The linear response scales with the cam
input and is unaffected; the two constant terms are not: the preload and the friction.)
- K: a ring of springs k with K(1,1) = 3k (link 1 also hangs on the drive spring) and
  K(N,N) = 2k, K(1,N) = K(N,1) = -k.
- Damping "vector" c = 2 zeta w m with w the square roots of the sorted generalised eigenvalues of
  (K, M): one number per mode, then used as if it were one damper per link. C is built like K from
  it, with the script's asymmetric corner terms: C(i,i) = c(i) + c(i+1), C(i,i+1) = C(i+1,i) =
  -c(i+1), then C(N,N) = c(1) + c(N), C(1,1) = 3 c(1), C(N,1) = -c(1), C(1,N) = -c(N).
- Excitation on link 1 only: f = c(1) zdot + k z, with z, zdot from the Dynacam table in mm.
- Idler preload: +2224 and -2224 on two links (even N: links N/2 - 2 and N/2 + 4; odd N: links
  (N - 3)/2 and (N + 7)/2). In mm units this is 2.224 N, not the 2224 N intended. The script's
  layout needs N >= 8.
- Friction: b = mu * 9.8 and the script subtracts diag(M) .* b .* sign(v) from the acceleration
  (m mu g instead of mu g, and read as mm/s^2): 7 mm/s^2 for mu = 0.35 and aluminium, where Coulomb
  friction would decelerate a sliding link by mu g = 3430 mm/s^2 (~500x more). Against accelerations
  of 1e5-1e6 mm/s^2 the friction coefficient has no visible effect (the report's section 6.4 noticed). The printed script
  says b = 0.25 * 9.8; the report's tables were made at 0.35 (`friction=0.35`).

Stability: the script's damping matrix can feed energy in; for N < 24 the model is unstable and
its numbers grow without bound (`growth_rate_1_s`, `ReplicaResult.stable`). The replica runs anyway
(the script did) and reports it.

Integration: from rest, MATLAB ode45 (RelTol 1e-3, AbsTol 1e-6) restarted at every degree with the
force linear between the two degrees (dynamics.solvers method "report-rk45").

Metrics as the script computes them
- 181 samples at whole degrees 0..180 including the initial state.
- Acceleration x'' = inv(M) (-C xdot - K x + forces), where `forces` is whatever the ODE function's
  global held last: the force at the end of the interval (ode45's last evaluation is at t2), i.e.
  without friction. The first row stays zero (MATLAB grows the array from row 2).
- RMS of the displacement, velocity and acceleration of link round(3N/4) (MATLAB rounding: link 64
  for N = 85) and the maximum |acceleration| of every link (`Ma`). Table 1's caption says link 63,
  but the script indexes round(3*85/4) = 64 and Table 1's printed values are link 64's (link 63's
  velocity RMS is 0.4-2.2 % off). Table 2 ("link 63") really is column 63 of `Ma` (within 0.01 %;
  column 64 is 0.04-2.9 % off): the authors picked the link their figure captions name, 3N/4
  rounded down. `ReplicaResult.table_link` and `table2_link` carry the two choices.

`run_quirks_fixed` runs the same set-up with the units and the damping fixed, to show what the
quirks cost (e.g. aluminium, modified trapezoid, link 64: RMS acceleration 6.46e5 -> 3.28e5 mm/s^2).
Results are in mm like the report's; every history has SI views (`x_m`, `v_m_s`, `a_m_s2`, ...) and
the tables `table1_si()`, `table2_si()` for summary.json.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from dynamics.cams.laws import get_law
from dynamics.cams.program import mqp2012_program
from dynamics.errors import DynamicsError
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.response.metrics import matlab_round, residual_vibration, rms

MATERIALS = {  # stiffness N/m, lumped mass kg (as in the script's comments)
    "al6061-t6": (92696969.7, 2.03),
    "ti-grade2": (143884892.1, 2.28),
}
CAMS = ("modified-sine", "modified-trapezoid", "poly-345", "poly-4567", "cycloidal")
ZETA = 0.13
PRELOAD = 2224.0  # the script's number; acts as 2.224 N in its mm units
GRAVITY = 9.8
MM = 1e-3  # metres per mm: the SI exports multiply by this

# The report's printed values (section 5.5), kept to compare against; mm, mm/s, mm/s^2.
# Table 1's modified-trapezoid Dynacam acceleration (2.28E+03) is a misprint (~1.93e5).
REPORT_TABLE1_DYNACAM = {
    "modified-sine": (156.84, 2223.3, 1.79e5),
    "modified-trapezoid": (156.95, 2283.2, 2.28e3),
    "poly-345": (156.94, 2275.7, 1.89e5),
    "poly-4567": (157.21, 2432.1, 2.31e5),
    "cycloidal": (157.04, 2331.9, 2.03e5),
}
REPORT_TABLE1 = {
    "al6061-t6": {
        "modified-sine": (157.63, 2881.9, 3.84e5),
        "modified-trapezoid": (158.00, 3709.7, 6.46e5),
        "poly-345": (157.91, 3464.2, 5.70e5),
        "poly-4567": (159.11, 5466.3, 1.11e6),
        "cycloidal": (158.29, 4190.8, 7.77e5),
    },
    "ti-grade2": {
        "modified-sine": (157.25, 2617.2, 3.53e5),
        "modified-trapezoid": (157.58, 2626.2, 3.01e5),
        "poly-345": (157.48, 2602.8, 2.93e5),
        "poly-4567": (158.23, 3255.4, 5.53e5),
        "cycloidal": (157.74, 2751.5, 3.42e5),
    },
}
REPORT_TABLE2 = {  # max |acceleration|, mm/s^2
    "al6061-t6": {
        "modified-sine": 944040.0,
        "modified-trapezoid": 1478200.0,
        "poly-345": 1332500.0,
        "poly-4567": 2384900.0,
        "cycloidal": 1741900.0,
    },
    "ti-grade2": {
        "modified-sine": 918580.0,
        "modified-trapezoid": 738320.0,
        "poly-345": 728790.0,
        "poly-4567": 1150500.0,
        "cycloidal": 817740.0,
    },
}


def dynacam_omega_rad_s(rpm: float) -> float:
    """The cam speed Dynacam computes with: 2 pi rpm / 60 rounded to 0.01 rad/s (see module doc)."""
    return round(2.0 * math.pi * rpm / 60.0, 2)


@dataclass(frozen=True)
class DynacamTable:
    """What the script read from Dynacam's export: one row per degree, 0..180, mm units."""

    angle_deg: np.ndarray
    s_mm: np.ndarray
    v_mm_s: np.ndarray
    a_mm_s2: np.ndarray


def dynacam_table(law_id: str, rpm: float = 180.0) -> DynacamTable:
    """The report's cam (two 112.5 mm rises over 45 deg, each followed by a 45 deg dwell) as Dynacam
    tabulated it at `rpm`: s, and v, a with Dynacam's rounded cam speed."""
    program = mqp2012_program(law_id, rpm)
    angle = np.arange(181.0)
    omega = 2.0 * math.pi * rpm / 60.0
    s, v, a, _ = program.svaj(angle / (6.0 * rpm))
    r = dynacam_omega_rad_s(rpm) / omega
    return DynacamTable(angle, s / MM, v * r / MM, a * r**2 / MM)


def script_matrices(n_links: int, stiffness: float, mass: float, zeta: float = ZETA):
    """M, K, C and the damping vector c exactly as the script builds them."""
    n = n_links
    M = mass * np.eye(n)
    K = np.zeros((n, n))
    for i in range(n - 1):
        K[i, i] = 2 * stiffness
        K[i, i + 1] = K[i + 1, i] = -stiffness
    K[n - 1, n - 1] = 2 * stiffness
    K[0, 0] = 3 * stiffness
    K[n - 1, 0] = K[0, n - 1] = -stiffness
    w = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))  # ascending, as MATLAB's eig(K, M)
    c = 2 * zeta * w * mass
    C = np.zeros((n, n))
    for i in range(n - 1):
        C[i, i] = c[i] + c[i + 1]
        C[i, i + 1] = -c[i + 1]
        C[i + 1, i] = -c[i + 1]
    C[n - 1, n - 1] = c[0] + c[n - 1]
    C[0, 0] = 3 * c[0]
    C[n - 1, 0] = -c[0]
    C[0, n - 1] = -c[n - 1]
    return M, K, C, c, w


def preload_links(n_links: int) -> tuple[int, int]:
    """1-based links carrying the script's +2224 and -2224 entries."""
    if n_links % 2 == 0:
        first = 1 + (n_links - 8) // 2 + 1
        return first, first + 6
    first = 1 + (n_links - 7) // 2 + 1
    return first, first + 5


def preload_vector(n_links: int) -> np.ndarray:
    p = np.zeros(n_links)
    plus, minus = preload_links(n_links)
    p[plus - 1] = PRELOAD
    p[minus - 1] = -PRELOAD
    return p


@dataclass(frozen=True)
class CamReplica:
    """One cam's histories as the script has them (mm units) and its table values."""

    law_id: str
    t_s: np.ndarray  # (181,)
    z_mm: np.ndarray
    zdot_mm_s: np.ndarray
    zddot_mm_s2: np.ndarray
    x_mm: np.ndarray  # (181, N)
    v_mm_s: np.ndarray
    a_mm_s2: np.ndarray  # the script's acceleration (first row zero)
    table_link: int  # round(3N/4)
    dwell_mask: np.ndarray  # (181,) True inside the cam's dwells

    @property
    def residual_vibration_mm(self) -> np.ndarray:
        """Per link, max |x - z| inside the dwells (mm); not in the report, for the comparisons."""
        return residual_vibration(self.x_mm, self.z_mm, self.dwell_mask)

    @property
    def rms_dynacam(self) -> tuple[float, float, float]:
        """Table 1 "Program Dynacam": RMS of z, zdot, zddot (mm, mm/s, mm/s^2)."""
        return float(rms(self.z_mm)), float(rms(self.zdot_mm_s)), float(rms(self.zddot_mm_s2))

    @property
    def rms_table_link(self) -> tuple[float, float, float]:
        """Table 1 "Calculated MATLAB": RMS of link round(3N/4) (mm, mm/s, mm/s^2)."""
        k = self.table_link - 1
        return float(rms(self.x_mm[:, k])), float(rms(self.v_mm_s[:, k])), float(rms(self.a_mm_s2[:, k]))

    @property
    def max_abs_acceleration_mm_s2(self) -> np.ndarray:
        """The script's `Ma`: max |acceleration| of every link (mm/s^2)."""
        return np.max(np.abs(self.a_mm_s2), axis=0)

    # SI views (for summary.json and the reporting layer)
    @property
    def z_m(self) -> np.ndarray:
        return self.z_mm * MM

    @property
    def zdot_m_s(self) -> np.ndarray:
        return self.zdot_mm_s * MM

    @property
    def zddot_m_s2(self) -> np.ndarray:
        return self.zddot_mm_s2 * MM

    @property
    def x_m(self) -> np.ndarray:
        return self.x_mm * MM

    @property
    def v_m_s(self) -> np.ndarray:
        return self.v_mm_s * MM

    @property
    def a_m_s2(self) -> np.ndarray:
        return self.a_mm_s2 * MM


@dataclass(frozen=True)
class ReplicaResult:
    material: str
    n_links: int
    rpm: float
    friction: float
    stiffness_N_per_m: float
    lumped_mass_kg: float
    zeta: float
    natural_frequencies_rad_s: np.ndarray  # the script's sorted w (of its K with K(1,1) = 3k)
    max_growth_rate_1_s: float  # largest real part of the state-matrix eigenvalues
    cams: dict[str, CamReplica] = field(repr=False)
    fixes: tuple[str, ...] = ()  # quirks fixed (`run_quirks_fixed`); () is the faithful replica

    @property
    def stable(self) -> bool:
        """False when the script's model has a growing free vibration (see `growth_rate_1_s`)."""
        return self.max_growth_rate_1_s < 0.0

    @property
    def table_link(self) -> int:
        return int(matlab_round(3 * self.n_links / 4))

    @property
    def table2_link(self) -> int:
        """The link whose maximum acceleration Table 2 prints: floor(3N/4) (see the module docstring)."""
        return 3 * self.n_links // 4

    def table1(self) -> dict[str, dict[str, tuple[float, float, float]]]:
        """cam -> {"dynacam": (s, v, a) RMS, "link": (x, v, a) RMS of link round(3N/4)}, mm units."""
        return {cam: {"dynacam": r.rms_dynacam, "link": r.rms_table_link} for cam, r in self.cams.items()}

    def table2(self) -> dict[str, float]:
        """cam -> max |acceleration| of `table2_link` (mm/s^2)."""
        return {cam: float(r.max_abs_acceleration_mm_s2[self.table2_link - 1]) for cam, r in self.cams.items()}

    def table1_si(self) -> dict[str, dict[str, tuple[float, float, float]]]:
        """As `table1`, in m, m/s, m/s^2."""
        return {cam: {k: tuple(q * MM for q in v) for k, v in row.items()} for cam, row in self.table1().items()}

    def table2_si(self) -> dict[str, float]:
        """As `table2`, in m/s^2."""
        return {cam: a * MM for cam, a in self.table2().items()}


def replica_system(material: str, n_links: int, friction: float) -> tuple[SecondOrderSystem, np.ndarray]:
    """The script's second-order system (mm units) with its friction term, and its c vector."""
    stiffness, mass = MATERIALS[material]
    M, K, C, c, _ = script_matrices(n_links, stiffness, mass)
    mass_diag = np.diag(M).copy()
    b = friction * GRAVITY

    def script_friction(x: np.ndarray, v: np.ndarray) -> np.ndarray:
        # The script subtracts diag(M).*b.*sign(v) from the acceleration; as a force that is
        # M times it (M is diagonal).
        return -mass_diag * mass_diag * b * np.sign(v)

    return SecondOrderSystem(M, C, K, script_friction if friction > 0 else None), c


def growth_rate_1_s(material: str, n_links: int) -> float:
    """Largest real part of the eigenvalues of the script's first-order state matrix.

    The script's C is not symmetric and not positive semi-definite (C(1,N) = -c(N) pairs with
    C(N,1) = -c(1), and c(N) is the damping of the highest mode), so it can feed energy in: for both
    materials the model has a growing free vibration for N < 24 (at N = 20, the report's first test,
    it grows 1.5x over the 1/6 s simulated; at N = 8, 3e5x (Al) to 2e6x (Ti)). From N = 24 on, all
    modes decay.
    """
    stiffness, mass = MATERIALS[material]
    M, K, C, _, _ = script_matrices(n_links, stiffness, mass)
    n = n_links
    state = np.block([[np.zeros((n, n)), np.eye(n)], [-K / mass, -C / mass]])
    return float(np.max(np.linalg.eigvals(state).real))


def _check_inputs(material, n_links, rpm, friction, cams):
    if material not in MATERIALS:
        raise DynamicsError(f"material: got {material!r}; expected one of {', '.join(MATERIALS)}")
    if not (isinstance(n_links, (int, np.integer)) and n_links >= 8):
        raise DynamicsError(f"n_links: got {n_links!r}; the mqp2012 preset needs an integer >= 8 (its preload layout)")
    if not (np.isfinite(rpm) and rpm > 0):
        raise DynamicsError(f"rpm: got {rpm!r}; expected a cam speed > 0 rev/min")
    if not (np.isfinite(friction) and friction >= 0):
        raise DynamicsError(f"friction: got {friction!r}; expected a Coulomb coefficient >= 0")
    if not cams:
        raise DynamicsError("cams: got none; expected at least one cam law id")
    for cam in cams:
        get_law(cam)  # any registered law can be tabulated as Dynacam would have; the report had CAMS


def run_mqp2012(
    material: str = "al6061-t6",
    *,
    n_links: int = 85,
    rpm: float = 180.0,
    friction: float = 0.35,
    cams: tuple[str, ...] = CAMS,
    method: str = "report-rk45",
) -> ReplicaResult:
    """Run the report's script for one material; `method` other than "report-rk45" swaps the
    integrator only (every quirk of the model and the metrics stays)."""
    _check_inputs(material, n_links, rpm, friction, cams)
    from dynamics.solvers import solve  # the solver package imports the system contract only

    stiffness, mass = MATERIALS[material]
    system, c = replica_system(material, n_links, friction)
    M, K, C = system.mass, system.stiffness, system.damping
    inv_m = np.linalg.inv(M)
    t = np.arange(181) * ((1.0 / (rpm / 60.0)) / 360.0)
    preload = preload_vector(n_links)
    results = {}
    for cam in cams:
        table = dynacam_table(cam, rpm)
        forces = np.tile(preload, (t.size, 1))
        forces[:, 0] = c[0] * table.v_mm_s + stiffness * table.s_mm
        response = solve(system, SampledForce(t, forces), t, method=method, x0=np.zeros(n_links), v0=np.zeros(n_links))
        acc = (inv_m @ (-C @ response.v.T - K @ response.x.T + forces.T)).T
        acc[0] = 0.0
        results[cam] = CamReplica(
            cam,
            t,
            table.s_mm,
            table.v_mm_s,
            table.a_mm_s2,
            response.x,
            response.v,
            acc,
            int(matlab_round(3 * n_links / 4)),
            mqp2012_program(cam, rpm).dwell_mask(t),
        )
    w = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))
    return ReplicaResult(
        material,
        n_links,
        float(rpm),
        float(friction),
        stiffness,
        mass,
        ZETA,
        w,
        growth_rate_1_s(material, n_links),
        results,
    )


FIXES = ("si-units", "modal-damping")


def modal_damping_matrix(M: np.ndarray, K: np.ndarray, zeta: float) -> np.ndarray:
    """Symmetric classical damping with ratio `zeta` on every mode of (K, M): M Phi diag(2 zeta w) Phi^T M."""
    lam, phi = scipy.linalg.eigh(K, M)  # phi is mass-normalised: phi^T M phi = I
    return M @ phi @ np.diag(2.0 * zeta * np.sqrt(lam)) @ phi.T @ M


def run_quirks_fixed(
    material: str = "al6061-t6",
    *,
    fixes: tuple[str, ...] = FIXES,
    n_links: int = 85,
    rpm: float = 180.0,
    friction: float = 0.35,
    cams: tuple[str, ...] = CAMS,
    samples_per_degree: int = 10,
) -> ReplicaResult:
    """The replica with some of the script's quirks fixed, to show what each one costs.

    - "si-units": the cam input in metres, so the 2224 N preload and the friction act at their real
      size; friction written as the force -mu m g sign(v) (N) instead of the script's m^2 b sign(v).
      The chain starts at rest in its static equilibrium under the preload, K^-1 p (the script
      started at x = 0, which with its 2.224 N was a negligible jolt; with 2224 N it would be a
      1e3 m/s^2 start-up transient).
    - "modal-damping": symmetric damping with ratio zeta on every mode of (K, M)
      (`modal_damping_matrix`) acting on the chain's deformation: in coordinates relative to the
      cam, x = z + y, M y'' + C y' + K y = -M 1 z'' + preload + friction(v = y' + z'). This replaces
      the script's damping vector, its asymmetric corners and its c(1) zdot drive term.
    Everything else stays (K with K(1,1) = 3k, the preload positions, 181 one-degree samples, link
    round(3N/4)). Accelerations are the equation of motion's (friction included, first row too).
    The exact first-order-hold solver integrates on a grid `samples_per_degree` times finer than the
    one-degree output (friction by its Heun splitting). Results are returned in mm like the replica.
    """
    _check_inputs(material, n_links, rpm, friction, cams)
    unknown = [f for f in fixes if f not in FIXES]
    if unknown:
        raise DynamicsError(f"fixes: unknown {unknown[0]!r}; expected some of {', '.join(FIXES)}")
    if not (isinstance(samples_per_degree, (int, np.integer)) and samples_per_degree >= 1):
        raise DynamicsError(f"samples_per_degree: got {samples_per_degree!r}; expected an integer >= 1")
    from dynamics.solvers import solve

    si = "si-units" in fixes
    relative = "modal-damping" in fixes
    length = MM if si else 1.0  # model length unit per mm of cam data
    stiffness, mass = MATERIALS[material]
    M, K, C_script, c, _ = script_matrices(n_links, stiffness, mass)
    C = modal_damping_matrix(M, K, ZETA) if relative else C_script
    mass_diag = np.diag(M).copy()
    deg_s = (1.0 / (rpm / 60.0)) / 360.0
    t = np.arange(180 * samples_per_degree + 1) * (deg_s / samples_per_degree)
    every = slice(None, None, samples_per_degree)
    preload = preload_vector(n_links)
    omega_ratio = dynacam_omega_rad_s(rpm) / (2.0 * math.pi * rpm / 60.0)
    x_start = np.linalg.solve(K, preload) if si else np.zeros(n_links)
    results = {}
    for cam in cams:
        program = mqp2012_program(cam, rpm)
        s, v, a, _ = program.svaj(t)
        z, zdot, zddot = s / MM * length, v * omega_ratio / MM * length, a * omega_ratio**2 / MM * length

        def friction_force(tt, x, vel, _program=program):
            if relative:
                vel = vel + _program.svaj(np.array([tt]))[1][0] * omega_ratio / MM * length
            if si:
                return -friction * GRAVITY * mass_diag * np.sign(vel)
            return -mass_diag * mass_diag * friction * GRAVITY * np.sign(vel)

        forces = np.tile(preload, (t.size, 1))
        if relative:
            forces -= np.outer(zddot, mass_diag)
        else:
            forces[:, 0] += c[0] * zdot + stiffness * z
        timed = {"time_dependent_force": friction_force} if friction > 0 else {}
        response = solve(
            SecondOrderSystem(M, C, K),
            SampledForce(t, forces),
            t,
            method="exact",
            x0=x_start,
            v0=np.zeros(n_links),
            **timed,
        )
        x, vel, acc = response.x, response.v, response.a
        if relative:
            x, vel, acc = x + z[:, None], vel + zdot[:, None], acc + zddot[:, None]
        to_mm = 1.0 / length
        results[cam] = CamReplica(
            cam,
            t[every],
            z[every] * to_mm,
            zdot[every] * to_mm,
            zddot[every] * to_mm,
            x[every] * to_mm,
            vel[every] * to_mm,
            acc[every] * to_mm,
            int(matlab_round(3 * n_links / 4)),
            program.dwell_mask(t[every]),
        )
    lam = scipy.linalg.eigvals(
        np.block([[np.zeros((n_links, n_links)), np.eye(n_links)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    )
    w = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))
    return ReplicaResult(
        material,
        n_links,
        float(rpm),
        float(friction),
        stiffness,
        mass,
        ZETA,
        w,
        float(np.max(lam.real)),
        results,
        tuple(fixes),
    )
