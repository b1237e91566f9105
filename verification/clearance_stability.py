"""Where the clearance chain's explicit integrator holds and where it fails, and what its accuracy costs.

Stability map (`step_map`, for the default velocity predictor, "ab2", unless told): one index cycle
from rest (180 rpm, modified sine, 10 links, friction 0.35) per link stiffness k, pin clearance g and
step h = factor x the stability limit h_max (dynamics.solvers.clearance_verlet.stable_step_s with
safety 1 and that predictor: omega_max h_max from the step's
amplification matrix at the full-contact top frequency, which grows as sqrt(k)). Outcomes, against
the same integrator at h_max / 64:
- "accurate": max |y - y_ref| <= `accuracy` x max |y_ref|;
- "inaccurate": finished and bounded but off by more;
- "diverged": SolverDivergedError.
With g = 0 the limit is sharp (diverged just above it). With free play a step above the limit often
does not diverge: the growing top mode opens spans into free play, which bounds it, and the run ends
"inaccurate" by orders of magnitude. The step must therefore come from the full-contact frequency,
not from watching for divergence.

Work-precision (`work_precision`): the fast integrator at several steps per output sample against
the event-located reference (verification.clearance_reference, rtol 1e-10, the same sampled cam input),
error in the station links' displacement and acceleration versus wall time; the reference's own
cost at looser tolerances for comparison.

Where event location fails (`event_map`): the reference restarts at every output time and every
contact change, and its steps shrink as 1/sqrt(k) once they are shorter than an output interval. Per
clearance g, stiffness k and rtol (10 links, the first `EVENT_DEGREES` of an index from rest, a budget
of `max_events` contact changes): contact changes, function evaluations, wall time and outcome
against the fast integrator at h_max / 32 (its own error there about 1e-5 of the peak or less):
"accurate" (within 1e-3), "inaccurate", or "failed" (more contact changes than the budget: refused
with a DynamicsError naming max_events, or a solve_ivp failure).

The common-interface methods (`method_map`, `method_work_precision`): ClearanceChain.system() (global
law, no tensioner, friction 0: the form has no cam velocity) solved by dynamics.solvers.solve.
Fixed-step methods are placed by omega_max h (omega_max the full-contact top frequency), adaptive ones
by rtol; outcomes against the fast integrator at h_max / 64: "accurate" within 1e-2, "inaccurate",
"diverged" (SolverDivergedError), "failed" (SolverFailedError). Newmark and HHT take no nonlinear
force, so they have no place on the nonlinear chain.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dynamics.cams import CamProgram
from dynamics.errors import DynamicsError, SolverDivergedError, SolverFailedError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain
from dynamics.models.system import SampledForce
from dynamics.options import DEFAULT_PIN_CLEARANCE_M
from dynamics.solvers import clearance_verlet as verlet
from dynamics.solvers import solve

OUTCOMES = ("accurate", "inaccurate", "diverged", "failed")
STEP_FACTORS = (0.5, 0.9, 0.99, 1.01, 1.1, 1.5, 2.0)
STIFFNESSES_N_PER_M = (1e7, 1e8, 1e9)
CLEARANCES_M = (0.0, DEFAULT_PIN_CLEARANCE_M, 4 * DEFAULT_PIN_CLEARANCE_M)  # none, the default, four times it


@dataclass(frozen=True)
class StepCase:
    stiffness_N_per_m: float
    clearance_m: float
    step_factor: float  # h / h_max
    step_s: float
    outcome: str
    relative_error: float  # nan when diverged


def _cam():
    return CamProgram.indexing("modified-sine", pitch_m=0.1125, rpm=180.0)


def _final(model: ClearanceChain, h: float, duration: float, predictor: str = "euler") -> np.ndarray:
    n_steps = max(int(round(duration / h)), 1)
    tf = h * np.arange(n_steps + 1)
    _, v, a, _ = _cam().svaj(tf)
    n = model.n_links
    run = verlet.integrate(model, v, a, h, np.zeros(n), -v[0] * np.ones(n), out_every=n_steps, predictor=predictor)
    return run.y[-1]


def step_case(
    stiffness_N_per_m: float,
    clearance_m: float,
    factor: float,
    *,
    n_links: int = 10,
    accuracy: float = 1e-2,
    n_limit_steps: int = 4000,
    predictor: str = verlet.DEFAULT_PREDICTOR,
) -> StepCase:
    """One case of the map: n_limit_steps steps at the limit's length (about one index cycle at 1e8 N/m),
    with the given velocity predictor (the limit is that predictor's own); the reference is the same
    predictor at h_max / 64."""
    chain = ChainModel(
        n_links=n_links, link_mass_kg=2.0, stiffness_N_per_m=stiffness_N_per_m, friction_coefficient=0.35
    )
    model = ClearanceChain(chain, clearance_m)
    h_max = verlet.stable_step_s(model, safety=1.0, predictor=predictor)
    # the same window for every predictor (the euler limit's steps): the final state's sensitivity
    # depends on where the window ends (an impact just there magnifies any phase error)
    duration = n_limit_steps * verlet.stable_step_s(model, safety=1.0)
    ref = _final(model, h_max / 64, duration, predictor)
    try:
        y = _final(model, factor * h_max, duration, predictor)
    except SolverDivergedError:
        return StepCase(stiffness_N_per_m, clearance_m, factor, factor * h_max, "diverged", np.nan)
    rel = float(np.max(np.abs(y - ref)) / np.max(np.abs(ref)))
    return StepCase(
        stiffness_N_per_m, clearance_m, factor, factor * h_max, "accurate" if rel <= accuracy else "inaccurate", rel
    )


def step_map(
    stiffnesses=STIFFNESSES_N_PER_M,
    clearances=CLEARANCES_M,
    factors=STEP_FACTORS,
    predictor: str = verlet.DEFAULT_PREDICTOR,
) -> list[StepCase]:
    """The map for one velocity predictor: by default the default run's (the global law's default)."""
    return [step_case(k, g, f, predictor=predictor) for k in stiffnesses for g in clearances for f in factors]


@dataclass(frozen=True)
class WorkPoint:
    label: str  # "fast, 8 steps/sample" or "reference, rtol 1e-6"
    wall_s: float
    error_x: float  # max |y - y_ref| / max |y_ref| over every link and output
    error_a: float  # same for the acceleration relative to the cam


def work_precision(n_links: int = 20, substeps=(4, 8, 16, 32, 64), rtols=(1e-6, 1e-8)) -> list[WorkPoint]:
    """Fast integrator and looser references against the reference at rtol 1e-10 (default link's k
    and mass, 0.094 mm, friction 0.35, modal zeta 0.13, 180 degrees from rest, 4 samples/degree)."""
    from verification.clearance_reference import reference_response

    chain = ChainModel(n_links=n_links, link_mass_kg=2.03, stiffness_N_per_m=9.0092e7, friction_coefficient=0.35)
    model = ClearanceChain(chain, DEFAULT_PIN_CLEARANCE_M)
    t = np.arange(721) / 4 / (6 * 180.0)
    cam = _cam()
    _, v, a, _ = cam.svaj(t)
    c = model.chain

    def reference(rtol):
        return reference_response(
            n_links=n_links,
            link_mass_kg=c.link_mass_kg,
            stiffness_N_per_m=c.stiffness_N_per_m,
            drive_stiffness_N_per_m=c.drive_stiffness,
            preload_N=c.preload_N,
            clearance_m=model.clearance_m,
            cam=cam,
            t_eval_s=t,
            damping_matrix=model.damping_matrix,
            friction_force_N=c.coulomb_force_N,
            friction_velocity_scale_m_s=c.friction_velocity_scale_m_s,
            rtol=rtol,
        )

    ref = reference(1e-10)
    sx, sa = np.max(np.abs(ref.y_m)), np.max(np.abs(ref.yddot_m_s2))
    points = []
    for sub in substeps:
        tf = np.linspace(t[0], t[-1], sub * (t.size - 1) + 1)
        zd, zdd = np.interp(tf, t, v), np.interp(tf, t, a)
        verlet.integrate(model, zd, zdd, tf[1] - tf[0], np.zeros(n_links), -v[0] * np.ones(n_links), out_every=sub)
        start = time.perf_counter()
        run = verlet.integrate(
            model, zd, zdd, tf[1] - tf[0], np.zeros(n_links), -v[0] * np.ones(n_links), out_every=sub
        )
        wall = time.perf_counter() - start
        points.append(
            WorkPoint(
                f"fast, {sub} steps/sample",
                wall,
                float(np.max(np.abs(run.y - ref.y_m)) / sx),
                float(np.max(np.abs(run.a - ref.yddot_m_s2)) / sa),
            )
        )
    for rtol in rtols:
        start = time.perf_counter()
        loose = reference(rtol)
        wall = time.perf_counter() - start
        points.append(
            WorkPoint(
                f"reference, rtol {rtol:g}",
                wall,
                float(np.max(np.abs(loose.y_m - ref.y_m)) / sx),
                float(np.max(np.abs(loose.yddot_m_s2 - ref.yddot_m_s2)) / sa),
            )
        )
    return points


# --- where event location fails, and the common-interface methods ------------------------------------

EVENT_DEGREES = 30.0
EVENT_CLEARANCES_M = (1e-7, 1e-6, 1e-5, 1e-4, 1e-3)
EVENT_STIFFNESSES_N_PER_M = (1e6, 1e7, 1e8, 1e9, 1e10)
EVENT_RTOLS = (1e-4, 1e-6, 1e-8)
EVENT_BUDGET = 1000


@dataclass(frozen=True)
class SmallCase:
    """A short window of the chain from rest: the cam's velocity and acceleration at the output times t
    (4 samples per degree), held linearly in between by every method."""

    model: ClearanceChain
    t: np.ndarray
    v: np.ndarray
    a: np.ndarray

    def fast(self, step_s: float):
        """The fast integrator at about `step_s` (a whole number of steps per output interval)."""
        sub = max(int(np.ceil((self.t[1] - self.t[0]) / step_s)), 1)
        tf = np.linspace(self.t[0], self.t[-1], sub * (self.t.size - 1) + 1)
        n = self.model.n_links
        return verlet.integrate(
            self.model,
            np.interp(tf, self.t, self.v),
            np.interp(tf, self.t, self.a),
            tf[1] - tf[0],
            np.zeros(n),
            -self.v[0] * np.ones(n),
            out_every=sub,
        )

    def reference(self, rtol: float, max_events: int | None = None, atol: float | None = None):
        from verification.clearance_reference import MAX_EVENTS, reference_response

        c = self.model.chain
        kelvin_voigt = self.model.span_damping == "kelvin-voigt"
        return reference_response(
            n_links=c.n_links,
            link_mass_kg=c.link_mass_kg,
            stiffness_N_per_m=c.stiffness_N_per_m,
            drive_stiffness_N_per_m=c.drive_stiffness,
            preload_N=c.preload_N,
            clearance_m=self.model.clearance_m,
            cam=_cam(),
            t_eval_s=self.t,
            damping_matrix=None if kelvin_voigt else self.model.damping_matrix,
            span_damping_beta_s=self.model.beta_s if kelvin_voigt else 0.0,
            friction_force_N=c.coulomb_force_N,
            friction_velocity_scale_m_s=c.friction_velocity_scale_m_s,
            rtol=rtol,
            atol=atol,
            max_events=MAX_EVENTS if max_events is None else max_events,
        )

    def common(self, method: str, **options):
        """ClearanceChain.system() by dynamics.solvers.solve (friction must be 0: see the module doc)."""
        c, n = self.model.chain, self.model.n_links
        force = SampledForce(self.t, c.base_excitation_force(self.a))
        return solve(
            self.model.system(), force, self.t, method=method, x0=np.zeros(n), v0=-self.v[0] * np.ones(n), **options
        )


def small_case(
    stiffness_N_per_m: float,
    clearance_m: float,
    *,
    n_links: int = 10,
    degrees: float = EVENT_DEGREES,
    friction_coefficient: float = 0.35,
    span_damping: str = "global",
) -> SmallCase:
    chain = ChainModel(
        n_links=n_links,
        link_mass_kg=2.0,
        stiffness_N_per_m=stiffness_N_per_m,
        friction_coefficient=friction_coefficient,
    )
    t = np.arange(int(round(4 * degrees)) + 1) / 4 / (6 * 180.0)
    _, v, a, _ = _cam().svaj(t)
    return SmallCase(ClearanceChain(chain, clearance_m, span_damping=span_damping), t, v, a)


@dataclass(frozen=True)
class EventCase:
    stiffness_N_per_m: float
    clearance_m: float
    rtol: float
    outcome: str  # accurate / inaccurate / failed
    contact_changes: int  # located (at failure: the budget)
    function_evaluations: int  # 0 at failure
    wall_s: float
    relative_error: float  # nan when failed
    message: str  # the error's line when failed


def _relative(y, ref) -> float:
    return float(np.max(np.abs(y - ref)) / np.max(np.abs(ref)))


def event_case(
    stiffness_N_per_m: float,
    clearance_m: float,
    *,
    max_events: int = EVENT_BUDGET,
    rtol: float = 1e-8,
    accuracy: float = 1e-3,
    degrees: float = EVENT_DEGREES,
    span_damping: str = "global",
) -> EventCase:
    case = small_case(stiffness_N_per_m, clearance_m, degrees=degrees, span_damping=span_damping)
    converged = case.fast(verlet.stable_step_s(case.model, safety=1.0) / 32).y
    start = time.perf_counter()
    try:
        ref = case.reference(rtol, max_events)
    except (SolverFailedError, DynamicsError) as e:
        return EventCase(
            stiffness_N_per_m, clearance_m, rtol, "failed", max_events, 0, time.perf_counter() - start, np.nan, str(e)
        )
    wall = time.perf_counter() - start
    rel = _relative(ref.y_m, converged)
    return EventCase(
        stiffness_N_per_m,
        clearance_m,
        rtol,
        "accurate" if rel <= accuracy else "inaccurate",
        ref.n_contact_changes,
        ref.n_function_evaluations,
        wall,
        rel,
        "",
    )


def event_map(
    stiffnesses=EVENT_STIFFNESSES_N_PER_M, clearances=EVENT_CLEARANCES_M, rtols=EVENT_RTOLS, **kw
) -> list[EventCase]:
    return [event_case(k, g, rtol=r, **kw) for r in rtols for k in stiffnesses for g in clearances]


METHOD_STIFFNESSES_N_PER_M = (1e6, 1e7, 1e8, 1e9, 1e10)
# fixed-step methods: omega_max h; adaptive ones: rtol
METHOD_SETTINGS = {
    "central-difference": (0.5, 1.0, 1.98, 2.02, 3.0),
    "exact": (0.5, 1.0, 2.0, 4.0, 16.0),
    "rk45": (1e-3, 1e-5, 1e-7),
    "radau": (1e-3, 1e-5),
}
FIXED_STEP = ("central-difference", "exact")


@dataclass(frozen=True)
class MethodCase:
    method: str
    stiffness_N_per_m: float
    setting: float  # omega_max h (fixed step) or rtol
    outcome: str
    wall_s: float
    relative_error: float  # nan when diverged or failed


def _steps_per_output(case: SmallCase, omega_h: float) -> tuple[int, float]:
    """Whole steps per output interval giving omega_max h closest to omega_h (at or above it), and the
    omega_max h they give."""
    omega = case.model.max_frequency_rad_s()
    dt_out = case.t[1] - case.t[0]
    sub = max(int(np.floor(omega * dt_out / omega_h)), 1)
    return sub, omega * dt_out / sub


def method_run(case: SmallCase, method: str, setting: float):
    """One common-interface solve: the response and the setting actually used."""
    if method in FIXED_STEP:
        sub, omega_h = _steps_per_output(case, setting)
        dt = (case.t[1] - case.t[0]) / sub
        options = {"dt": dt * (1 + 1e-12)} if method == "central-difference" else {"substeps": sub}
        return case.common(method, **options), omega_h
    return case.common(method, rtol=setting, atol=setting * 1e-5), setting


def method_case(
    method: str,
    stiffness_N_per_m: float,
    setting: float,
    *,
    clearance_m: float = DEFAULT_PIN_CLEARANCE_M,
    accuracy: float = 1e-2,
    degrees: float = EVENT_DEGREES,
) -> MethodCase:
    case = small_case(stiffness_N_per_m, clearance_m, degrees=degrees, friction_coefficient=0.0)
    converged = case.fast(verlet.stable_step_s(case.model, safety=1.0) / 64).y
    used = _steps_per_output(case, setting)[1] if method in FIXED_STEP else setting
    start = time.perf_counter()
    try:
        r = method_run(case, method, setting)[0]
    except SolverDivergedError:
        return MethodCase(method, stiffness_N_per_m, used, "diverged", time.perf_counter() - start, np.nan)
    except SolverFailedError:
        return MethodCase(method, stiffness_N_per_m, used, "failed", time.perf_counter() - start, np.nan)
    wall = time.perf_counter() - start
    rel = _relative(r.x, converged)
    return MethodCase(method, stiffness_N_per_m, used, "accurate" if rel <= accuracy else "inaccurate", wall, rel)


def method_map(stiffnesses=METHOD_STIFFNESSES_N_PER_M, settings=METHOD_SETTINGS) -> list[MethodCase]:
    """Every method x stiffness x setting; a fixed step is whole steps per output interval, so soft
    chains reach only the small omega_max h of one step per output, done once."""
    cases, done = [], set()
    for method, values in settings.items():
        for k in stiffnesses:
            for value in values:
                if method in FIXED_STEP:
                    case = small_case(k, DEFAULT_PIN_CLEARANCE_M, friction_coefficient=0.0)
                    key = (method, k, _steps_per_output(case, value)[0])
                    if key in done:
                        continue
                    done.add(key)
                cases.append(method_case(method, k, value))
    return cases


def method_work_precision(
    stiffness_N_per_m: float = 9.0092e7, clearance_m: float = DEFAULT_PIN_CLEARANCE_M, degrees: float = 90.0
) -> list[WorkPoint]:
    """Every method that solves the nonlinear chain, step or tolerance swept, against the reference at
    rtol 1e-10 (10 links, friction 0, `degrees` of an index from rest)."""
    case = small_case(stiffness_N_per_m, clearance_m, degrees=degrees, friction_coefficient=0.0)
    ref = case.reference(1e-10)
    sx, sa = np.max(np.abs(ref.y_m)), np.max(np.abs(ref.yddot_m_s2))
    h_max = verlet.stable_step_s(case.model, safety=1.0)

    def timed(label, run, warm=True):
        if warm:
            run()  # compile / warm caches
        walls = []
        while not walls or (warm and len(walls) < 5 and sum(walls) < 0.2):  # best of a few for short runs
            start = time.perf_counter()
            y, a = run()
            walls.append(time.perf_counter() - start)
        wall = min(walls)
        return WorkPoint(
            label, wall, float(np.max(np.abs(y - ref.y_m)) / sx), float(np.max(np.abs(a - ref.yddot_m_s2)) / sa)
        )

    def fast(f):
        def run():
            r = case.fast(h_max * f)
            return r.y, r.a

        return run

    def common(method, setting):
        def run():
            r = method_run(case, method, setting)[0]
            return r.x, r.a

        return run

    def reference(rtol):
        def run():
            r = case.reference(rtol)
            return r.y_m, r.yddot_m_s2

        return run

    points = [timed(f"fast, h = {f:g} h_max", fast(f)) for f in (0.5, 0.25, 0.125, 0.0625)]
    points += [timed(f"central-difference, omega h = {w:g}", common("central-difference", w)) for w in (1.0, 0.5, 0.25)]
    points += [timed(f"exact (Heun splitting), omega h = {w:g}", common("exact", w)) for w in (1.0, 0.5, 0.25)]
    points += [timed(f"rk45, rtol {r:g}", common("rk45", r)) for r in (1e-4, 1e-6, 1e-8)]
    points += [timed(f"radau, rtol {r:g}", common("radau", r)) for r in (1e-4, 1e-6)]
    points += [timed(f"reference, rtol {r:g}", reference(r), warm=False) for r in (1e-6, 1e-8)]
    return points
