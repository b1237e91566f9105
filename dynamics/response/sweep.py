"""Speed sweep: residual vibration and peak acceleration at one station versus cam speed, per cam law.

Two models: `rpm_sweep`, the link drive's linear chain, modal (below); `machine_rpm_sweep`, the
machine on its wheels, whose relabelled steady state (the seat changes, the polygonal feed) is not a
periodic response of fixed modes: each point is the linear machine's own run at that speed
(dynamics.machine_scene.simulate_machine), critical speeds from the machine's frequencies
(MachineOnWheels.modes). The rest of this docstring is the link drive's modal sweep.

Why it is fast. The chain is linear (friction 0) and written relative to the cam, y = x - z 1, under
the force -M 1 z''(t) (dynamics.models.chain). In the modes of (K, M) every mode j is a damped oscillator

    q_j'' + c_j q_j' + w_j^2 q_j = -G_j z''(t),   G_j = phi_j^T M 1 (participation),

and with the complex coordinate u_j (q_j = 2 Re u_j, u_j' = l_j u_j + b_j p(t), l_j the pole,
b_j = 1 / (2 i w_dj)) one step h under a first-order-hold force is exactly

    u_k+1 = E u_k + b (G0 p_k + G1 p_k+1),  E = exp(l h), G1 = h phi2(l h), G0 = h (phi1(l h) - phi2(l h)).

The periodic steady state of that recurrence over n samples of one index cycle is diagonalised by the
discrete Fourier transform: U_m (w^m - E) = b P_m (G0 + G1 w^m), w = exp(2 pi i / n). So every speed
costs one transfer function per station link and one FFT per cam: no matrix exponential, no time
loop. The mode shapes are computed once (`chain_modes`) and reused for every speed and cam; only
the step h = cycle time / n and the force scale (rpm^2) change with the speed, because the samples
sit at the same cam angles at every speed. This is the same discretisation as `simulate(...,
method="exact", steady_state=True)` on the same grid (first-order hold between samples), so the two
agree to rounding when all modes are kept.

Friction: refused (friction_coefficient > 0 raises DynamicsError). Coulomb friction makes the model
nonlinear, so neither the modal decoupling nor the speed scaling holds; run `simulate` per speed.

Critical speeds: the index cycle repeats `cycles_per_rev` = 360 / (index + dwell angle) times per cam
revolution, so the forcing has the fundamental f_idx = cycles_per_rev rpm / 60 Hz and its harmonics
k f_idx. A critical speed is an rpm at which a harmonic k of the index frequency equals a natural
frequency f_j of the chain (drive spring included): rpm_jk = 60 f_j / (k cycles_per_rev). Marked for
the modes the cam actually excites (effective modal mass G_j^2 at least `min_mass_fraction` of the
chain's mass; for the default chain modes 1, 3, 5 carry 84 %, 9 %, 3 %).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.linalg import eigh
from scipy.sparse.linalg import eigsh

from dynamics.cams.laws import get_law
from dynamics.cams.program import CamProgram
from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.lanczos import lanczos_start
from dynamics.response.metrics import STATIONS, station_links
from dynamics.response.seating import RIGID, TOOTH_STIFFNESS_MODEL

# which model a sweep ran, in words (SweepResult.model)
LINK_DRIVE_MODEL = "the link drive's linear chain"
MACHINE_MODEL = "the linear machine on its wheels (free play 0)"

# Above this many links, a truncated mode set of at most N/10 modes comes from sparse shift-invert
# Lanczos (cost ~ N r^2, ARPACK keeps ~2r vectors) rather than a dense eigensolve (~ N^3); below
# either bound the dense solve is faster and simpler.
_DENSE_LIMIT = 400


@dataclass(frozen=True)
class ChainModes:
    """The kept modes of a linear chain: one decomposition, reused for every speed and cam."""

    omega_rad_s: np.ndarray  # (r,) undamped natural frequencies, ascending
    damping_1_s: np.ndarray  # (r,) modal damping coefficients c_j (2 zeta_j w_j)
    shapes: np.ndarray  # (N, r) mass-normalised mode shapes
    participation: np.ndarray  # (r,) G_j = phi_j^T M 1 (sqrt(kg))
    total_mass_kg: float

    @property
    def n_links(self) -> int:
        return self.shapes.shape[0]

    @property
    def n_modes(self) -> int:
        return self.omega_rad_s.size

    @property
    def natural_frequencies_Hz(self) -> np.ndarray:
        return self.omega_rad_s / (2 * np.pi)

    @property
    def effective_mass_fraction(self) -> np.ndarray:
        """G_j^2 / total mass: the share of the cam's base excitation each mode takes."""
        return self.participation**2 / self.total_mass_kg

    @property
    def poles(self) -> np.ndarray:
        """l_j = -c_j / 2 + i w_dj (the upper pole of each underdamped mode)."""
        half = 0.5 * self.damping_1_s
        return -half + 1j * np.sqrt(self.omega_rad_s**2 - half**2)


def stiffness_matrix_sparse(model: ChainModel) -> sp.csr_matrix:
    """The chain's K (ring of springs plus the drive spring on link 1) as a sparse matrix; equal to
    ChainModel.stiffness_matrix() without forming N x N dense storage."""
    return model.topology().stiffness_matrix_sparse()


def chain_modes(model: ChainModel, n_modes: int | None = None) -> ChainModes:
    """The `n_modes` lowest modes of the linear chain (all by default) with the model's damping."""
    if model.friction_coefficient > 0.0:
        raise DynamicsError(
            f"friction_coefficient: got {model.friction_coefficient!r}; the modal sweep needs the linear model "
            "(friction 0); run simulate() per speed for friction"
        )
    n = model.n_links
    if n_modes is None:
        n_modes = n
    if not (isinstance(n_modes, (int, np.integer)) and 1 <= n_modes <= n):
        raise DynamicsError(f"n_modes: got {n_modes!r}; expected an integer in 1..{n}")
    m = model.link_mass_kg  # the chain's mass matrix is m I
    k_sparse = stiffness_matrix_sparse(model)
    if n <= _DENSE_LIMIT or n_modes > n // 10:
        lam, vec = eigh(k_sparse.toarray() / m, subset_by_index=[0, n_modes - 1])
    else:
        lam, vec = eigsh((k_sparse / m).tocsc(), k=n_modes, sigma=0.0, which="LM", v0=lanczos_start(n))
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
    omega = np.sqrt(np.clip(lam, 0.0, None))
    shapes = vec / np.sqrt(m)
    if model.rayleigh_coefficients is not None:
        alpha, beta = model.rayleigh_coefficients
        damping = alpha + beta * omega**2
    else:
        damping = 2.0 * model.damping_ratio * omega
    if np.any(damping <= 0.0) or np.any(damping >= 2.0 * omega):
        raise DynamicsError(
            "damping: the periodic modal solution needs every kept mode damped and underdamped "
            f"(0 < c_j < 2 w_j); got modal damping ratios {np.min(damping / (2 * omega)):.3g}.."
            f"{np.max(damping / (2 * omega)):.3g}"
        )
    participation = m * shapes.sum(axis=0)
    return ChainModes(omega, damping, shapes, participation, float(m * n))


def _phi12(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """phi1(z) = (e^z - 1) / z and phi2(z) = (e^z - 1 - z) / z^2, with a Taylor series near 0 where
    the closed forms cancel."""
    z = np.asarray(z, dtype=complex)
    small = np.abs(z) < 0.5
    zs = np.where(small, z, 0.0)
    phi1_s = np.zeros_like(z)
    phi2_s = np.zeros_like(z)
    term = np.ones_like(z)  # z^k / k!
    for k in range(25):  # |z| < 0.5: the 25th term is below 1e-40
        phi1_s += term / (k + 1)
        phi2_s += term / ((k + 1) * (k + 2))
        term = term * zs / (k + 1)
    zl = np.where(small, 1.0, z)
    em1 = np.expm1(zl)
    phi1_l = em1 / zl
    phi2_l = (em1 - zl) / zl**2
    return np.where(small, phi1_s, phi1_l), np.where(small, phi2_s, phi2_l)


def modal_periodic_response(modes: ChainModes, zddot_m_s2: np.ndarray, step_s, links) -> tuple[np.ndarray, np.ndarray]:
    """Periodic steady state at the given links under the cam acceleration samples.

    zddot_m_s2: (..., n) cam acceleration at n equally spaced samples of one period (the sample at
    the period's end equals the first and is not repeated); step_s: the sample spacing (s), an array
    whose shape broadcasts against the leading shape `...` (one transfer function per distinct
    entry, shared by everything broadcast over it). Returns (y_m, a_m_s2), each (..., n, len(links)):
    the links' motion relative to the cam (x - z) and their absolute acceleration at the samples.
    """
    z = np.asarray(zddot_m_s2, dtype=float)
    n = z.shape[-1]
    h = np.asarray(step_s, dtype=float)
    cols = np.asarray(links, dtype=int).reshape(-1)
    if cols.size == 0 or cols.min() < 0 or cols.max() >= modes.n_links:
        raise DynamicsError(f"links: got {links!r}; expected 0-based link indices in 0..{modes.n_links - 1}")
    if h.size == 0 or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise DynamicsError(f"step_s: got {step_s!r}; expected positive sample spacings in seconds")
    h_x, h_a = _transfer(modes, h.reshape(-1), n, cols)
    h_x = h_x.reshape(*h.shape, n, cols.size)
    h_a = h_a.reshape(*h.shape, n, cols.size)
    spectrum = np.fft.fft(z, axis=-1)[..., None]
    y = 2.0 * np.fft.ifft(spectrum * h_x, axis=-2).real
    quasi_static = 1.0 - modes.shapes[cols] @ modes.participation  # (L,): 0 when every mode is kept
    a = 2.0 * np.fft.ifft(spectrum * h_a, axis=-2).real + z[..., None] * quasi_static
    return y, a


def _transfer(modes: ChainModes, steps: np.ndarray, n: int, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step h and DFT index m, the displacement and acceleration transfer functions
    sum_j phi_lj b_j (-G_j) (G0 + G1 w^m) / (w^m - E) (times l_j^2 for acceleration): (S, n, L) each."""
    lam = modes.poles
    kappa = -modes.participation / (2j * lam.imag)  # b_j times the force's modal factor -G_j
    phi = modes.shapes[cols]  # (L, r)
    weights = np.concatenate([phi * kappa, phi * (kappa * lam**2)]).T  # (r, 2L): q'' = 2 Re(l^2 u) - G z''
    wm = np.exp(2j * np.pi * np.arange(n) / n)[:, None]  # (n, 1)
    out = np.empty((steps.size, n, 2 * cols.size), dtype=complex)
    for i, h in enumerate(steps):
        zl = lam * h
        p1, p2 = _phi12(zl)
        g1 = h * p2
        g0 = h * (p1 - p2)
        out[i] = ((g0 + g1 * wm) / (wm - np.exp(zl))) @ weights
    return out[:, :, : cols.size], out[:, :, cols.size :]


@dataclass(frozen=True)
class CriticalSpeed:
    rpm: float
    mode: int  # 1-based, ascending frequency
    harmonic: int  # k: the k-th harmonic of the index frequency meets the mode
    frequency_Hz: float


def critical_speeds_rpm(
    natural_frequencies_Hz,
    cycles_per_rev: float,
    rpm_range: tuple[float, float],
    max_harmonic: int = 10,
    modes: tuple[int, ...] | None = None,
) -> tuple[CriticalSpeed, ...]:
    """rpm_jk = 60 f_j / (k cycles_per_rev) for harmonics k = 1..max_harmonic and the given 1-based
    modes (all by default), keeping those inside rpm_range; sorted by rpm."""
    f = np.asarray(natural_frequencies_Hz, dtype=float)
    if not (np.isfinite(cycles_per_rev) and cycles_per_rev > 0):
        raise DynamicsError(f"cycles_per_rev: got {cycles_per_rev!r}; expected a positive number")
    if not (isinstance(max_harmonic, (int, np.integer)) and max_harmonic >= 1):
        raise DynamicsError(f"max_harmonic: got {max_harmonic!r}; expected an integer >= 1")
    lo, hi = rpm_range
    chosen = range(1, f.size + 1) if modes is None else modes
    out = []
    for j in chosen:
        for k in range(1, max_harmonic + 1):
            rpm = 60.0 * f[j - 1] / (k * cycles_per_rev)
            if lo <= rpm <= hi:
                out.append(CriticalSpeed(float(rpm), int(j), k, float(f[j - 1])))
    return tuple(sorted(out, key=lambda c: c.rpm))


@dataclass(frozen=True)
class SweepResult:
    """Periodic steady-state metrics at one station for every (cam, speed); SI units."""

    rpm: np.ndarray  # (n_speeds,)
    cam_ids: tuple[str, ...]
    station: str  # station name, or "link <n>"
    station_link: int  # 1-based
    residual_vibration_m: np.ndarray  # (n_cams, n_speeds): max |x - z| over the dwell samples
    peak_acceleration_m_s2: np.ndarray  # (n_cams, n_speeds): max |x''| over the cycle
    natural_frequencies_Hz: np.ndarray  # kept modes, ascending
    critical_speeds: tuple[CriticalSpeed, ...]
    cycles_per_rev: float
    samples_per_cycle: int
    n_modes: int
    definition: str = (
        "critical speed: rpm at which harmonic k of the index frequency (cycles_per_rev * rpm / 60 Hz) "
        "equals a natural frequency of the chain"
    )
    model: str = LINK_DRIVE_MODEL  # which model ran, in words for the report and its plot
    # on the wheels, the seating model each (cam, speed) ran (dynamics.response.seating.RIGID or
    # TOOTH_STIFFNESS_MODEL: the run's own verdict at that speed); None: the link drive, which has no seats
    seating_model: tuple[tuple[str, ...], ...] | None = None


def parse_rpm_range(text: str) -> np.ndarray:
    """'FROM:TO:STEP' (rev/min) -> the speeds FROM, FROM + STEP, ... up to TO inclusive."""
    parts = str(text).split(":")
    try:
        lo, hi, step = (float(p) for p in parts)
    except ValueError:
        raise DynamicsError(f"rpm range: got {text!r}; expected FROM:TO:STEP, three numbers in rev/min") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and np.isfinite(step) and 0 < lo <= hi and step > 0):
        raise DynamicsError(f"rpm range: got {text!r}; expected 0 < FROM <= TO and STEP > 0 (rev/min)")
    count = int(np.floor((hi - lo) / step * (1 + 1e-12))) + 1
    if count > 1_000_000:
        raise DynamicsError(f"rpm range: got {text!r} ({count} speeds); expected at most 1,000,000 speeds")
    return lo + step * np.arange(count)


def _station(station, n_links: int) -> tuple[str, int]:
    if isinstance(station, str):
        if station not in STATIONS:
            raise DynamicsError(f"station: got {station!r}; expected one of {', '.join(STATIONS)} or a link number")
        return station, station_links(n_links)[station]
    if isinstance(station, (int, np.integer)) and 1 <= station <= n_links:
        return f"link {int(station)}", int(station)
    raise DynamicsError(f"station: got {station!r}; expected a station name or a link number in 1..{n_links}")


def cam_cycle_samples(
    cam_id: str, samples_per_cycle: int, *, pitch_m: float, index_deg: float, dwell_deg: float, rpm: float
) -> tuple[np.ndarray, np.ndarray, CamProgram]:
    """Times (s) and cam acceleration (m/s^2) at the samples of one index cycle at `rpm`, and the program."""
    program = CamProgram.indexing(cam_id, pitch_m=pitch_m, index_deg=index_deg, dwell_deg=dwell_deg, rpm=rpm)
    t = program.cycle_s * np.arange(samples_per_cycle) / samples_per_cycle
    return t, program.svaj(t)[2], program


def _checked_inputs(cam_ids, rpms, samples_per_cycle, min_mass_fraction) -> tuple[tuple[str, ...], np.ndarray]:
    """The cam law ids as a tuple and the speeds as an array, checked."""
    cam_ids = (cam_ids,) if isinstance(cam_ids, str) else tuple(cam_ids)
    if not cam_ids:
        raise DynamicsError("cam_ids: got none; expected at least one cam law id")
    for cam in cam_ids:
        get_law(cam)
    r = np.atleast_1d(np.asarray(rpms, dtype=float))
    if r.ndim != 1 or r.size == 0 or not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise DynamicsError(f"rpms: got {rpms!r}; expected one or more finite cam speeds > 0 rev/min")
    if not (isinstance(samples_per_cycle, (int, np.integer)) and samples_per_cycle >= 8):
        raise DynamicsError(f"samples_per_cycle: got {samples_per_cycle!r}; expected an integer >= 8")
    if not (0.0 <= min_mass_fraction < 1.0):
        raise DynamicsError(f"min_mass_fraction: got {min_mass_fraction!r}; expected 0 <= value < 1")
    return cam_ids, r


def rpm_sweep(
    model: ChainModel,
    cam_ids,
    rpms,
    *,
    pitch_m: float = 0.1125,
    index_deg: float = 45.0,
    dwell_deg: float = 45.0,
    station="tight-side",
    samples_per_cycle: int = 360,
    n_modes: int | None = None,
    max_harmonic: int = 10,
    min_mass_fraction: float = 0.01,
    modes: ChainModes | None = None,
) -> SweepResult:
    """Residual vibration and peak acceleration at `station` versus cam speed `rpms` (rev/min) for
    each cam law in `cam_ids`, in periodic steady state of continuous indexing (linear chain).

    `samples_per_cycle` samples of one index cycle (360 = 4 per cam degree for the default 90-degree
    cycle) carry the cam's acceleration (first-order hold between them) and are where the metrics are
    read. `n_modes` keeps the lowest modes only (all by default); `modes` passes a decomposition
    computed earlier (from `chain_modes(model, n_modes)`) to skip the eigensolve.
    """
    cam_ids, r = _checked_inputs(cam_ids, rpms, samples_per_cycle, min_mass_fraction)
    name, link = _station(station, model.n_links)
    if modes is None:
        modes = chain_modes(model, n_modes)
    elif modes.n_links != model.n_links:
        raise DynamicsError(f"modes: computed for {modes.n_links} links; expected {model.n_links}")

    ref_rpm = 60.0  # samples sit at the same cam angles at every speed: z'' scales with rpm^2, h with 1/rpm
    samples = [
        cam_cycle_samples(
            cam, samples_per_cycle, pitch_m=pitch_m, index_deg=index_deg, dwell_deg=dwell_deg, rpm=ref_rpm
        )
        for cam in cam_ids
    ]
    t_ref, _, program = samples[0]  # every cam shares the index/dwell layout, so the grid and dwells
    zdd = [a for _, a, _ in samples]
    dwell = program.dwell_mask(t_ref)
    scale = (r / ref_rpm) ** 2
    zddot = np.asarray(zdd)[:, None, :] * scale[None, :, None]  # (cams, speeds, n)
    step = program.cycle_s * (ref_rpm / r) / samples_per_cycle  # (speeds,)
    y, a = modal_periodic_response(modes, zddot, step, [link - 1])
    residual = np.max(np.abs(y[:, :, dwell, 0]), axis=-1)
    peak = np.max(np.abs(a[:, :, :, 0]), axis=-1)

    cycles_per_rev = 360.0 / (index_deg + dwell_deg)
    excited = tuple(int(j) + 1 for j in np.flatnonzero(modes.effective_mass_fraction >= min_mass_fraction))
    critical = critical_speeds_rpm(
        modes.natural_frequencies_Hz, cycles_per_rev, (float(r.min()), float(r.max())), max_harmonic, excited
    )
    return SweepResult(
        rpm=r,
        cam_ids=cam_ids,
        station=name,
        station_link=link,
        residual_vibration_m=residual,
        peak_acceleration_m_s2=peak,
        natural_frequencies_Hz=modes.natural_frequencies_Hz,
        critical_speeds=critical,
        cycles_per_rev=cycles_per_rev,
        samples_per_cycle=int(samples_per_cycle),
        n_modes=modes.n_modes,
        model=f"{LINK_DRIVE_MODEL}, {modes.n_modes} modes",
    )


def _machine_station(station, machine) -> tuple[str, int]:
    """(name, 0-based place) of a station name or a 1-based link number on the machine."""
    places = machine.stations()
    if isinstance(station, str):
        if station not in places:
            raise DynamicsError(f"station: got {station!r}; expected one of {', '.join(places)} or a link number")
        return station, places[station]
    if isinstance(station, (int, np.integer)) and 1 <= station <= machine.n_links:
        return f"link {int(station)}", int(station) - 1
    raise DynamicsError(f"station: got {station!r}; expected a station name or a link number in 1..{machine.n_links}")


def machine_rpm_sweep(
    model,
    cam_ids,
    rpms,
    *,
    pitch_m: float = 0.1125,
    index_deg: float = 45.0,
    dwell_deg: float = 45.0,
    station="tight-side",
    samples_per_cycle: int = 360,
    max_harmonic: int = 10,
    min_mass_fraction: float = 0.01,
    done=None,
    model_at=None,
) -> SweepResult:
    """`rpm_sweep` on the machine on its wheels: `model` is its dynamics.models.clearance_machine.ClearanceMachine
    (friction 0). At each speed and cam law the linear machine (free play 0, global damping law, the
    polygonal feed, the wheels and the carriage as the model has them) runs exactly as the pipeline
    runs it (dynamics.machine_scene.simulate_machine, choice "linear", its default step) in its
    relabelled periodic steady state over the pipeline's window (two index cycles from an index's
    start at `samples_per_cycle` per cycle); the metrics are the pipeline's at the station's place
    (its peaks over every step, the response's "station_peaks", as the pipeline's stations take
    them; at a link number, not a station, the output samples'). Critical speeds from the machine's
    own natural frequencies (MachineOnWheels.modes),
    for the modes with at least `min_mass_fraction` of the excitation. Not modal: every point is a
    steady-state search, about a thousand times the link drive's cost per point: `done(cam_id)`, when
    given, is called as each cam law's speeds are done (the stage's progress lines).

    Seating: `model_at(cam, t)`, when given, is the machine that runs the cam law at one speed on the
    output times `t` (the run's seating verdict at that speed: stages.chain.run_rpm_sweeps), else `model`
    at every speed; `seating_model` records which seating each point ran, and the modes (critical speeds)
    are the model's that ran, the tooth model's where any point ran it (as stages.chain.scene_that_ran)."""
    from dynamics.machine_scene import simulate_machine
    from dynamics.response.metrics import link_metrics

    cam_ids, r = _checked_inputs(cam_ids, rpms, samples_per_cycle, min_mass_fraction)
    if model.chain.friction_coefficient > 0.0:
        raise DynamicsError(
            f"friction_coefficient: got {model.chain.friction_coefficient!r}; the speed sweep runs the machine "
            "without friction"
        )
    name, place = _machine_station(station, model.machine)
    cycle_deg = index_deg + dwell_deg
    per_degree = samples_per_cycle / cycle_deg
    residual = np.empty((len(cam_ids), r.size))
    peak = np.empty_like(residual)
    seating = [[""] * r.size for _ in cam_ids]
    modes_of = model  # the machine whose modes give the critical speeds: the tooth model's where one ran
    for i, cam_id in enumerate(cam_ids):
        for j, rpm in enumerate(r):
            # the pipeline's output grid (stages.chain.output_times_s): two index cycles in degrees
            t = np.arange(2 * samples_per_cycle + 1) / per_degree / (360.0 / 60.0 * rpm)
            cam = CamProgram.indexing(cam_id, pitch_m=pitch_m, index_deg=index_deg, dwell_deg=dwell_deg, rpm=rpm)
            ran = model if model_at is None else model_at(cam, t)
            seating[i][j] = seating_model_of(ran.machine)
            if seating[i][j] == TOOTH_STIFFNESS_MODEL and seating_model_of(modes_of.machine) == RIGID:
                modes_of = ran
            out, _ = simulate_machine(ran, cam, t, choice="linear", links=[place])
            at_station = (out.diagnostics.get("station_peaks") or {}).get(name)
            if at_station is None:
                lm = link_metrics(
                    out.x_m, out.v_m_s, out.a_m_s2, out.z_m, out.zdot_m_s, out.zddot_m_s2, cam.dwell_mask(t)
                )
                at_station = {
                    "residual_vibration_m": lm.residual_vibration_m[0],
                    "max_abs_acceleration_m_s2": lm.max_abs_acceleration_m_s2[0],
                }
            residual[i, j] = at_station["residual_vibration_m"]
            peak[i, j] = at_station["max_abs_acceleration_m_s2"]
        if done is not None:
            done(cam_id)
    frequencies, fraction = modes_of.machine.modes()
    cycles_per_rev = 360.0 / cycle_deg
    excited = tuple(int(j) + 1 for j in np.flatnonzero(fraction >= min_mass_fraction))
    critical = critical_speeds_rpm(frequencies, cycles_per_rev, (float(r.min()), float(r.max())), max_harmonic, excited)
    return SweepResult(
        rpm=r,
        cam_ids=cam_ids,
        station=name,
        station_link=place + 1,
        residual_vibration_m=residual,
        peak_acceleration_m_s2=peak,
        natural_frequencies_Hz=frequencies,
        critical_speeds=critical,
        cycles_per_rev=cycles_per_rev,
        samples_per_cycle=int(samples_per_cycle),
        n_modes=frequencies.size,
        definition=(
            "critical speed: rpm at which harmonic k of the index frequency (cycles_per_rev * rpm / 60 Hz) "
            "equals a natural frequency of the machine on its wheels"
        ),
        model=MACHINE_MODEL,
        seating_model=tuple(tuple(row) for row in seating),
    )


def seating_note(sweep: SweepResult) -> str | None:
    """Which seating the sweep's points ran, in words for its progress line and the report (None: the
    link drive, which has no seats); per point it is `seating_model`, rpm_sweep.csv's column."""
    if sweep.seating_model is None:
        return None
    points = [model for row in sweep.seating_model for model in row]
    switched = points.count(TOOTH_STIFFNESS_MODEL)
    if switched == 0:
        return f"{RIGID} at every point"
    note = f"{TOOTH_STIFFNESS_MODEL} at {switched} of {len(points)} points (rigid seating does not hold there)"
    return note if switched == len(points) else f"{note}, {RIGID} at the others"


def seating_model_of(machine) -> str:
    """The seating model a dynamics.models.machine.MachineOnWheels runs, in the verdict's words."""
    return RIGID if np.isinf(machine.tooth_stiffness_N_per_m) else TOOTH_STIFFNESS_MODEL
