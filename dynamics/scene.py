"""Which chain model a scene needs, and the clearance chain's response (periodic or from rest).

`simulate_chain(model, cam, t_eval_s, choice="auto")` always solves the linear chain first (exact,
cheap): it gives the preload that would keep every span in pulling contact (the linear motion does
not depend on the preload, so that preload is P - min T_linear), and it decides the model:

- "linear": asked for; or, with "auto", pin clearance 0 (the clearance law is then the linear law
  exactly) or a linear solution that never leaves pulling contact (min tension >= 0 at every output
  sample: free play is never entered). Its response is the exact linear one, returned as is.
- "clearance": asked for; or, with "auto", the linear solution leaves pulling contact somewhere, or
  an idler tensioner is modelled (only the clearance model carries it). Solved by the explicit
  integrator dynamics.solvers.clearance_verlet, by default with its `default_predictor` at its
  `default_safety` (the global law: "ab2" at 0.31 of its stability limit; the 32 station metrics
  within 1.5e-3 of converged on the default scene, 1.6e-2 and 2.1e-2 on two others:
  benchmarks/bench_accuracy.py). With `accuracy` the step is then halved until the station metrics
  change by at most that (`_controlled`).

Periodic steady state of the clearance chain: started from the linear chain's periodic state, the
one-period map (the chain stepped one cam period) is iterated until the state at the period's start
changes by less than `tol` over one period (relative to the largest |y| and |y'| over the period),
the iteration accelerated (dynamics.solvers.shooting: Anderson acceleration, with the linear chain's
Newton step on its slowly decaying modes), so that long chains, whose low modes lose little per
period, settle in a few periods. If it does not settle within `max_cycles` periods, the period ends
of its final plain stretch are searched for a repeat after k = 2..MAX_SUBHARMONIC periods (a
subharmonic response: impacting systems have them); if none repeats, no periodic state is found and
the response is reported as what it is, the motion after `max_cycles` periods, with a statement
saying so. A steady state is never claimed unless the residual test passed.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, fields, replace
from enum import StrEnum
from typing import NamedTuple

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.models.clearance import ClearanceChain, Tensioner
from dynamics.models.layout import LINK_DRIVE, MachineLayout
from dynamics.options import LINEAR_ELASTIC_STRAIN_LIMIT, MODEL_CHOICES
from dynamics.response.fidelity import relative_change
from dynamics.response.metrics import link_metrics, station_links
from dynamics.solvers import cache, ring_on_topology, shooting
from dynamics.solvers import clearance_verlet as verlet
from dynamics.solvers._common import serial_blas
from dynamics.solvers.simulate import ChainResponse, SlackChainWarning, simulate

MAX_SUBHARMONIC = 6
DEFAULT_TOL = 1e-6
DEFAULT_MAX_CYCLES = 60
# simulate_chain(accuracy=...): the clearance chain's step is halved until the station metrics'
# estimated relative error is within it, at most MAX_STEP_DOUBLINGS times (16x the stability-set
# steps). Not by default: 1e-3 costs the default dynamics stage about 13x on the wheels (13.2 s
# against 0.98 s) and 2-5x on the single-link drive (docs/physics.md, "Default accuracy";
# docs/performance.md, "Default accuracy of the clearance chain"); --tolerance asks for it.
MAX_STEP_DOUBLINGS = 4


class ChainModelKind(StrEnum):
    """Which chain model produced a response."""

    LINEAR = "linear"
    CLEARANCE = "clearance"


class Validity(StrEnum):
    """Whether a response holds for its scene, as data for whoever reports it."""

    VALID = "valid"
    # the linear response standing in where the clearance model was needed: it does not hold where a
    # span's tension goes below 0. No model choice gives it since the clearance chain runs at any
    # length (issue 24); kept as the reports' vocabulary (reporting.sections)
    NOT_VALID_WHERE_TENSION_NEGATIVE = "not valid where tension < 0"
    # the linear model's own numbers (its minimum tension, the preload for full contact) where it
    # deforms a span beyond any metal link's elastic range (LinearModelValidity)
    OUTSIDE_LINEAR_MODEL = "outside the linear model"


class ModelChoice(NamedTuple):
    model: ChainModelKind
    reason: str  # in words, for the report; no numbers, so equal reasons group
    validity: Validity


@dataclass(frozen=True)
class Scene:
    """The explicit description of one run's chain beyond its linear model (dynamics.models.chain.ChainModel):
    the pin free play, the span damping law and the tensioner, which model to run and how."""

    pin_clearance_m: float  # axial free play per span; inf: a chain that can only pull
    span_damping: str  # one of dynamics.models.clearance.SPAN_DAMPING_LAWS
    tensioner: Tensioner | None  # None: a rigid idler
    model: str  # one of MODEL_CHOICES
    steady_state: bool  # periodic steady state (False: from rest)
    solver: str  # the linear chain's method (dynamics.solvers.METHODS)
    layout: MachineLayout = LINK_DRIVE  # how the chain is driven and carried (dynamics.models.layout)
    accuracy: float | None = None  # the clearance chain's step error target (simulate_chain; None: stability-set step)


@dataclass(frozen=True)
class SteadyState:
    """How the clearance chain's periodic state was found (or not)."""

    found: bool
    period_cycles: int | None  # 1: periodic with the cam; k > 1: subharmonic of period k cam cycles; None: none
    # the cam (index) cycles the steady state's search stepped before the output window, on the model
    # that ran, at every step it searched at (a long chain's coarse and fine searches); under the step
    # control (`accuracy`, --tolerance) the sum over its levels. Not counted: the linear model's cycles
    # that chose the model, and the machine's SETTLE_CYCLES plain cycles at the window's step
    cycles: int
    residual: float  # last change per period (relative), or per k periods for a subharmonic
    statement: str


@dataclass(frozen=True)
class ImpactStatistics:
    """The impacts themselves over the output window (SI), beside the peak span force, which is mostly
    the chain's inertial load. An impact is a span entering contact from free play; m_eff = m / 2 (two
    equal links closing on one span), t_c = pi sqrt(m_eff / k) the impact's duration (half a period of
    their contact oscillation). All zero when there is no impact (and for the linear model).

    - closing speed: |e'| of the span at the instant it enters contact (its two ends' relative speed);
      max and median / 90th percentile over the window's impacts. An undamped contact's force peaks
      at sqrt(k m_eff) times it.
    - force spike: the largest |span force| within t_c of an impact. The span's force just before
      contact is zero (it was in free play), so this is the force the impact itself builds before the
      contact's first half-oscillation ends; later in the contact the span carries the chain's load.
    - impact energy per cycle: sum over the impacts of the approach's kinetic energy 1/2 m_eff v^2
      (what the contacts must absorb and give back or lose), per cam cycle.
    - dissipated per cycle: the energy the contacts' own losses take out: the Kelvin-Voigt span
      dashpots' work over the contacts begun by impacts, per cam cycle (per impact 1/2 m_eff v^2
      (1 - exp(-2 pi zeta / sqrt(1 - zeta^2))) for the two-mass contact). The global damping law's
      contact is lossless (its losses are spread over the chain's motion, not in the pin joints):
      0 there, and the impact energy goes into the chain's vibration, which that law damps."""

    closing_speed_max_m_s: float = 0.0
    closing_speed_median_m_s: float = 0.0
    closing_speed_p90_m_s: float = 0.0
    force_spike_N: float = 0.0
    energy_per_cycle_J: float = 0.0
    dissipated_per_cycle_J: float = 0.0


def impact_statistics(run, cycles: float) -> ImpactStatistics:
    """ImpactStatistics of an integrator's run over `cycles` cam cycles: a clearance_verlet.Run, or
    the machine's window of index cycles (dynamics.machine_scene), which carries the same fields."""
    speeds = run.impact_speeds_m_s
    median, p90 = np.percentile(speeds, [50.0, 90.0]) if speeds.size else (0.0, 0.0)
    return ImpactStatistics(
        run.impact_max_speed_m_s,
        float(median),
        float(p90),
        run.impact_force_spike_N,
        float(run.impact_kinetic_energy_J / cycles),
        float(run.impact_dissipated_J / cycles),
    )


@dataclass(frozen=True)
class LowestMode:
    """The chain's lowest natural mode (full contact, the model as it ran) under the run's damping law,
    against the harmonics of the cam's cycle rate (SI). The cam drives every harmonic n / cycle_s; the
    mode nearest one of them takes its share of that harmonic amplified by `amplification`, the linear
    dynamic amplification 1 / sqrt((1 - r^2)^2 + (2 zeta r)^2), r = n f_cycle / f_1 (1: the force as
    if applied slowly). Under the Kelvin-Voigt law zeta_1 = beta omega_1 / 2 is tiny (0.0032 on the
    default chain) and a harmonic near f_1 builds a resonance that the free play can move onto it (a
    softening law); `decay_per_cycle` = exp(-zeta omega_1 T) is also how slowly a search for the
    periodic state converges (docs/physics.md, "Damping laws")."""

    frequency_Hz: float
    damping_ratio: float
    harmonic: int  # n: the harmonic of the cycle rate nearest frequency_Hz (at least 1)
    detuning: float  # frequency_Hz / (n / cycle_s) - 1
    amplification: float
    decay_per_cycle: float


def lowest_mode(frequency_Hz: float, damping_ratio: float, cycle_s: float) -> LowestMode:
    """LowestMode of a mode at frequency_Hz with damping_ratio, driven by a cam of period cycle_s."""
    n = max(1, round(frequency_Hz * cycle_s))
    r = n / (cycle_s * frequency_Hz)
    amplification = 1.0 / float(np.hypot(1.0 - r * r, 2.0 * damping_ratio * r))
    decay = float(np.exp(-damping_ratio * 2.0 * np.pi * frequency_Hz * cycle_s))
    return LowestMode(float(frequency_Hz), float(damping_ratio), int(n), 1.0 / r - 1.0, amplification, decay)


@dataclass(frozen=True)
class LinearModelValidity:
    """Whether the linear model's own numbers (its minimum tension, the preload for full contact) hold
    (SI): its largest |span force| over its window (or its steady cycle) deforms a span by
    largest |T| / k from its unloaded length, against LINEAR_ELASTIC_STRAIN_LIMIT x the pitch. Where the
    link's yield load is known (the FEA's yield strength / peak stress per newton: `with_yield_load`),
    whether the preload for full contact is above it: such a preload yields the link at rest, so no
    designer can apply it (said in `reason`, the numbers' validity unchanged)."""

    validity: Validity  # VALID or OUTSIDE_LINEAR_MODEL
    reason: str  # in words; the numbers are the fields beside it
    largest_span_force_N: float
    span_deformation_m: float  # largest_span_force_N / k
    deformation_bound_m: float  # LINEAR_ELASTIC_STRAIN_LIMIT x pitch
    yield_load_N: float | None = None  # None: not known to the dynamics (with_yield_load adds it)
    preload_above_yield_load: bool | None = None

    @property
    def valid(self) -> bool:
        return self.validity == Validity.VALID


def linear_model_validity(
    min_tension_N: float, peak_tension_N: float, stiffness_N_per_m: float, pitch_m: float
) -> LinearModelValidity:
    """LinearModelValidity of a linear model whose span forces range over [min_tension_N, peak_tension_N]
    on spans of stiffness k and a chain of pitch pitch_m. Valid up to the bound itself."""
    force = max(abs(min_tension_N), abs(peak_tension_N))
    deformation = force / stiffness_N_per_m
    bound = LINEAR_ELASTIC_STRAIN_LIMIT * pitch_m
    if deformation <= bound:
        validity, reason = (
            Validity.VALID,
            f"the linear model deforms no span by more than {LINEAR_ELASTIC_STRAIN_LIMIT:.0%} of the pitch "
            "(the elastic strain of the strongest structural metals)",
        )
    else:
        validity, reason = (
            Validity.OUTSIDE_LINEAR_MODEL,
            f"the linear model deforms a span by more than {LINEAR_ELASTIC_STRAIN_LIMIT:.0%} of the pitch, "
            "beyond the elastic range of any metal link: its minimum tension and the preload for full "
            "contact describe no chain",
        )
    return LinearModelValidity(validity, reason, force, deformation, bound)


def with_yield_load(
    validity: LinearModelValidity, preload_for_full_contact_N: float, yield_load_N: float
) -> LinearModelValidity:
    """`validity` with the link's yield load and whether the preload for full contact is above it."""
    above = bool(preload_for_full_contact_N > yield_load_N)
    reason = validity.reason
    if above:
        reason += (
            "; the preload for full contact is above the link's yield load: it would yield the link "
            "at rest, not a preload a designer can apply"
        )
    return replace(validity, reason=reason, yield_load_N=float(yield_load_N), preload_above_yield_load=above)


def linear_validity_at_yield(contact, yield_strength_Pa: float | None, stress_Pa_per_N: float):
    """A ContactSummary's linear_model_validity with the link's yield load, yield_strength_Pa /
    stress_Pa_per_N (the FEA's peak stress per newton of pin load), where both are known; as it is
    otherwise (None for the single-link drive)."""
    validity = contact.linear_model_validity
    if validity is None or yield_strength_Pa is None or not stress_Pa_per_N > 0:
        return validity
    return with_yield_load(validity, contact.preload_for_full_contact_N, yield_strength_Pa / stress_Pa_per_N)


@dataclass(frozen=True)
class Resonance:
    """Of the machine's lowest NEAREST_RESONANCE_MODES modes (dynamics.solvers.machine_modes), the one its
    nearest cam harmonic drives hardest: the largest amplification x harmonic_share, the linear response the harmonic builds on the
    mode relative to the cam's strongest harmonic applied slowly. The amplification alone does not
    rank them under the global law (zeta 0.13 on every mode caps it at 3.9, so the mode nearest some
    harmonic, however weak, would win: mode 6 at the 21st on the default machine, 3.877 against mode
    1's 3.862 at the third); under the Kelvin-Voigt law it dominates. Mode 1's LowestMode is the
    summary's lowest_mode object itself."""

    mode_number: int  # 1: the lowest
    harmonic_share: float  # |A_n| / max |A_m| of the cam's acceleration harmonics, n the mode's harmonic
    # the highest of the modes searched: a harmonic far above it may meet a higher mode unsearched (a
    # long chain's 12 lowest modes end at 4.0 Hz at 10,000 links, below the 12 Hz index rate)
    searched_up_to_Hz: float
    mode: LowestMode


# samples of one cam cycle for its harmonics (at least 16 per period of the highest one asked for)
HARMONIC_SAMPLES = 1024


def harmonic_shares(cam, harmonics) -> np.ndarray:
    """|A_n| / max_m |A_m| at the `harmonics` n >= 1 of the cam's cycle rate: A_n the Fourier
    coefficients of the cam's acceleration over one cycle (cam.cycle_s), the inertial load it puts on
    the chain, sampled at HARMONIC_SAMPLES points or more."""
    n = np.asarray(harmonics, dtype=int)
    samples = max(HARMONIC_SAMPLES, 16 * int(n.max()))
    t = np.arange(samples) * (cam.cycle_s / samples)
    amplitudes = np.abs(np.fft.rfft(np.asarray(cam.svaj(t)[2], dtype=float)))[1:]
    return amplitudes[n - 1] / amplitudes.max()


def nearest_resonance(frequencies_Hz, damping_ratios, cam, lowest: LowestMode) -> Resonance:
    """Resonance of the modes at frequencies_Hz (ascending, the first mode 1) with their damping ratios,
    driven by `cam`; `lowest` is mode 1's LowestMode (its frequency and damping ratio are the first of
    each), returned itself where mode 1 is driven hardest (the first of equals)."""
    modes = [lowest] + [
        lowest_mode(float(f), float(z), cam.cycle_s) for f, z in zip(frequencies_Hz[1:], damping_ratios[1:])
    ]
    shares = harmonic_shares(cam, [m.harmonic for m in modes])
    best = int(np.argmax([m.amplification * share for m, share in zip(modes, shares)]))
    return Resonance(best + 1, float(shares[best]), float(max(frequencies_Hz)), modes[best])


@dataclass(frozen=True)
class ContactSummary:
    """What the designer reads about contact, per scenario (SI)."""

    model: ChainModelKind
    reason: str
    validity: Validity
    clearance_m: float
    contact_lost: bool  # some span left pulling contact (in the linear model: its tension went below 0)
    free_play_time_fraction: float  # share of span-time in free play over the output window
    impacts_per_cycle: float  # entries of a span into contact from free play, per cam cycle
    impact_force_spike_N: float  # largest |span force| within one impact duration of an impact (ImpactStatistics)
    peak_tension_N: float
    min_tension_N: float
    preload_for_full_contact_N: float  # from the linear model: P - its minimum tension (>= 0)
    linear_min_tension_N: float
    steady_state: SteadyState | None = None
    steps_per_output: int | None = None
    diagnostics: dict = field(default_factory=dict)
    impacts: ImpactStatistics = ImpactStatistics()
    # the machine on its wheels (drive "wheels"): the seat changes at the end of the window's last
    # index (dynamics.solvers.machine_verlet.Seating); None for the single-link drive
    seating: object = None
    # the clearance chain's station metrics' estimated relative error from its step (the last step
    # doubling's change, `_controlled`); None: the linear chain, or the step was not controlled
    step_error_estimate: float | None = None
    # how the stations' max/min and RMS metrics were taken: "every step" (the machine kernel tracks
    # them at its stations at every integrator step, dynamics.solvers.machine_verlet.PEAK_METRICS,
    # and the RMS over time by the trapezoid rule on the steps, RMS_METRICS) or "output samples"
    # (the largest output sample, the RMS over the samples: the single-link drive, the linear chain)
    peak_sampling: str = "output samples"
    # the machine on its wheels: its lowest mode under the run's damping law against the cam's harmonics
    # (LowestMode); None for the single-link drive
    lowest_mode: LowestMode | None = None
    # the machine on its wheels: of its lowest NEAREST_RESONANCE_MODES modes the one its nearest cam
    # harmonic drives hardest (Resonance); None for the single-link drive
    nearest_resonance: Resonance | None = None
    # whether linear_min_tension_N and preload_for_full_contact_N hold (LinearModelValidity); on the
    # wheels (the pitch is the sprocket's), None for the single-link drive
    linear_model_validity: LinearModelValidity | None = None


def choose_model(model: ClearanceChain, choice: str, linear_min_tension_N: float) -> ModelChoice:
    """The model for a scene, why, and whether its response holds; see the module docstring."""
    linear, clearance, valid = ChainModelKind.LINEAR, ChainModelKind.CLEARANCE, Validity.VALID
    if choice not in MODEL_CHOICES:
        raise DynamicsError(f"model: expected one of {', '.join(MODEL_CHOICES)}, got {choice!r}")
    if choice == "linear":
        return ModelChoice(linear, "asked for (--model linear)", valid)
    if choice == "clearance":
        return ModelChoice(clearance, "asked for (--model clearance)", valid)
    if model.tensioner is not None:
        return ModelChoice(clearance, "an idler tensioner is modelled, which only the clearance model carries", valid)
    if model.clearance_m == 0.0:
        return ModelChoice(linear, "pin clearance 0: the clearance law is the linear chain exactly", valid)
    # the reasons carry no numbers (linear_min_tension_N is reported beside them), so that scenarios
    # with the same reason read as one group in the report
    if linear_min_tension_N >= 0.0:
        return ModelChoice(
            linear,
            "the linear solution never leaves pulling contact (its minimum tension stays >= 0), "
            "so the free play is never entered",
            valid,
        )
    return ModelChoice(
        clearance,
        "the linear solution leaves pulling contact (its minimum tension goes below zero "
        "against the preload): the pin free play is crossed and the load reverses through "
        "impacts",
        valid,
    )


def simulate_chain(
    model: ClearanceChain,
    cam,
    t_eval_s,
    *,
    choice: str = "auto",
    steady_state: bool = True,
    links=None,
    n_modes: int | None = None,
    method: str = "exact",
    safety: float | None = None,
    tol: float = DEFAULT_TOL,
    max_cycles: int = DEFAULT_MAX_CYCLES,
    predictor: str | None = None,
    accuracy: float | None = None,
    kernel: str = "ring",
    progress=None,
) -> tuple[ChainResponse, ContactSummary]:
    """The response of the scene's model at t_eval_s and what it says about contact. The clearance
    chain's step: a fraction `safety` (default `verlet.default_safety`) of the stability limit of the
    velocity `predictor` (default `verlet.default_predictor`); with `accuracy` (a relative error) that
    step halved until the station metrics change by at most it (ContactSummary.step_error_estimate).
    `kernel`: the compiled step, the ring's own (dynamics.solvers.clearance_verlet) or the machine's on
    the ring's topology (dynamics.solvers.ring_on_topology: what it does not give yet is listed there,
    so the pipeline keeps the ring's). `progress` (a dynamics.search_progress.SearchProgress): told
    of every cam cycle of the clearance chain's periodic-state search."""
    if kernel not in ring_on_topology.KERNELS:
        raise DynamicsError(f"kernel: expected one of {', '.join(ring_on_topology.KERNELS)}, got {kernel!r}")
    t = np.asarray(t_eval_s, dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SlackChainWarning)  # reported through the summary
        lin = simulate(
            model.chain,
            cam,
            t,
            method=method,
            steady_state=steady_state,
            n_modes=n_modes,
            links=None if choice != "linear" else links,
        )
    needed = _preload_for_full_contact(model, lin)
    chosen = choose_model(model, choice, lin.min_tension_N)
    if chosen.model == ChainModelKind.LINEAR:
        out = lin if links is None or choice == "linear" else _select(lin, links)
        summary = ContactSummary(
            *chosen,
            model.clearance_m,
            lin.min_tension_N < 0.0,
            float(np.mean(lin.tension_N < 0.0)) if model.clearance_m > 0 else 0.0,
            0.0,
            0.0,
            float(lin.tension_N.max()),
            lin.min_tension_N,
            needed,
            lin.min_tension_N,
        )
        return out, summary
    predictor = verlet.default_predictor(model) if predictor is None else predictor
    safety = verlet.default_safety(model, predictor) if safety is None else safety
    if accuracy is not None and not (0 < accuracy < 1):
        raise DynamicsError(f"accuracy: expected a relative error in (0, 1) or None, got {accuracy!r}")
    with serial_blas():
        return _clearance_response(
            model,
            cam,
            t,
            lin,
            links,
            steady_state,
            safety,
            tol,
            max_cycles,
            chosen,
            predictor,
            accuracy,
            kernel,
            progress,
        )


def _preload_for_full_contact(model: ClearanceChain, lin: ChainResponse) -> float:
    """The preload that would keep every span in contact: the linear response's minimum tension below 0."""
    return max(model.chain.preload_N - lin.min_tension_N, 0.0)


def _select(r: ChainResponse, links) -> ChainResponse:
    cols = [int(i) for i in np.atleast_1d(links)]
    return replace(r, x_m=r.x_m[:, cols], v_m_s=r.v_m_s[:, cols], a_m_s2=r.a_m_s2[:, cols], links=tuple(cols))


def _cam_nodes(cam, t0: float, step: float, n_steps: int):
    tf = t0 + step * np.arange(n_steps + 1)
    _, v, a, _ = cam.svaj(tf)
    return np.asarray(v, dtype=float), np.asarray(a, dtype=float)


def _integrator(kernel: str):
    """The compiled step behind clearance_verlet.integrate's call (`simulate_chain`'s `kernel`)."""
    return verlet.integrate if kernel == "ring" else ring_on_topology.integrate


def _clearance_response(
    model, cam, t, lin, links, steady_state, safety, tol, max_cycles, chosen, predictor, accuracy, kernel, progress
):
    needed = _preload_for_full_contact(model, lin)
    h_out = np.diff(t)
    if np.max(np.abs(h_out - h_out[0])) > 1e-9 * h_out[0]:
        raise DynamicsError("t_eval_s: the clearance model needs equally spaced output times")
    sub = verlet.substeps_for(model, float(h_out[0]), safety, predictor)
    n = model.n_links
    y0 = lin.x_m[0] - lin.z_m[0]
    w0 = lin.v_m_s[0] - lin.zdot_m_s[0]
    start = (y0, w0, 0.0, 0.0)
    on_cycle = None if progress is None else progress.observer("with free play", tol)
    level = _window_run(model, cam, t, sub, start, steady_state, tol, max_cycles, predictor, kernel, on_cycle=on_cycle)
    estimate = None
    if accuracy is not None:
        level, estimate = _controlled(
            model, cam, t, level, start, steady_state, tol, max_cycles, predictor, accuracy, kernel, on_cycle
        )
    sub, run, ss = level.sub, level.run, level.steady_state
    h = float(h_out[0]) / sub
    s, v, a, _ = (np.asarray(q, dtype=float) for q in cam.svaj(t))
    cols = list(range(n)) if links is None else [int(i) for i in np.atleast_1d(links)]
    tension = model.tension_N(run.y, run.u)
    period = getattr(cam, "period_s", None) or (t[-1] - t[0])
    cycles = (t[-1] - t[0]) / period
    response = ChainResponse(
        t_s=t,
        x_m=s[:, None] + run.y[:, cols],
        v_m_s=v[:, None] + run.w[:, cols],
        a_m_s2=a[:, None] + run.a[:, cols],
        z_m=s,
        zdot_m_s=v,
        zddot_m_s2=a,
        tension_N=tension,
        drive_force_N=model.chain.drive_force_N(s + run.y[:, 0], s),
        links=tuple(cols),
        min_tension_N=run.min_tension_N,
        slack=run.free_play_fraction > 0.0,
        method="clearance-verlet",
        diagnostics={
            "steps_per_output": sub,
            "step_s": h,
            "steady_state": ss,
            "step_error_estimate": estimate,
            "carriage_m": run.u if model.tensioner is not None else None,
        },
    )
    summary = ContactSummary(
        *chosen,
        model.clearance_m,
        run.free_play_fraction > 0.0 or run.min_tension_N < 0.0,
        run.free_play_fraction,
        run.impacts / cycles,
        run.impact_force_spike_N,
        run.peak_tension_N,
        run.min_tension_N,
        needed,
        lin.min_tension_N,
        ss,
        sub,
        impacts=impact_statistics(run, cycles),
        step_error_estimate=estimate,
    )
    return response, summary


class _Level(NamedTuple):
    """One step size's output window: its steps per output sample, run, state at the window's start
    and how that state was found."""

    sub: int
    run: verlet.Run
    state: tuple
    steady_state: SteadyState | None


def _window_run(
    model, cam, t, sub, start, steady_state, tol, max_cycles, predictor, kernel="ring", cycles_before=0, on_cycle=None
) -> _Level:
    """The output window at `sub` steps per output sample, from the periodic state at that step
    (searched from `start`, its SteadyState counting `cycles_before` cycles stepped before the search,
    `on_cycle` told of each: `_periodic_state`) or, without steady state, from `start` itself."""
    h = float(t[1] - t[0]) / sub
    state, ss = start, None
    if steady_state:
        state, ss = _periodic_state(
            model,
            cam,
            t[0],
            h,
            start,
            tol,
            max_cycles,
            predictor,
            kernel=kernel,
            cycles_before=cycles_before,
            on_cycle=on_cycle,
        )
    zd, zdd = _cam_nodes(cam, t[0], h, sub * (t.size - 1))
    run = _integrator(kernel)(
        model, zd, zdd, h, state[0], state[1], u0=state[2], ud0=state[3], out_every=sub, predictor=predictor
    )
    return _Level(sub, run, state, ss)


def _controlled(
    model, cam, t, level, start, steady_state, tol, max_cycles, predictor, accuracy, kernel="ring", on_cycle=None
):
    """Step doubling on the output window until the station metrics' estimated error is within
    `accuracy` (or MAX_STEP_DOUBLINGS are spent): returns the finest level and its estimate, the
    change from step h to h/2. The scheme is second order, so that change is about 3x the error left
    at h/2 once the steps are in the asymptotic range; the 3x is kept as margin, because the ab2
    predictor's error is not monotone in the step before it (benchmarks/bench_accuracy.py). The finer
    level's periodic state is searched from the coarser one's (a few cycles: they differ by the
    coarser step's error); without steady state both start where the run starts. The finest level's
    SteadyState counts the cam cycles every level's search stepped (SteadyState.cycles); `on_cycle`
    told of each (`_periodic_state`)."""
    coarse = _station_values(model, cam, t, level.run)
    estimate = np.inf
    for _ in range(MAX_STEP_DOUBLINGS):
        previous = level
        # a coarser level without a periodic state hands on its last state (the motion after
        # max_cycles): both windows start there, and no steady state is claimed for the finer one
        search = steady_state and previous.steady_state.found
        begin = previous.state if steady_state else start
        before = previous.steady_state.cycles if search else 0
        level = _window_run(
            model, cam, t, 2 * previous.sub, begin, search, tol, max_cycles, predictor, kernel, before, on_cycle
        )
        if steady_state and not search:  # no search at this level: the coarser level's steady state stands
            level = level._replace(steady_state=previous.steady_state)
        fine = _station_values(model, cam, t, level.run)
        estimate = relative_change(fine, coarse)
        if estimate <= accuracy:
            break
        coarse = fine
    return level, estimate


def _station_values(model, cam, t, run) -> np.ndarray:
    """station_values of a clearance-chain run (its motion relative to the cam) at the four stations."""
    cols = [link - 1 for link in station_links(model.n_links).values()]
    s, v, a, _ = (np.asarray(q, dtype=float) for q in cam.svaj(t))
    # the stations' columns made absolute, not the whole chain's (long chains)
    x, xd, xdd = (c[:, None] + r[:, cols] for c, r in ((s, run.y), (v, run.w), (a, run.a)))
    return station_values(cam, t, x, xd, xdd, range(len(cols)))


def station_values(cam, t, x_m, v_m_s, a_m_s2, columns) -> np.ndarray:
    """The link metrics (dynamics.response.metrics.link_metrics) at the 0-based `columns` of the
    absolute motion x, x', x'' (samples x links) at t under `cam`, as one vector: what the step
    control compares, for the link drive and the machine on its wheels. The dwell samples are the
    cam's (every sample when it has no dwell mask or none of them lies in a dwell)."""
    cols = list(columns)
    s, v, a, _ = (np.asarray(q, dtype=float) for q in cam.svaj(t))
    mask = cam.dwell_mask(t) if hasattr(cam, "dwell_mask") else np.ones(t.size, dtype=bool)
    if not np.any(mask):
        mask = np.ones(t.size, dtype=bool)
    lm = link_metrics(x_m[:, cols], v_m_s[:, cols], a_m_s2[:, cols], s, v, a, mask)
    return np.concatenate([np.ravel(getattr(lm, f.name)) for f in fields(lm)])


def _periodic_state(
    model,
    cam,
    t0,
    h,
    state,
    tol,
    max_cycles,
    predictor="euler",
    depth=shooting.DEFAULT_DEPTH,
    kernel="ring",
    cycles_before=0,
    on_cycle=None,
):
    """(the state at the period's start, SteadyState) of the periodic state searched from `state` at the
    step h (the module docstring); the SteadyState counts the cam cycles this search stepped plus
    `cycles_before`, those the step control's coarser levels stepped before it (SteadyState.cycles).
    `on_cycle(change)`: the search's `on_period` (shooting.accelerated_fixed_point: after every cam
    cycle with its change per cycle; dynamics.search_progress)."""
    period = getattr(cam, "period_s", None)
    if period is None:
        raise DynamicsError("steady_state: the cam program is not periodic (period_s is None); use steady_state=False")
    n = model.n_links
    n_p = max(int(round(period / h)), 1)
    h_p = period / n_p
    every = shooting.search_out_every(n_p)
    zd, zdd = _cam_nodes(cam, t0, h_p, n_p)

    def one_period(x):
        run = _integrator(kernel)(
            model, zd, zdd, h_p, x[:n], x[n : 2 * n], u0=x[-2], ud0=x[-1], out_every=every, predictor=predictor
        )
        end = np.concatenate([run.y[-1], run.w[-1], [run.u[-1], run.ud[-1]]])
        return end, _scale(run, n)

    x0 = np.concatenate([state[0], state[1], [state[2], state[3]]])
    precondition = _slow_mode_newton(model, period) if depth else None
    search = shooting.accelerated_fixed_point(
        one_period, x0, tol=tol, max_periods=max_cycles, depth=depth, precondition=precondition, on_period=on_cycle
    )
    end = search.state
    state = (end[:n], end[n : 2 * n], float(end[-2]), float(end[-1]))
    cycle, residual = cycles_before + search.periods, search.residual
    if search.converged:
        return state, SteadyState(
            True,
            1,
            cycle,
            residual,
            f"periodic steady state found after {cycle} cam cycles (change per cycle {residual:.2g} <= {tol:g})",
        )
    ends, scale = search.plain_ends, search.plain_scale
    for k in range(2, MAX_SUBHARMONIC + 1):
        if len(ends) > k:
            res_k = float(np.max(np.abs(ends[-1] - ends[-1 - k]) / scale))
            if res_k <= tol:
                return state, SteadyState(
                    True,
                    k,
                    cycle,
                    res_k,
                    f"subharmonic response: the motion repeats every {k} cam cycles, not every "
                    f"cycle (change per {k} cycles {res_k:.2g}); the output window shows "
                    f"{'all' if k <= 2 else 'part'} of that period",
                )
    return state, SteadyState(
        False,
        None,
        cycle,
        residual,
        f"NO periodic steady state found: after {cycle} cam cycles the state still changes "
        f"by {residual:.2g} per cycle and repeats after no k <= {MAX_SUBHARMONIC} cycles "
        "(a chaotic or very slowly settling response); the results are the motion after "
        f"{cycle} cycles, not a steady state",
    )


def _slow_mode_newton(model, period_s: float):
    """The linear chain's Newton step on its slow modes (dynamics.solvers.shooting.slow_mode_newton),
    computed once per chain and period."""
    from dynamics.response.sweep import stiffness_matrix_sparse

    def compute():
        return shooting.slow_mode_newton(
            stiffness_matrix_sparse(model.chain),
            model.chain.link_mass_kg,
            model.damping_ratio_at,
            period_s,
            shooting.SLOW_DECAY,
        )

    return cache.cached(("slow-mode newton", model.chain, model.span_damping, model.beta_s, period_s), compute)


def _scale(run, n: int) -> np.ndarray:
    tiny = np.finfo(float).tiny
    sy = max(float(np.max(np.abs(run.y))), tiny)
    sw = max(float(np.max(np.abs(run.w))), tiny)
    su = max(float(np.max(np.abs(run.u))), sy)
    sud = max(float(np.max(np.abs(run.ud))), sw)
    return np.concatenate([np.full(n, sy), np.full(n, sw), [su, sud]])


def scene_model(scene: Scene, chain) -> ClearanceChain:
    """The clearance chain of a scene on its linear chain (a dynamics.models.chain.ChainModel)."""
    return ClearanceChain(chain, scene.pin_clearance_m, span_damping=scene.span_damping, tensioner=scene.tensioner)


def simulate_scene(
    scene: Scene, chain, cam, t_eval_s, *, links=None, n_modes=None, progress=None
) -> tuple[ChainResponse, ContactSummary]:
    """What the orchestrators call: the scene's model (auto, linear or clearance) for one cam.
    `progress` (a dynamics.search_progress.SearchProgress): told how the steady-state search goes."""
    if scene.layout.on_wheels:
        from dynamics.machine_scene import machine_model, simulate_machine, simulate_machine_to_accuracy

        model = machine_model(scene, chain)
        options = dict(choice=scene.model, steady_state=scene.steady_state, links=links, progress=progress)
        if scene.accuracy is None:
            return simulate_machine(model, cam, t_eval_s, **options)
        return simulate_machine_to_accuracy(model, cam, t_eval_s, accuracy=scene.accuracy, **options)
    return simulate_chain(
        scene_model(scene, chain),
        cam,
        t_eval_s,
        choice=scene.model,
        steady_state=scene.steady_state,
        links=links,
        n_modes=n_modes,
        method=scene.solver,
        accuracy=scene.accuracy,
        progress=progress,
    )
