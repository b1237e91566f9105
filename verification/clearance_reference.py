"""Slow reference solution of the clearance chain (issue #11), written from the model's equations.

The model (SI): N links of mass m_i, displacement x_i from the static preloaded
state, written relative to the cam input z(t) as y = x - z 1. Span j joins link j to link j+1 (the
last closes the loop to link 0), stretch e_j = y_j+1 - y_j, axial free play g_j >= 0, preload P:

    T = P + k e               for e >= -P/k              (pulling contact)
    T = 0                     for -P/k - g < e < -P/k    (free play)
    T = k (e + P/k + g)       for e <= -P/k - g          (pushing contact)

+T_j acts on link j, -T_j on link j+1. The drive pushes link 0 with k_d (z - x_0). Damping is
either (a) a matrix C on y' (always acting, as the linear model's) or (b) a Kelvin-Voigt dashpot
beta k_j on every span while it is in contact (pulling or pushing) and beta k_d on the drive, or
both. Friction -F_c tanh(x'_i / v_s) on every link. An optional idler tensioner (carriage u, rate
k_t, mass m_t, damper c_t) lengthens the idler span's stretch to e_s + 2u and obeys
m_t u'' = 2P - k_t u - c_t u' - 2 T_s, so its static state is u = 0.

Method: scipy.integrate.solve_ivp (DOP853 by default) at tight tolerance, with every contact change
located as an event and the integration restarted there. Within one integration segment every span
keeps its contact mode and the force law of that mode (extended past the mode's edge), so the
right-hand side is smooth and the integrator keeps its order; one event function (the smallest
distance of any span that can change mode to the edge of its mode's interval of stretch, falling
through zero) ends the segment, the crossing span takes its new mode, and the integration restarts
from the located state. Segments also end at every output time, where the held cam input's
acceleration has its kinks. No step straddles a kink of the force law or of the input.

Cam input (`cam_input`). The relative motion y is forced by -m z''(t):
- "sampled" (default): as dynamics.solvers.simulate does it, so that it and any solver built the same way
  can be compared with this reference to its tolerance: z'' is the cam's acceleration sampled at
  t_eval_s and linear in between (first-order hold), the friction sees z' linear between the cam's
  velocity samples, and the absolute motion reported is the cam's own s, v, a plus y. Those two
  inputs are not each other's integral (they differ by the hold's error), so the energy balance
  holds only to that error here (about 1e-2 relative at one-degree samples).
- "held": the consistent input of a cam whose acceleration is that first-order hold: z' and z its
  exact integrals from the cam's values at t_eval_s[0] (`HeldCam`), used for friction, energy and
  the absolute motion. The energy balance holds to the integration tolerance. The held input drifts
  from the cam by the hold's error: 6.5e-4 m and 1e-2 m/s after 180 degrees of the modified sine
  at one-degree samples, 0.6 m/s for the simple-harmonic law, whose acceleration jumps.
- "exact": cam.svaj(t) at every evaluation (about 0.2 ms each for a CamProgram: slow, for short
  windows): the response to the cam itself, to measure the sampling error of the other two.

The energy terms are integrated with the motion (extra states) from the same forces: the work the
cam does on the chain (through the drive spring and dashpot and through a damping matrix's coupling
to the cam frame, -z' 1^T C y'), the energy the dampers dissipate (y'^T C y', beta k e'^2 in contact,
beta k_d y_0'^2, c_t u'^2) and friction's. Stored energy is kinetic (absolute velocities; the
carriage's) plus the span springs measured from their unstressed length (the integral of T de,
continuous and piecewise quadratic), the drive spring and the tensioner's spring with its preload
force (1/2 k_t u^2 - 2P u). cam work = dissipated + change of stored, to the integration tolerance.

Limits: a span that enters and leaves a mode within one integrator step (a graze) is not seen; the
steps at rtol 1e-10 are far shorter than any contact. A contact that chatters (an inelastic span
settling onto its stop through ever shorter bounces) would need infinitely many events: the run
stops with an error after `max_events`.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from dynamics.errors import DynamicsError, SolverFailedError
from dynamics.response.metrics import matlab_round

PULLING, FREE, PUSHING = 1, 0, -1
CAM_INPUTS = ("sampled", "held", "exact")
METHODS = ("DOP853", "RK45", "Radau", "BDF", "LSODA")
_EPS = np.finfo(float).eps
# Default absolute tolerance on displacements, per unit rtol: the scale of the contact stretches
# (P/k is 24 um for the default chain, pin clearances are tens of um).
ATOL_LENGTH_SCALE_M = 1e-5
# Default budget of contact changes: 10x the most any window here locates (about 2000, 85 links over
# 180 degrees). A restart costs 4-6 ms (10 to 85 links, measured under load), so a chattering run is
# refused after 1.5-2 minutes; a budget of 100 000 would run 7-10 minutes first, like a hang.
MAX_EVENTS = 20_000


class HeldCam:
    """A cam input whose acceleration is `cam`'s sampled at t_s and linear in between (first-order
    hold), its velocity and displacement the exact integrals from the cam's values at t_s[0].
    Duck type of the cams (`svaj`); defined on [t_s[0], t_s[-1]] (extrapolated by the end pieces)."""

    def __init__(self, cam, t_s):
        t = np.asarray(t_s, dtype=float)
        if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0.0):
            raise DynamicsError("t_s: expected at least two strictly increasing sample times")
        s, v, a, _ = (np.asarray(q, dtype=float) for q in cam.svaj(t))
        h = np.diff(t)
        jerk = np.diff(a) / h
        v_start = v[0] + np.concatenate([[0.0], np.cumsum(a[:-1] * h + jerk * h**2 / 2)])
        s_start = s[0] + np.concatenate([[0.0], np.cumsum(v_start[:-1] * h + a[:-1] * h**2 / 2 + jerk * h**3 / 6)])
        self.t_s = t
        self._t_list = t.tolist()
        # per interval: start time, z, z', z'' at its start and the constant jerk
        self._pieces = np.column_stack([t[:-1], s_start[:-1], v_start[:-1], a[:-1], jerk])
        self._piece_list = [tuple(row) for row in self._pieces.tolist()]
        self.period_s = None
        self.advance_m = None

    @property
    def interval_start_velocity_m_s(self) -> np.ndarray:
        """z' at the start of every interval (t_s[i] to t_s[i + 1])."""
        return self._pieces[:, 2]

    def _index(self, t: float) -> int:
        return min(max(bisect.bisect_right(self._t_list, t) - 1, 0), len(self._piece_list) - 1)

    def svaj(self, t_s):
        t = np.asarray(t_s, dtype=float)
        i = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, len(self._piece_list) - 1)
        t0, s0, v0, a0, j = (self._pieces[i, c] for c in range(5))
        tau = t - t0
        return (
            s0 + v0 * tau + a0 * tau**2 / 2 + j * tau**3 / 6,
            v0 + a0 * tau + j * tau**2 / 2,
            a0 + j * tau,
            j + 0.0 * tau,
        )

    def z_and_zdot(self, t: float) -> tuple[float, float]:
        """Displacement and velocity at one time, without numpy overhead (for per-step callbacks)."""
        t0, s0, v0, a0, j = self._piece_list[self._index(t)]
        tau = t - t0
        return s0 + tau * (v0 + tau * (a0 / 2 + tau * j / 6)), v0 + tau * (a0 + tau * j / 2)


@dataclass(frozen=True)
class ReferenceResponse:
    """The reference solution at the output times. Link columns are links 0..N-1 (0 = driven link);
    span columns are spans 0..N-1 (span j joins link j to link j+1, the last closes the loop)."""

    t_s: np.ndarray  # (m,)
    x_m: np.ndarray  # (m, N) absolute: the cam input z plus y
    v_m_s: np.ndarray
    a_m_s2: np.ndarray
    y_m: np.ndarray  # (m, N) relative to the cam input, y = x - z 1
    ydot_m_s: np.ndarray
    yddot_m_s2: np.ndarray
    z_m: np.ndarray  # (m,) the cam input: the cam's own (sampled, exact) or the held input (held)
    zdot_m_s: np.ndarray
    zddot_m_s2: np.ndarray
    tension_N: np.ndarray  # (m, N) span force, tension positive (Kelvin-Voigt dashpot included in contact)
    contact_mode: np.ndarray  # (m, N) int8: 1 pulling contact, 0 free play, -1 pushing contact
    drive_force_N: np.ndarray  # (m,) on link 0, k_d (z - x_0) (+ its dashpot under law (b))
    tensioner_u_m: np.ndarray  # (m,) carriage displacement (zeros without a tensioner)
    n_contact_changes: int  # span mode changes in the window (each located as an event)
    contact_change_times_s: np.ndarray  # (n_contact_changes,) one entry per span that changed mode
    cam_work_J: np.ndarray  # (m,) work done by the cam on the chain since t_s[0]
    damper_dissipation_J: np.ndarray  # (m,) dissipated by dampers since t_s[0]
    friction_dissipation_J: np.ndarray  # (m,) dissipated by friction since t_s[0]
    stored_energy_J: np.ndarray  # (m,) kinetic + elastic (springs from their unstressed length)
    method: str
    n_function_evaluations: int

    @property
    def energy_balance_residual_J(self) -> np.ndarray:
        """cam work - (dissipated + change of stored energy): zero to the integration tolerance with
        cam_input "held" or "exact"; with "sampled", up to the sampled input's inconsistency."""
        return self.cam_work_J - (
            self.damper_dissipation_J + self.friction_dissipation_J + self.stored_energy_J - self.stored_energy_J[0]
        )


def idler_span_index(n_links: int) -> int:
    """0-based index of the span at the idler end: joins 1-based links round(N/2) and round(N/2) + 1
    (MATLAB rounding, as the idler-end station of dynamics.response.metrics)."""
    return int(matlab_round(n_links / 2)) - 1


def reference_response(
    *,
    n_links: int,
    link_mass_kg,
    stiffness_N_per_m,
    drive_stiffness_N_per_m: float,
    preload_N: float,
    clearance_m,
    cam,
    t_eval_s,
    damping_matrix=None,
    span_damping_beta_s: float = 0.0,
    friction_force_N=0.0,
    friction_velocity_scale_m_s: float = 5e-3,
    tensioner=None,
    idler_span: int | None = None,
    cam_input: str = "sampled",
    y0=None,
    ydot0=None,
    u0_m: float = 0.0,
    udot0_m_s: float = 0.0,
    method: str = "DOP853",
    rtol: float = 1e-10,
    atol: float | None = None,
    max_step: float = np.inf,
    max_events: int = MAX_EVENTS,
) -> ReferenceResponse:
    """The clearance chain's response at t_eval_s, from the state (y0, ydot0) at t_eval_s[0].

    Per-link inputs (link_mass_kg, friction_force_N = mu m g) and per-span inputs
    (stiffness_N_per_m; clearance_m, metres, inf = a span that can only pull) are scalars or arrays of
    length n_links; a span of stiffness 0 carries the constant force P. damping_matrix: (N, N), law
    (a), acting on y'. span_damping_beta_s: law (b). tensioner: None (rigid idler) or
    (rate_N_per_m, mass_kg, damping_N_s_per_m), a tuple or an object with those attributes; it sits
    in span `idler_span` (default `idler_span_index(n_links)`). y0, ydot0: motion relative to the
    cam (default: every link at the cam's position, motionless: y = 0, y' = -z'(t0)).
    cam_input: "sampled", "held" or "exact" (module docstring). method: a solve_ivp method
    (DOP853 by default, the fastest here: Radau took 20x longer with a 1e11 N/m tensioner).
    atol: on displacements in metres (default rtol x ATOL_LENGTH_SCALE_M, 10 um); velocities get
    atol times the chain's highest frequency bound. max_events: contact changes allowed before the
    run stops with a one-line error (chatter; `MAX_EVENTS` by default)."""
    model = _Model.build(
        n_links,
        link_mass_kg,
        stiffness_N_per_m,
        drive_stiffness_N_per_m,
        preload_N,
        clearance_m,
        damping_matrix,
        span_damping_beta_s,
        friction_force_N,
        friction_velocity_scale_m_s,
        tensioner,
        idler_span,
    )
    t = np.asarray(t_eval_s, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
        raise DynamicsError("t_eval_s: expected at least two strictly increasing finite times")
    if cam_input not in CAM_INPUTS:
        raise DynamicsError(f"cam_input: expected one of {', '.join(CAM_INPUTS)}, got {cam_input!r}")
    if method not in METHODS:
        raise DynamicsError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    if not (np.isfinite(rtol) and 0 < rtol < 1e-2):
        raise DynamicsError(f"rtol: expected 0 < rtol < 1e-2, got {rtol!r}")
    if not (isinstance(max_events, (int, np.integer)) and max_events >= 0):
        raise DynamicsError(f"max_events: expected an integer >= 0, got {max_events!r}")
    if cam_input == "exact":
        rates = _ExactRates(cam)
        z_out, zd_out, zdd_out, _ = (np.asarray(q, dtype=float) for q in cam.svaj(t))
    else:
        held = HeldCam(cam, t) if cam_input == "held" else None
        z_out, zd_out, zdd_out, _ = (np.asarray(q, dtype=float) for q in (held or cam).svaj(t))
        rates = _SampledRates(t, zd_out, zdd_out, held)
    n = model.n
    y_start = np.zeros(n) if y0 is None else _vector("y0", y0, n)
    yd_start = np.full(n, -zd_out[0]) if ydot0 is None else _vector("ydot0", ydot0, n)
    state = np.concatenate([y_start, yd_start, [u0_m, udot0_m_s] if model.has_tensioner else [], [0.0, 0.0, 0.0]])
    if not np.all(np.isfinite(state)):
        raise DynamicsError("y0, ydot0, u0_m, udot0_m_s: expected finite values")
    integrator = _Integrator(model, rates, method, rtol, atol, max_step, max_events)
    return integrator.run(t, state, z_out, zd_out, zdd_out)


@dataclass(frozen=True)
class _Model:
    n: int
    mass: np.ndarray
    k: np.ndarray
    kd: float
    preload: float
    gap: np.ndarray
    damping: np.ndarray | None
    beta: float
    coulomb: np.ndarray
    v_scale: float
    has_tensioner: bool
    k_t: float
    m_t: float
    c_t: float
    idler: int

    @staticmethod
    def build(n, mass, k, kd, preload, gap, damping, beta, coulomb, v_scale, tensioner, idler) -> _Model:
        if not (isinstance(n, (int, np.integer)) and n >= 2):
            raise DynamicsError(f"n_links: expected an integer >= 2, got {n!r}")
        mass = _per_item("link_mass_kg", mass, n)
        if np.any(mass <= 0):
            raise DynamicsError("link_mass_kg: expected masses > 0 kg")
        k = _per_item("stiffness_N_per_m", k, n)
        gap = _per_item("clearance_m", gap, n, allow_inf=True)
        coulomb = _per_item("friction_force_N", coulomb, n)
        if not (np.isfinite(kd) and kd >= 0):
            raise DynamicsError(f"drive_stiffness_N_per_m: expected a finite value >= 0, got {kd!r}")
        if not (np.isfinite(preload) and preload >= 0):
            raise DynamicsError(f"preload_N: expected a finite value >= 0, got {preload!r}")
        if not (np.isfinite(beta) and beta >= 0):
            raise DynamicsError(f"span_damping_beta_s: expected a finite value >= 0 s, got {beta!r}")
        if not (np.isfinite(v_scale) and v_scale > 0):
            raise DynamicsError(f"friction_velocity_scale_m_s: expected a value > 0, got {v_scale!r}")
        if damping is not None:
            damping = np.array(damping, dtype=float)
            if damping.shape != (n, n) or not np.all(np.isfinite(damping)):
                raise DynamicsError(f"damping_matrix: expected a finite ({n}, {n}) array, got shape {damping.shape}")
        k_t = m_t = c_t = 0.0
        if tensioner is not None:
            k_t, m_t, c_t = _tensioner_values(tensioner)
        idler = idler_span_index(n) if idler is None else int(idler)
        if not 0 <= idler < n:
            raise DynamicsError(f"idler_span: expected a span index in 0..{n - 1}, got {idler!r}")
        return _Model(
            n,
            mass,
            k,
            float(kd),
            float(preload),
            gap,
            damping,
            float(beta),
            coulomb,
            float(v_scale),
            tensioner is not None,
            k_t,
            m_t,
            c_t,
            idler,
        )

    @property
    def pull_edge(self) -> np.ndarray:
        """Stretch at which each span leaves pulling contact, -P/k (-inf for a constant-force span)."""
        with np.errstate(divide="ignore"):
            return np.where(self.k > 0, -self.preload / np.where(self.k > 0, self.k, 1.0), -np.inf)

    @property
    def switchable(self) -> np.ndarray:
        """Spans whose force law has kinks: stiffness > 0 and free play > 0."""
        return (self.k > 0) & (self.gap > 0)

    def span_energy_J(self, e: np.ndarray) -> np.ndarray:
        """Elastic energy of every span from its unstressed length: the integral of T de."""
        pull, push = self.pull_edge, self.pull_edge - self.gap
        k = self.k
        safe_k = np.where(k > 0, k, 1.0)
        pulling = np.where(k > 0, (self.preload + k * e) ** 2 / (2 * safe_k), self.preload * e)
        pushing = np.where(np.isfinite(push), 0.5 * k * (e - np.where(np.isfinite(push), push, 0.0)) ** 2, 0.0)
        return np.where(e >= pull, pulling, np.where(e <= push, pushing, 0.0))


class _SampledRates:
    """z'(t), z''(t) between output samples: z'' linear between the samples (first-order hold); z'
    its integral (`held` given: that HeldCam's) or linear between the velocity samples."""

    def __init__(self, t: np.ndarray, v: np.ndarray, a: np.ndarray, held: HeldCam | None):
        h = np.diff(t)
        jerk = np.diff(a) / h
        if held is not None:
            v0, c1, c2 = held.interval_start_velocity_m_s, a[:-1], jerk / 2
        else:
            v0, c1, c2 = v[:-1], np.diff(v) / h, np.zeros_like(h)
        self.rows = [tuple(r) for r in np.column_stack([t[:-1], v0, c1, c2, a[:-1], jerk]).tolist()]
        self.row = self.rows[0]

    def select(self, i: int) -> None:
        """Evaluate in interval i (t[i] to t[i + 1]) from now on."""
        self.row = self.rows[min(i, len(self.rows) - 1)]

    def __call__(self, t: float) -> tuple[float, float]:
        t0, v0, c1, c2, a0, j = self.row
        tau = t - t0
        return v0 + tau * (c1 + tau * c2), a0 + tau * j


class _ExactRates:
    """z'(t), z''(t) of the cam itself."""

    def __init__(self, cam):
        self.cam = cam

    def select(self, i: int) -> None:
        pass

    def __call__(self, t: float) -> tuple[float, float]:
        _, v, a, _ = self.cam.svaj(np.array([t]))
        return float(v[0]), float(a[0])


class _Integrator:
    """The segment loop: solve_ivp between output times and contact changes."""

    def __init__(self, model: _Model, cam_rates, method, rtol, atol, max_step, max_events):
        self.model, self.cam_rates = model, cam_rates
        self.method, self.rtol, self.max_step, self.max_events = method, rtol, max_step, max_events
        n = model.n
        self.nxt = np.r_[1:n, 0]
        self.prv = np.r_[n - 1, 0 : n - 1]
        self.pull = model.pull_edge
        self.push = self.pull - model.gap
        self.switch_idx = np.flatnonzero(model.switchable)
        self.col_sum = None if model.damping is None else model.damping.sum(axis=0)
        self.inv_mass = 1.0 / model.mass
        self.nfev = 0
        self.atol = self._atol(atol)
        # a span's law is continuous at its edges: following the old law this far past the edge
        # changes the force by k * margin (1e-6 N at k = 1e8, margin 1e-14 m)
        self.edge_margin = 10.0 * float(self.atol[0])

    def _atol(self, atol) -> np.ndarray:
        m = self.model
        if atol is None:
            atol = self.rtol * ATOL_LENGTH_SCALE_M
        if not (np.isfinite(atol) and atol > 0):
            raise DynamicsError(f"atol: expected a positive tolerance in metres, got {atol!r}")
        omega = np.sqrt((4 * float(m.k.max()) + m.kd + (m.k_t if m.has_tensioner else 0.0)) / float(m.mass.min()))
        omega = max(omega, 1.0)
        parts = [np.full(m.n, atol), np.full(m.n, atol * omega)]
        if m.has_tensioner:
            parts.append([atol, atol * max(omega, np.sqrt(m.k_t / m.m_t))])
        energy = atol * max(float(m.k.max()), m.kd, 1.0) * atol / self.rtol * m.n
        parts.append(np.full(3, energy))
        return np.concatenate(parts)

    # the model's pieces --------------------------------------------------------------------------

    def stretch(self, s: np.ndarray):
        n = self.model.n
        y, yd = s[:n], s[n : 2 * n]
        e = y[self.nxt] - y
        ed = yd[self.nxt] - yd
        if self.model.has_tensioner:
            e[self.model.idler] += 2 * s[2 * n]
            ed[self.model.idler] += 2 * s[2 * n + 1]
        return e, ed

    def set_modes(self, modes: np.ndarray) -> None:
        m = self.model
        self.modes = modes
        self.t_offset = np.where(
            modes == PULLING,
            m.preload,
            np.where(modes == PUSHING, m.preload + m.k * np.where(np.isfinite(m.gap), m.gap, 0.0), 0.0),
        )
        self.t_slope = np.where(modes == FREE, 0.0, m.k)
        sw = self.switch_idx
        self.lower = np.where(modes[sw] == PULLING, self.pull[sw], np.where(modes[sw] == FREE, self.push[sw], -np.inf))
        self.upper = np.where(modes[sw] == PULLING, np.inf, np.where(modes[sw] == FREE, self.pull[sw], self.push[sw]))

    def classify(self, e: np.ndarray, ed: np.ndarray) -> np.ndarray:
        """Contact mode of every span from its stretch; on an edge, the side it is moving to."""
        pulling = (e > self.pull) | ((e == self.pull) & (ed >= 0))
        pushing = (e < self.push) | ((e == self.push) & (ed <= 0))
        return np.where(pulling, PULLING, np.where(pushing, PUSHING, FREE)).astype(np.int8)

    def forces(self, t: float, s: np.ndarray):
        """Span forces, link accelerations y'', carriage acceleration and the energy rates."""
        m = self.model
        n = m.n
        self.nfev += 1
        zd, zdd = self.cam_rates(t)
        y, yd = s[:n], s[n : 2 * n]
        e, ed = self.stretch(s)
        tension = self.t_offset + self.t_slope * e
        dissipation = 0.0
        if m.beta:
            dash = m.beta * self.t_slope * ed
            tension = tension + dash
            dissipation += float(dash @ ed) + m.beta * m.kd * yd[0] ** 2
        f = tension - tension[self.prv]
        drive = -m.kd * y[0] - m.beta * m.kd * yd[0]
        f[0] += drive
        cam_power = zd * drive
        if m.damping is not None:
            cyd = m.damping @ yd
            f -= cyd
            cam_power -= zd * float(self.col_sum @ yd)
            dissipation += float(yd @ cyd)
        friction_loss = 0.0
        if np.any(m.coulomb):
            v_abs = zd + yd
            ff = -m.coulomb * np.tanh(v_abs / m.v_scale)
            f += ff
            friction_loss = -float(v_abs @ ff)
        ydd = f * self.inv_mass - zdd
        udd = None
        if m.has_tensioner:
            u, ud = s[2 * n], s[2 * n + 1]
            udd = (2 * m.preload - m.k_t * u - m.c_t * ud - 2 * tension[m.idler]) / m.m_t
            dissipation += m.c_t * ud**2
        return tension, drive, ydd, udd, (cam_power, dissipation, friction_loss)

    def rhs(self, t: float, s: np.ndarray) -> np.ndarray:
        n = self.model.n
        _, _, ydd, udd, rates = self.forces(t, s)
        parts = [s[n : 2 * n], ydd]
        if udd is not None:
            parts.append([s[2 * n + 1], udd])
        parts.append(rates)
        return np.concatenate(parts)

    def distance_to_edge(self, t: float, s: np.ndarray) -> float:
        """Smallest distance (m) of a span that can change mode to the edge of its mode's interval,
        plus the hysteresis `edge_margin`: a span switches `edge_margin` past the edge, so that after
        the restart every span is inside its interval by at least the root finder's error and the
        event function starts positive (it must, to see the next crossing fall through zero)."""
        e, _ = self.stretch(s)
        es = e[self.switch_idx]
        return float(np.min(np.minimum(es - self.lower, self.upper - es))) + self.edge_margin

    def stored_energy(self, s: np.ndarray, zd: float) -> float:
        m = self.model
        n = m.n
        e, _ = self.stretch(s)
        v_abs = zd + s[n : 2 * n]
        energy = 0.5 * float(m.mass @ v_abs**2) + float(m.span_energy_J(e).sum()) + 0.5 * m.kd * s[0] ** 2
        if m.has_tensioner:
            u, ud = s[2 * n], s[2 * n + 1]
            energy += 0.5 * m.m_t * ud**2 + 0.5 * m.k_t * u**2 - 2 * m.preload * u
        return energy

    # the loop -------------------------------------------------------------------------------------

    def switch(self, s: np.ndarray) -> int:
        """The span that reached an edge takes the mode beyond it; any other found outside its
        interval (a simultaneous crossing) takes the mode its stretch is in. Returns how many
        spans changed mode."""
        e, ed = self.stretch(s)
        sw = self.switch_idx
        es = e[sw]
        dist = np.minimum(es - self.lower, self.upper - es)
        modes = self.modes.copy()
        i = int(np.argmin(dist))
        j = sw[i]
        if modes[j] != FREE:
            new = FREE
        else:
            new = PULLING if abs(es[i] - self.pull[j]) <= abs(es[i] - self.push[j]) else PUSHING
        others = sw[(dist < -self.edge_margin) & (np.arange(sw.size) != i)]
        modes[others] = self.classify(e, ed)[others]
        modes[j] = new
        changed = int(np.count_nonzero(modes != self.modes))
        self.set_modes(modes)
        return changed

    def run(self, t: np.ndarray, state: np.ndarray, z_out, zd_out, zdd_out) -> ReferenceResponse:
        m = self.model
        n = m.n
        e0, ed0 = self.stretch(state)
        self.set_modes(self.classify(e0, ed0))

        def edge(t_s: float, s: np.ndarray) -> float:
            return self.distance_to_edge(t_s, s)

        edge.terminal = True
        edge.direction = -1  # leaving the mode's interval: the distance falls through zero
        events = [edge] if self.switch_idx.size else None
        out = np.empty((t.size, state.size))
        ydd_out = np.empty((t.size, n))
        tension_out = np.empty((t.size, n))
        modes_out = np.empty((t.size, n), dtype=np.int8)
        drive_out = np.empty(t.size)
        change_times: list[float] = []
        step = None

        def record(i: int, s: np.ndarray) -> None:
            self.cam_rates.select(i)
            tension, drive, ydd, _, _ = self.forces(t[i], s)
            # spans without free play keep one law throughout: their mode is read off their stretch
            modes = self.classify(*self.stretch(s))
            modes[self.switch_idx] = self.modes[self.switch_idx]
            out[i], ydd_out[i], tension_out[i], modes_out[i], drive_out[i] = s, ydd, tension, modes, drive

        record(0, state)
        for i in range(t.size - 1):
            self.cam_rates.select(i)
            t_now, t_end = t[i], t[i + 1]
            while True:
                if t_end - t_now <= 4 * _EPS * max(abs(t_end), 1.0):
                    break
                first = None if step is None else min(step, t_end - t_now)
                sol = solve_ivp(
                    self.rhs,
                    (t_now, t_end),
                    state,
                    method=self.method,
                    rtol=self.rtol,
                    atol=self.atol,
                    max_step=self.max_step,
                    events=events,
                    first_step=first,
                )
                if sol.status < 0:
                    raise SolverFailedError(f"clearance reference ({self.method}): {sol.message} at t = {t_now:.9g} s")
                if sol.t.size >= 3:
                    step = float(sol.t[-2] - sol.t[-3])
                if sol.status == 1:
                    t_now = float(sol.t_events[0][0])
                    state = sol.y_events[0][0].copy()
                    change_times.extend([t_now] * self.switch(state))
                    if len(change_times) > self.max_events:
                        raise SolverFailedError(
                            f"clearance reference: more than {self.max_events} contact changes (max_events) by "
                            f"t = {t_now:.9g} s, each one a restart of solve_ivp (contacts chattering?): raise "
                            "max_events, or use the fast integrator dynamics.solvers.clearance_verlet, whose cost "
                            "does not grow with contact changes"
                        )
                    continue
                state = sol.y[:, -1]
                break
            record(i + 1, state)

        y, yd = out[:, :n], out[:, n : 2 * n]
        stored = np.array([self.stored_energy(out[i], zd_out[i]) for i in range(t.size)])
        return ReferenceResponse(
            t_s=t,
            x_m=z_out[:, None] + y,
            v_m_s=zd_out[:, None] + yd,
            a_m_s2=zdd_out[:, None] + ydd_out,
            y_m=y,
            ydot_m_s=yd,
            yddot_m_s2=ydd_out,
            z_m=z_out,
            zdot_m_s=zd_out,
            zddot_m_s2=zdd_out,
            tension_N=tension_out,
            contact_mode=modes_out,
            drive_force_N=drive_out,
            tensioner_u_m=out[:, 2 * n] if m.has_tensioner else np.zeros(t.size),
            n_contact_changes=len(change_times),
            contact_change_times_s=np.array(change_times),
            cam_work_J=out[:, -3],
            damper_dissipation_J=out[:, -2],
            friction_dissipation_J=out[:, -1],
            stored_energy_J=stored,
            method=f"solve_ivp {self.method} rtol {self.rtol:g} with contact events",
            n_function_evaluations=self.nfev,
        )


def _per_item(name: str, value, n: int, *, allow_inf: bool = False) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise DynamicsError(f"{name}: expected a scalar or {n} values (one per link/span), got shape {arr.shape}")
    ok = ~np.isnan(arr) & (arr >= 0) & (np.isfinite(arr) | allow_inf)
    if not np.all(ok):
        bound = "values >= 0 (inf allowed)" if allow_inf else "finite values >= 0"
        raise DynamicsError(f"{name}: expected {bound}, got {value!r}")
    return arr


def _vector(name: str, value, n: int) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (n,):
        raise DynamicsError(f"{name}: expected {n} values (one per link), got shape {arr.shape}")
    return arr


def _tensioner_values(tensioner) -> tuple[float, float, float]:
    if all(hasattr(tensioner, a) for a in ("rate_N_per_m", "mass_kg", "damping_N_s_per_m")):
        values = (tensioner.rate_N_per_m, tensioner.mass_kg, tensioner.damping_N_s_per_m)
    else:
        try:
            values = tuple(float(v) for v in tensioner)
        except (TypeError, ValueError):
            values = ()
        if len(values) != 3:
            raise DynamicsError(f"tensioner: expected (rate_N_per_m, mass_kg, damping_N_s_per_m), got {tensioner!r}")
    k_t, m_t, c_t = (float(v) for v in values)
    if not (np.isfinite(k_t) and k_t >= 0 and np.isfinite(m_t) and m_t > 0 and np.isfinite(c_t) and c_t >= 0):
        raise DynamicsError(f"tensioner: expected rate >= 0 N/m, mass > 0 kg, damping >= 0 N*s/m, got {values!r}")
    return k_t, m_t, c_t
