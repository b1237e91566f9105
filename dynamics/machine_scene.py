"""A scene's chain on its wheels (issue #22): which model runs and its response, as
dynamics.scene.simulate_chain does for the single-link drive.

`simulate_machine(model, cam, t_eval_s, choice="auto")` always runs the linear machine first (the
clearance machine at free play 0 with the global damping law: the span law is then linear, and the
model is dynamics.models.machine.MachineOnWheels with its polygonal feed), in its relabelled periodic
steady state (or from rest). The model is chosen from it exactly as for the single-link drive
(dynamics.scene.choose_model): the linear machine when the free play is 0 or its minimum tension
stays >= 0; the clearance machine otherwise (or when asked, or with a tensioner), started from the
linear machine's steady state.

The step (issue #24): a run given no step steps its window at the default safety / WINDOW_REFINEMENT
(by damping law). With a steady state it searches the clearance machine's (or, when it is the
answer, the linear machine's) relabelled steady state at SEARCH_SAFETY of the stability limit and
settles it for SETTLE_CYCLES index cycles at the window's step: the window's accuracy of the fine
step at the cost of the old default (docs/performance.md#default-accuracy-of-the-clearance-chain).
A search that finds no steady state leaves the motion after max_cycles coarse cycles, which is not
the fine step's: it is redone at the window's step. A run from rest steps its window there from
the start. A run given its `safety` (the step control, a converged reference) steps everything at it.

Frame of the output (the machine as it runs): every index moves each link one place ahead, and the
response's columns are places: column j is the link at link j's place at the start of each index
(a seated link's column is its wheel's pitch-circle motion, a link seated on a sprocket held to the
cam moves with the cam). The seat changes happen at each index's start, where the output sample
is the state after them; at a tooth phase other than 0 inside the index, when the cam has lifted
(1 - phase) of a pitch (dynamics.solvers.machine_verlet.index_cycle), and the samples from then on
are in the next index's places (a column then shows the link one place behind). The spans between two links seated on the same wheel do not stretch
(rigid seating); their column in `tension_N` is the larger of the wheel's two strand-end spans
(an upper bound of what the seated spans carry). `drive_force_N` is the force the sprocket's drive
puts on the chain along its path: k_theta / R_m^2 times the sprocket's lag behind the cam, or, for
a sprocket held to the cam, the strand-end tensions' difference plus the seated links' inertia.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from functools import partial

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.response.metrics import LinkMetrics
from dynamics.scene import (
    DEFAULT_MAX_CYCLES,
    DEFAULT_TOL,
    ChainModelKind,
    ContactSummary,
    LinearModelValidity,
    LowestMode,
    ModelChoice,
    Resonance,
    SteadyState,
    _select,
    choose_model,
    impact_statistics,
    linear_model_validity,
    lowest_mode,
    nearest_resonance,
    station_values,
)
from dynamics.search_progress import SearchProgress
from dynamics.solvers import clearance_verlet as verlet
from dynamics.solvers import machine_modes, machine_shooting
from dynamics.solvers import machine_verlet as mv
from dynamics.solvers.simulate import ChainResponse

# The linear machine's steady state is found to this tolerance before the model is chosen: enough for
# the choice and the preload for full contact (its minimum tension to about this fraction), not
# for the answer (see simulate_machine)
CHOICE_TOL = 1e-3
# The default run spends its steps where they pay (issue #24): the clearance machine's steady state is
# searched at SEARCH_SAFETY of the stability limit (by law), then SETTLE_CYCLES index cycles and the
# window are stepped at the default safety / WINDOW_REFINEMENT (by law). A run given its safety (the
# step control, a converged reference) steps everything at it. The refinements are measured
# (benchmarks/bench_accuracy.py and the default job's 2 materials x 5 cam laws, against euler at 1/32 of
# 0.25, worst station metric; the peaks at the contact changes by one-sided quadratics,
# machine_verlet.step_peaks): the global law at 3.5 is at most 7.1e-4 off and at every refinement
# from 3.0 to 4.5 at most 9.1e-4 (the error is not monotone in the step: errors partly cancel at
# one step count and not at the next), where 2.75 left 1.2e-3 (titanium, modified sine) and 2.25
# 1.6e-3; the Kelvin-Voigt law's dashpot force jumps at each impact: at 4 its window from rest is
# 3.0e-4 off (41 links, 240 rpm), at most 9.1e-4 from 3.6 to 5.6, 1.1e-3 at 3.2.
SEARCH_SAFETY = {"global": 0.9, "kelvin-voigt": 0.5}
WINDOW_REFINEMENT = {"global": 3.5, "kelvin-voigt": 4.0}
SETTLE_CYCLES = 1
# Long chains (above DENSE_LINK_LIMIT links, the O(N) damping's range; the default run's 85 links are
# not in it) spend fewer cycles where the window cannot see them (issue #24, measured at 1,000 links on
# the default wheels, 0.094 mm, 180 rpm, against a run at twice the window's refinement, tol 1e-8):
# - the search's fixed point at SEARCH_SAFETY is itself 2.8e-3 per cycle from the window step's, so
#   it is searched to long_search_tol, not to `tol`;
# - it is settled at the default safety (a third of the window's steps), not the window's step (one
#   settling cycle at the window's step moved the metrics by 8e-6 at 2,000 links): by SETTLE_CYCLES
#   plain cycles, or where they would keep too much of the slow modes' offset between the two steps'
#   fixed points by the same search to the same tolerance (SETTLE_SEARCH_ABOVE_DECAY, below), and
#   where that search would take many cycles to it by defect correction with coarse cycles
#   (SETTLE_DEFECT_CORRECTED_ABOVE_DECAY);
# - the linear machine decides the model from its search at SEARCH_SAFETY, with no confirming cycle
#   at the default safety (its minimum tension at the two steps within 2e-6: CHOICE_TOL is 1e-3).
# long_search_tol: a start whose cycle changes it by r is within about r / (1 - rho) of the fixed
# point, rho the slowest mode's decay per cycle (0.80 at 1,000 links, 0.89 at 2,000, 0.956 at 5,000,
# 0.978 at 10,000 on that scene), so the search stops at LONG_SEARCH_STATE_ERROR (1 - rho): the same
# bound on the state's error at every length, 1e-4 at 10,000 links (the tolerance all lengths had
# before) and 9e-4 at 1,000 (8 cycles instead of 10; the station metrics moved by 2.2e-4, 6.9e-4
# from the tight run against 7.6e-4 at 1e-4). A fixed 1e-3 at 10,000 links moved them by 5.8e-3.
# Never below LONG_SEARCH_TOL there, the fixed tolerance before (up to LONG_SEARCH_STATE_ERROR_UP_TO_DECAY
# the bound is looser than it: 3.6e-4 at 0.92).
LONG_SEARCH_STATE_ERROR = 4.5e-3
LONG_SEARCH_TOL = 1e-4
# The state's error bound holds the station metrics to 1e-3 only while they are not much more sensitive
# to the state than it (1,000 links: 2.2e-4 for 4.5e-3). Above this rho they are (the slack side's
# max |a| and RMS a, its impacts' timing): searched to long_search_tol's bound, 4,000 links (rho 0.946,
# 2.4e-4) were 7.2e-3 from the search to 1e-5, 3,000 (0.926, 3.3e-4) 7.8e-4 (benchmarks/
# bench_long_accuracy.py, the default wheels, 0.094 mm, 180 rpm, docs/performance.md "Long clearance
# chains on wheels").
LONG_SEARCH_STATE_ERROR_UP_TO_DECAY = 0.92
# Above it the tolerance is this tighter bound on the state's error, LONG_SEARCH_SLACK_STATE_ERROR
# (1 - rho), with the settle at the window's step (SETTLE_AT_WINDOW_STEP_ABOVE_DECAY) and each mode's
# damping ratio to 1e-7 (machine_damping.default_tolerance): measured against the tight runs (the
# step at the default safety / 5 or / 10 for search, settle and window, searched to 1e-8, each ratio to
# 1e-7; benchmarks/bench_long_accuracy.py, the scene above), worst station metric (the slack side's
# max |a|): 4,000 links (rho 0.946) 2.2e-3 at a tolerance of 1e-4, 2.4e-4 at 3e-5; 3,000 (0.926)
# 1.4e-4 at 1e-4. The error is where the search happens to stop inside its bound, so the bound is set
# by the worst measured length (4,000: 2.7e-5; at twice the bound, 5.4e-5, 1.05e-3) and holds the
# state's error to the same 5e-4 at every rho above the threshold (3,000 links 3.7e-5, 5,000 2.2e-5,
# 10,000 1.1e-5). With it the default run is 3.1e-4, 2.4e-4 and 4.0e-4 from the tight runs at 3,000,
# 4,000 and 5,000 links, for 23.7 against 19.3 s of CPU at 3,000 links and 38.2 against 23.1 s at
# 4,000 (20 index cycles more). Never below
# LONG_SEARCH_TOL_FLOOR: the Kelvin-Voigt law's nearly undamped slow modes (rho 0.9995 at 1,000 links) ask for
# 2.5e-7, which no search reaches in its budget (the search to 1e-5 took 77 index cycles at 4,000 links)
LONG_SEARCH_SLACK_STATE_ERROR = 5e-4
LONG_SEARCH_TOL_FLOOR = 1e-5
# One settling cycle at the default safety keeps rho (the slowest mode's decay per cycle) of the
# offset between the search step's fixed point and the default step's. Above this rho the settle is a
# search to long_search_tol instead (measured on the default wheels, 0.094 mm, 180 rpm, against a run
# at the default safety / 10, tol 1e-8, worst station metric: 2,000 links, rho 0.89: one cycle 3.05e-3,
# the search 2.4e-3 (+2 cycles); 10,000 links, rho 0.978: one cycle left 3.2e-2 from the default
# step's fixed point, the search 7.4e-4 (+15 cycles); 1,000 links, rho 0.80: one cycle 4.3e-4, the
# search 5.5e-4 for 2 more cycles, so it keeps the one cycle)
SETTLE_SEARCH_ABOVE_DECAY = 0.85
# Above this rho the settle's search is a defect correction with coarse cycles
# (machine_shooting.defect_corrected_periodic_state: one cycle at the default safety gives the two
# steps' difference, the coarse map plus it is searched with the coarse search's history, a cycle at
# the default safety accepts the result by the same test to the same tolerance). It needs two cycles
# at the default safety and some coarse ones whenever the first is not accepted, so it pays only where
# the fine search takes more. Measured (benchmarks/bench_long_settle.py, the scene above, the same
# coarse state): 2,000 links, rho 0.893: 3 coarse + 2 fine cycles, 1.6 s of CPU, against the fine
# search's 2 cycles, 0.9 s; 5,000 links, rho 0.956: 12 coarse + 4 fine, 10.1 s, against 16 cycles,
# 19.6 s, and the station metrics 2.0e-4 from the default safety's fixed point searched to 1e-7
# against the fine search's 3.4e-3; 10,000 links, rho 0.978: 24 coarse + 3 fine, 29.6 s, against 15
# cycles, 35.5 s (the two 7.3e-4 apart).
SETTLE_DEFECT_CORRECTED_ABOVE_DECAY = 0.92
# Above this rho the settle finds the fixed point at the window's step, not at the default safety: the
# window starts at its own step's fixed point, where the default safety's differs from it along the slow
# modes by more than the window's first cycles remove (they keep rho of it per cycle). Measured at
# 3,000 links (rho 0.926) against the tight runs: the slack side's RMS a 8.3e-3 settled at the default
# safety (tolerance 1e-4), 7.1e-3 at the window's step alone, 1.4e-4 with the damping's ratios to 1e-7
# as well (24.7 s of CPU against 20.8 s); at 4,000 links (0.946) the damping's 1e-7 alone left 1.1e-2,
# the state's RMS x 9.7e-4 off, with this too 2.2e-3 (RMS x 6.9e-5). Its fine cycles are 3.5 times the
# default safety's (WINDOW_REFINEMENT), the defect correction's 3-4 of them about 4-7 s at 3,000-4,000 links
SETTLE_AT_WINDOW_STEP_ABOVE_DECAY = 0.92


def machine_model(scene, chain) -> ClearanceMachine:
    """The clearance machine of a scene (its layout, tensioner, free play, damping law) on one
    material's chain (a dynamics.models.chain.ChainModel)."""
    return ClearanceMachine.of(chain, scene.layout, scene.tensioner, scene.pin_clearance_m, scene.span_damping)


def linear_machine(model: ClearanceMachine) -> ClearanceMachine:
    """The linear machine simulate_machine decides the model with: `model`'s machine at free play 0
    with the global damping law, its friction and no tensioner."""
    return ClearanceMachine(model.machine, 0.0, "global", None, model.friction_chain)


def simulate_machine(
    model: ClearanceMachine, cam, t_eval_s, *, links=None, **settings
) -> tuple[ChainResponse, ContactSummary]:
    """The response of the machine at t_eval_s (index cycles from an index's start, equally spaced,
    a whole number of samples per cycle) at `links` (None: every link) and what it says about contact
    and seating. `settings`: _run_machine's (choice, steady_state, safety, predictor, tol, max_cycles,
    progress)."""
    out = _run_machine(model, cam, t_eval_s, **settings)
    return _response(out, cam, links), _summary(out, cam)


@dataclass(frozen=True)
class _Outcome:
    """What one run of simulate_machine gives its response and its summary: the scene's machine
    (`model`), the one that ran (`ran`: it, or its linear machine), the model choice, the output times
    and the window over them, the linear machine's span force range (min, peak) that chose the model,
    the steady state and the window's steps per output sample."""

    model: ClearanceMachine
    ran: ClearanceMachine
    chosen: ModelChoice
    t_s: np.ndarray
    window: _Window
    linear_tension_N: tuple[float, float]
    steady_state: SteadyState | None
    steps_per_output: int


def _run_machine(
    model: ClearanceMachine,
    cam,
    t_eval_s,
    *,
    choice: str = "auto",
    steady_state: bool = True,
    safety: float | None = None,
    predictor: str | None = None,
    tol: float = DEFAULT_TOL,
    max_cycles: int = DEFAULT_MAX_CYCLES,
    progress: SearchProgress | None = None,
) -> _Outcome:
    """The machine stepped over t_eval_s as the module docstring says: the model `choice` ("auto",
    "linear", "clearance"), in its relabelled steady state (searched to `tol` in `max_cycles` index
    cycles) or from rest, the step's `safety` and `predictor` (None: the defaults, SearchSettings.of);
    `progress` hears of the long chains' searches (SearchSettings.progress)."""
    t = np.asarray(t_eval_s, dtype=float)
    period = getattr(cam, "period_s", None)
    if period is None:
        raise DynamicsError("cam: the machine on its wheels needs a periodic indexing cam (one pitch per index)")
    h_out = float(t[1] - t[0])
    per_cycle = int(round(period / h_out))
    if np.max(np.abs(np.diff(t) - h_out)) > 1e-9 * h_out or abs(per_cycle * h_out - period) > 1e-9 * period:
        raise DynamicsError("t_eval_s: the machine needs equally spaced output times, a whole number per index cycle")
    if abs(t[0] / period - round(t[0] / period)) > 1e-9:
        raise DynamicsError("t_eval_s: the machine's output window must start at an index's start (the dwell's end)")
    linear = linear_machine(model)
    options = dict(tol=tol, max_cycles=max_cycles, steady_state=steady_state, progress=progress)
    lin_search = SearchSettings.of(linear, predictor, safety, **options)
    lin_pred = lin_search.predictor
    n_state = model.n_state  # the DOFs, and a tooth model's seat offsets
    start = (np.zeros(n_state), np.zeros(n_state))
    lin_sub = mv.substeps_for(linear, h_out, lin_search.safety, lin_pred)
    # the linear machine first to CHOICE_TOL: its minimum tension decides the model (and gives the
    # preload for full contact) and its state starts the clearance machine's steady state, which
    # is then iterated to `tol`; only when the linear machine is the answer is it iterated on to `tol`
    # and its window stepped
    choosing = replace(lin_search, tol=max(tol, CHOICE_TOL))
    choice_sub = _choice_substeps(linear, h_out, lin_sub, lin_search)
    lin_state, lin_ss, lin_last = start_state(linear, cam, h_out, per_cycle, choice_sub, start, choosing)
    lin = None
    if lin_last is not None and lin_ss.found:
        # in the steady state every index cycle is the last one stepped (to choosing.tol): its minimum
        # tension is the window's
        lin_min, lin_peak = lin_last.min_tension_N, lin_last.peak_tension_N
    else:
        lin = _window(linear, cam, t, per_cycle, lin_sub, lin_state, lin_pred)
        lin_min, lin_peak = lin.min_tension_N, lin.peak_tension_N
    chosen = choose_model(model, choice, lin_min)
    if chosen.model == ChainModelKind.LINEAR and (lin is None or lin_search.default_step):
        # the linear machine is the answer: its steady state to `tol` (or its window from rest) at the
        # window's step
        lin_state, lin_ss, lin_sub = _searched_and_settled(linear, cam, h_out, per_cycle, lin_state, lin_search)
        lin = _window(linear, cam, t, per_cycle, lin_sub, lin_state, lin_pred, _found(lin_ss))
        lin_min, lin_peak = lin.min_tension_N, lin.peak_tension_N
        chosen = choose_model(model, choice, lin_min)
    if chosen.model == ChainModelKind.LINEAR:
        run, sub, ss = lin, lin_sub, lin_ss
    else:
        search = SearchSettings.of(model, predictor, safety, **options)
        state, ss, sub = _searched_and_settled(model, cam, h_out, per_cycle, lin_state, search)
        run = _window(model, cam, t, per_cycle, sub, state, search.predictor, _found(ss))
    ran = model if chosen.model == ChainModelKind.CLEARANCE else linear
    return _Outcome(model, ran, chosen, t, run, (lin_min, lin_peak), ss, sub)


class _Window:
    """The outputs of consecutive index cycles at the output times, with their statistics and the
    station peaks and RMS over every step (machine_verlet.MachineRun.station_peaks, `station_rms`:
    stations x machine_verlet.RMS_METRICS)."""

    def __init__(self, q, v, a, tension, runs, seating, step_s, station_peaks=None, station_rms=None):
        self.q, self.v, self.a, self.tension_N = q, v, a, tension
        self.seating = seating
        self.step_s = step_s
        self.cycles = len(runs)  # index cycles stepped (the statistics are over them)
        recorded = sum(r.q.shape[0] for r in runs)
        self.impacts = sum(r.impacts for r in runs)
        self.free_play_fraction = float(sum(r.free_play_fraction * r.q.shape[0] for r in runs) / recorded)
        self.peak_tension_N = max(r.peak_tension_N for r in runs)
        self.min_tension_N = min(r.min_tension_N for r in runs)
        self.impact_force_spike_N = max(r.impact_force_spike_N for r in runs)
        self.impact_kinetic_energy_J = sum(r.impact_kinetic_energy_J for r in runs)
        self.impact_dissipated_J = sum(r.impact_dissipated_J for r in runs)
        self.impact_max_speed_m_s = max(r.impact_max_speed_m_s for r in runs)
        self.impact_speeds_m_s = np.concatenate([r.impact_speeds_m_s for r in runs])
        self.station_peaks = station_peaks
        self.station_rms = station_rms


@dataclass(frozen=True)
class SearchSettings:
    """How a machine's relabelled steady state is searched and its window stepped: the step's
    predictor and `safety` (its fraction of the stability limit), the change per index cycle the
    search accepts (`tol`, relative to the largest |q| and |q'| over the cycle) and its cycles
    (`max_cycles`); `steady_state` False: no search, the window from the state given (from rest).
    `default_step`: the safety is the default one, so the search runs at SEARCH_SAFETY and the window
    at safety / WINDOW_REFINEMENT (a safety given steps everything at it). `progress`: told of every
    index cycle of a long chain's search (its accelerated one, above DENSE_LINK_LIMIT links; it does
    not change the search). `of` takes each default from its home."""

    predictor: str
    safety: float
    tol: float = DEFAULT_TOL
    max_cycles: int = DEFAULT_MAX_CYCLES
    steady_state: bool = True
    default_step: bool = True
    progress: SearchProgress | None = field(default=None, compare=False)

    @classmethod
    def of(cls, model, predictor: str | None = None, safety: float | None = None, **settings) -> SearchSettings:
        """`model`'s settings: its default predictor and safety (clearance_verlet.default_predictor,
        default_safety) where none is given; `settings` the other fields."""
        pred = verlet.default_predictor(model) if predictor is None else predictor
        saf = verlet.default_safety(model, pred) if safety is None else safety
        return cls(pred, saf, default_step=safety is None, **settings)


def _searched_and_settled(model, cam, h_out, per_cycle, state, search: SearchSettings):
    """(state, SteadyState or None, steps per output sample of the window): where the window starts.
    Given its step (not `search.default_step`): the relabelled steady state searched from `state` at
    `search.safety` (from rest: `state` itself). The default step: the window at safety /
    WINDOW_REFINEMENT, the steady state searched at SEARCH_SAFETY and settled at the window's step (a
    long chain's: to long_search_tol, then settled at `safety` (`_settle_substeps`: at the window's step
    above SETTLE_AT_WINDOW_STEP_ABOVE_DECAY) as `_settle_kind` says: one cycle, the
    search on to the same tolerance, or that tolerance by defect correction with coarse cycles, its
    coarse search stopped at machine_shooting.DEFECT_COARSE_TOL_FACTOR times it); a
    search that finds none is redone from `state` at the window's step to `tol` (the motion after
    max_cycles coarse cycles is not the fine step's)."""
    pred = search.predictor
    if not search.default_step:
        sub = mv.substeps_for(model, h_out, search.safety, pred)
        state, ss, _ = start_state(model, cam, h_out, per_cycle, sub, state, search)
        return state, ss, sub
    fine = mv.substeps_for(model, h_out, search.safety / WINDOW_REFINEMENT[model.span_damping], pred)
    done = None
    if search.steady_state:
        coarse = mv.substeps_for(model, h_out, SEARCH_SAFETY[model.span_damping], pred)
        long_chain = model.reduced_damping
        to = replace(search, tol=long_search_tol(model, cam, search.tol)) if long_chain else search
        settle = _settle_substeps(model, cam, h_out, search.safety, pred, fine) if long_chain else fine
        kind = _settle_kind(model, cam) if long_chain else "cycle"
        settled, found, ss = _SETTLES[kind](model, cam, h_out, per_cycle, (coarse, settle), state, to)
        if settled is not None:
            return settled, ss, fine
        if _coarse_substeps(model, h_out, fine, pred) == coarse:
            done = (found, ss.cycles)  # a long chain's search at `fine` starts with this same coarse search
    state, ss, _ = start_state(model, cam, h_out, per_cycle, fine, state, search, coarse_done=done)
    return state, ss, fine


def _settle_by_cycles(model, cam, h_out, per_cycle, steps, state, search):
    """The search at the coarse step of `steps` (coarse, settle substeps), then SETTLE_CYCLES plain
    cycles at the settle step: (the settled state or None when the search found none, the search's
    state, its SteadyState); `_SETTLES`' signature."""
    coarse, settle = steps
    found, ss, _ = start_state(model, cam, h_out, per_cycle, coarse, state, search)
    if not ss.found:
        return None, found, ss
    return _settled(model, cam, h_out, per_cycle, settle, found, search.predictor), found, ss


def _settle_by_search(model, cam, h_out, per_cycle, steps, state, search):
    """The search at the coarse step, carried to the settle step's fixed point by the same search to the
    same tolerance (its coarse part the one done)."""
    coarse, settle = steps
    found, ss, _ = start_state(model, cam, h_out, per_cycle, coarse, state, search)
    if not ss.found:
        return None, found, ss
    settled, ss, _ = start_state(model, cam, h_out, per_cycle, settle, found, search, (found, ss.cycles))
    return settled, found, ss


def _settle_by_defect_correction(model, cam, h_out, per_cycle, steps, state, search):
    """The coarse search, then the settle step's fixed point to the same tolerance with coarse cycles
    (machine_shooting.defect_corrected_periodic_state)."""
    coarse, settle = steps
    two = machine_shooting.defect_corrected_periodic_state(
        model,
        cam,
        (h_out / coarse, per_cycle * coarse),
        (h_out / settle, per_cycle * settle),
        *state,
        tol=search.tol,
        max_cycles=search.max_cycles,
        predictor=search.predictor,
        on_period=_observer(model, search),
    )
    ss = _steady_state(two.found, two.cycles, two.residual, search.tol)
    found = (two.q0, two.v0)
    return (found if two.settled is not None else None), found, ss


# how a coarse steady state is carried to the settle step's fixed point, by `_settle_kind`
_SETTLES = {
    "cycle": _settle_by_cycles,
    "search": _settle_by_search,
    "defect correction": _settle_by_defect_correction,
}


def _settle_kind(model, cam) -> str:
    """How a long chain's coarse steady state is carried to the default safety's fixed point, by its
    slowest mode's decay per cycle (machine_shooting.slowest_decay_per_cycle): "cycle" (SETTLE_CYCLES
    plain cycles) up to SETTLE_SEARCH_ABOVE_DECAY, "search" (the accelerated search at the default
    safety) up to SETTLE_DEFECT_CORRECTED_ABOVE_DECAY, "defect correction" above."""
    decay = machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s)
    # (the decay above which, the settle): the first row the decay exceeds; the bounds read when called
    by_decay = ((SETTLE_DEFECT_CORRECTED_ABOVE_DECAY, "defect correction"), (SETTLE_SEARCH_ABOVE_DECAY, "search"))
    return next((kind for above, kind in by_decay if decay > above), "cycle")


def _settle_substeps(model, cam, h_out, safety, predictor, fine) -> int:
    """Steps per output sample a long chain's steady state is settled at: the default `safety`'s, or
    the window's (`fine`) where the slowest mode keeps more than SETTLE_AT_WINDOW_STEP_ABOVE_DECAY of
    itself per cycle (machine_shooting.slowest_decay_per_cycle)."""
    if machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s) > SETTLE_AT_WINDOW_STEP_ABOVE_DECAY:
        return fine
    return mv.substeps_for(model, h_out, safety, predictor)


def long_search_tol(model, cam, tol: float) -> float:
    """The tolerance of a long chain's search at SEARCH_SAFETY (never tighter than `tol`): the change per
    cycle that leaves the state within about LONG_SEARCH_STATE_ERROR of the fixed point, given its
    slowest mode's decay per index cycle rho (machine_shooting.slowest_decay_per_cycle), never below
    LONG_SEARCH_TOL, up to LONG_SEARCH_STATE_ERROR_UP_TO_DECAY; above it within
    LONG_SEARCH_SLACK_STATE_ERROR, never below LONG_SEARCH_TOL_FLOOR."""
    decay = machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s)
    if decay > LONG_SEARCH_STATE_ERROR_UP_TO_DECAY:
        return max(tol, LONG_SEARCH_TOL_FLOOR, LONG_SEARCH_SLACK_STATE_ERROR * (1.0 - decay))
    return max(tol, LONG_SEARCH_TOL, LONG_SEARCH_STATE_ERROR * (1.0 - decay))


def _settled(model, cam, h_out, per_cycle, sub, state, predictor):
    """The steady state found at the search's step carried to the window's finer step: SETTLE_CYCLES
    index cycles with the seat change between them (the relabelled map contracts about 20x per
    cycle on the default scene: one cycle takes the coarse state to 1e-6 of the fine one)."""
    q0, v0, *_ = mv.relabelled_periodic_state(
        model, cam, h_out / sub, per_cycle * sub, *state, tol=0.0, max_cycles=SETTLE_CYCLES, predictor=predictor
    )
    return q0, v0


def _found(ss) -> bool:
    return ss is not None and ss.found


def start_state(model, cam, h_out, per_cycle, sub, state, search: SearchSettings, coarse_done=None):
    """(state, SteadyState or None, last cycle's run) of the relabelled steady state searched from
    `state` at `sub` steps per output sample to `search.tol` in `search.max_cycles` (with its
    predictor; its safety is `sub`'s); `state` itself when not `search.steady_state`. `coarse_done`:
    (state, cycles) of this search's coarse part (`_coarse_substeps`) already run from `state`, not run
    again: its end and the index cycles it stepped, which the SteadyState counts and the budget of
    `search.max_cycles` spends."""
    tol, max_cycles, predictor = search.tol, search.max_cycles, search.predictor
    if not search.steady_state:
        return state, None, None
    # long chains (the O(N) damping's range) cycle with Anderson acceleration: their slow low modes take
    # plain cycling dozens of cycles. Up to DENSE_LINK_LIMIT links plain cycling, as the default run's
    # numbers were computed (the accelerated search lands on the same fixed point to its tolerance,
    # which moves the 85-link station metrics by up to 6e-6 and the linear machine's minimum tension,
    # found to CHOICE_TOL, by up to 9e-5)
    find = mv.relabelled_periodic_state
    if model.reduced_damping:
        find = partial(machine_shooting.relabelled_periodic_state, on_period=_observer(model, search))
    coarse_cycles = 0
    coarse = _coarse_substeps(model, h_out, sub, predictor)
    if coarse_done is not None:
        state, coarse_cycles = coarse_done
    elif coarse is not None:
        # most of the search at the coarsest step the search takes, the rest at `sub` from there: the
        # two fixed points differ by the step's error only, and the state is accepted by the test at `sub`
        q0, v0, coarse_cycles, *_ = find(
            model, cam, h_out / coarse, per_cycle * coarse, *state, tol=tol, max_cycles=max_cycles, predictor=predictor
        )
        state = (q0, v0)
    q0, v0, cycles, residual, found, last = find(
        model,
        cam,
        h_out / sub,
        per_cycle * sub,
        *state,
        tol=tol,
        max_cycles=max(max_cycles - coarse_cycles, 1),
        predictor=predictor,
    )
    return (q0, v0), _steady_state(found, coarse_cycles + cycles, residual, tol), last


def _observer(model, search: SearchSettings):
    """The `on_period` of `model`'s search (None without `search.progress`): the linear machine's
    cycles counted apart from those of the machine with free play."""
    if search.progress is None:
        return None
    name = "with free play" if model.clearance_m > 0 else "of the linear machine"
    return search.progress.observer(name, search.tol)


def _steady_state(found: bool, cycles: int, residual: float, tol: float) -> SteadyState:
    if found:
        text = (
            f"relabelled periodic steady state found after {cycles} index cycles "
            f"(change per cycle {residual:.2g} <= {tol:g})"
        )
        return SteadyState(True, 1, cycles, residual, text)
    text = (
        f"NO relabelled periodic steady state found: after {cycles} index cycles the state still changes by "
        f"{residual:.2g} per cycle; the results are the motion after {cycles} cycles, not a steady state"
    )
    return SteadyState(False, None, cycles, residual, text)


def _coarse_substeps(model, h_out, sub, predictor) -> int | None:
    """Steps per output sample of a long chain's (the O(N) damping's) search before the one at `sub`:
    at SEARCH_SAFETY of the stability limit, where that is coarser than `sub` (None: no coarse search;
    up to DENSE_LINK_LIMIT links never, the default run's numbers as they were). The linear machine's
    search to CHOICE_TOL that decides the model is run at this step alone (`_choice_substeps`: measured
    at 1,000 links, its minimum tension there and at the default safety within 2e-6)."""
    if not model.reduced_damping or model.span_damping not in SEARCH_SAFETY:
        return None
    coarse = mv.substeps_for(model, h_out, SEARCH_SAFETY[model.span_damping], predictor)
    return coarse if coarse < sub else None


def _choice_substeps(linear, h_out, sub, search: SearchSettings) -> int:
    """Steps per output sample of the linear machine's search to CHOICE_TOL that decides the model:
    at SEARCH_SAFETY of the stability limit where that is coarser than `sub` (the step of the linear
    machine's window), for the default step at any length and for a long chain at any step
    (`_coarse_substeps`); else `sub`. Only the model choice, the linear machine's minimum tension and
    the start of the next search come from it, and each search is accepted at its own step. Measured
    on the default run (85 links, both materials, five cams; 3-4 steps per output sample instead of
    10): its minimum tension moved by 2.0e-5 of itself (CHOICE_TOL is 1e-3), the station metrics by
    at most 4.3e-7, the searches' cycles the same."""
    coarse = _coarse_substeps(linear, h_out, sub, search.predictor)
    if coarse is None and search.default_step:
        coarse = min(sub, mv.substeps_for(linear, h_out, SEARCH_SAFETY[linear.span_damping], search.predictor))
    return sub if coarse is None else coarse


def _window(model, cam, t, per_cycle, sub, state, predictor, periodic=False) -> _Window:
    """Index cycle after index cycle over the output samples, the seat change between cycles; a
    sample at a cycle's start is the state after the seat change. `periodic`: the state is the
    relabelled steady state (x0 = T(P(x0)) to its tolerance), so every cycle is the first one in
    the frame of places and is stepped once."""
    h_out = t[1] - t[0]
    h = h_out / sub
    zr, zd, zdd = mv.cycle_nodes(cam, h, per_cycle * sub)
    stations = station_dofs(model)
    q0, v0 = state
    rows_q, rows_v, rows_a, rows_t, runs, peaks = [], [], [], [], [], []
    moments = 0.0  # the window's (machine_verlet.step_moments), the displacement absolute
    lift_at_start = float(cam.svaj(np.array([0.0]))[0][0])  # the cycle's nodes count the lift from it
    seating = None
    remaining = t.size
    while remaining > 0:
        cycle_start_s = t[t.size - remaining]
        flags_at = _node_flags(cam, cycle_start_s, (remaining - 1) * h_out)
        if remaining == 1 and runs:  # the window ends at an index's start: the state after the seat change
            start = mv.integrate(
                model,
                zr[:2],
                zd[:2],
                zdd[:2],
                h,
                q0,
                v0,
                out_every=1,
                predictor=predictor,
                stations=stations,
                node_flags=flags_at(np.array([0.0, h])),
            )
            for rows, out in ((rows_q, start.q), (rows_v, start.v), (rows_a, start.a), (rows_t, start.tension_N)):
                rows.append(out[:1])
            peaks.append(start.station_peaks)
            break
        if not (periodic and runs):  # periodic: every cycle is the first, seat change included
            q_next, v_next, run, seating = mv.next_index_start(
                model,
                cam,
                (zr, zd, zdd),
                h,
                q0,
                v0,
                out_every=sub,
                predictor=predictor,
                stations=stations,
                flags_at=flags_at,
            )
            peaks.append(run.station_peaks)
        runs.append(run)
        take = min(per_cycle, remaining)
        for rows, out in ((rows_q, run.q), (rows_v, run.v), (rows_a, run.a), (rows_t, run.tension_N)):
            rows.append(out[:take])
        # the output intervals in the window: to the next cycle's first sample, or to the window's last
        intervals = take if remaining > take else take - 1
        lift = float(cam.svaj(np.array([cycle_start_s]))[0][0]) - lift_at_start
        moments = moments + mv.shifted_moments(run.station_moments[:intervals].sum(axis=0), lift)
        remaining -= take
        q0, v0 = q_next, v_next
    rows = (np.concatenate(r) for r in (rows_q, rows_v, rows_a, rows_t))
    return _Window(*rows, runs, seating, h, mv.merged_peaks(peaks), mv.station_rms(moments))


def station_dofs(model: ClearanceMachine) -> np.ndarray:
    """The DOF at each of the machine's four stations (places, Machine.stations(), in its order; -1: a
    place held to the cam), whose peaks the kernel tracks at every step."""
    return model.topology.link_dof()[list(model.machine.stations().values())]


def _node_flags(cam, cycle_start_s: float, window_left_s: float):
    """The node flags (machine_verlet.IN_WINDOW | IN_DWELL) at times since an index cycle's start at
    `cycle_start_s`: in the window up to `window_left_s` after it (the window's last sample), in a
    dwell where the cam's dwell mask says (every node counts as a dwell node when the cam has none,
    as dynamics.scene.station_values counts its samples)."""
    has_mask = hasattr(cam, "dwell_mask")

    def flags_at(since_s):
        since = np.asarray(since_s, dtype=float)
        inside = since <= window_left_s * (1.0 + 1e-12) + 1e-15
        dwell = cam.dwell_mask(cycle_start_s + since) if has_mask else np.ones(since.size, dtype=bool)
        return np.where(inside, mv.IN_WINDOW, 0) | np.where(dwell, mv.IN_DWELL, 0)

    return flags_at


def _link_spans(model: ClearanceMachine) -> np.ndarray:
    """For each link span j (link j to link j + 1), the topology span that carries it, or -1 inside a
    seated group."""
    groups = model.machine.groups if model.machine.drive == "wheels" else tuple((j,) for j in range(model.n_links))
    place_of = np.empty(model.n_links, dtype=int)
    for p, carried in enumerate(groups):
        place_of[list(carried)] = p
    out = np.full(model.n_links, -1)
    for j in range(model.n_links):
        nxt = (j + 1) % model.n_links
        if place_of[j] != place_of[nxt]:
            out[j] = place_of[j]  # span p joins place p to place p + 1
    return out


def _link_tensions(model: ClearanceMachine, span_tension: np.ndarray) -> np.ndarray:
    if model.seats:  # a tooth model: every link span is a span of its own
        return span_tension
    spans = _link_spans(model)
    out = np.empty((span_tension.shape[0], model.n_links))
    free = spans >= 0
    out[:, free] = span_tension[:, spans[free]]
    for ends in model.machine.wheel_ends:
        group = [j for j in model.machine.groups[ends.ahead_span][:-1]]
        out[:, group] = np.maximum(span_tension[:, [ends.behind_span]], span_tension[:, [ends.ahead_span]])
    return out


def _drive_force(model: ClearanceMachine, run: _Window, zdd: np.ndarray) -> np.ndarray:
    ends = model.machine.wheel_ends[0]
    if ends.dof is not None:
        return -model.topology.ground_vector()[ends.dof] * run.q[:, ends.dof]
    if model.seats:  # a held sprocket's tooth springs, -k_t (y - offset) on its seated links
        seated = list(model.seats[0][1])
        offsets = model.topology.n_dof + np.arange(len(seated))
        return -model.machine.tooth_stiffness_N_per_m * np.sum(run.q[:, seated] - run.q[:, offsets], axis=1)
    seated = len(model.machine.groups[0]) * model.chain.link_mass_kg
    return run.tension_N[:, ends.behind_span] - run.tension_N[:, ends.ahead_span] + seated * zdd


def _response(out: _Outcome, cam, links) -> ChainResponse:
    model, t, run = out.model, out.t_s, out.window
    s, v, a, _ = (np.asarray(x, dtype=float) for x in cam.svaj(t))
    cols = list(range(model.n_links)) if links is None else [int(i) for i in np.atleast_1d(links)]
    dof = model.topology.link_dof()[cols]
    held = dof < 0
    pick = np.where(held, 0, dof)

    def at_links(x):
        return np.where(held[None, :], 0.0, x[:, pick])

    tension = _link_tensions(model, run.tension_N)
    return ChainResponse(
        t_s=t,
        x_m=s[:, None] + at_links(run.q),
        v_m_s=v[:, None] + at_links(run.v),
        a_m_s2=a[:, None] + at_links(run.a),
        z_m=s,
        zdot_m_s=v,
        zddot_m_s2=a,
        tension_N=tension,
        drive_force_N=_drive_force(model, run, a),
        links=tuple(cols),
        min_tension_N=run.min_tension_N,
        slack=run.free_play_fraction > 0.0 or run.min_tension_N < 0.0,
        method="machine-verlet",
        diagnostics={
            "steps_per_output": out.steps_per_output,
            "step_s": run.step_s,
            "steady_state": out.steady_state,
            "carriage_m": run.q[:, -1] if model.tensioner is not None else None,
            "frame": "places (relabelled: each index moves every link one place ahead)",
            "station_peaks": _station_peaks(model, run),
            "station_rms": {
                name: dict(zip(mv.RMS_METRICS, (float(x) for x in row)))
                for name, row in zip(model.machine.stations(), run.station_rms)
            },
        },
    )


def _station_peaks(model: ClearanceMachine, run: _Window) -> dict[str, dict[str, float]] | None:
    """Per station (place) its peaks over every step (machine_verlet.PEAK_METRICS): the residual
    vibration, when no node of the window lies in a dwell, is the deviation's peak (as
    dynamics.scene.station_values then counts every sample)."""
    if run.station_peaks is None:
        return None
    out = {}
    for name, row in zip(model.machine.stations(), run.station_peaks):
        values = dict(zip(mv.PEAK_METRICS, (float(x) for x in row)))
        if np.isnan(values["residual_vibration_m"]):
            values["residual_vibration_m"] = values["max_deviation_m"]
        out[name] = values
    return out


def _free_play_fraction(model, chosen, run: _Window) -> float:
    """The clearance machine's share of span-time in free play; for the linear machine, as for the
    single-link drive, the share of its output span-samples below zero tension where there is free
    play to enter (0 without)."""
    if chosen.model == ChainModelKind.LINEAR:
        return float(np.mean(run.tension_N < 0.0)) if model.clearance_m > 0 else 0.0
    return run.free_play_fraction


def machine_lowest_mode(model: ClearanceMachine, cycle_s: float) -> LowestMode:
    """The machine's lowest natural mode under `model`'s damping law against the harmonics of an index
    cycle of cycle_s (dynamics.scene.LowestMode): the first of the machine's lowest modes, one cached
    eigensolve per machine (dynamics.solvers.machine_modes)."""
    frequency = machine_modes.lowest_frequency_Hz(model.machine)
    return lowest_mode(frequency, model.damping_ratio_at(2.0 * np.pi * frequency), cycle_s)


def machine_nearest_resonance(model: ClearanceMachine, cam, lowest: LowestMode) -> Resonance:
    """Of the machine's lowest NEAREST_RESONANCE_MODES modes (dynamics.solvers.machine_modes, the solve
    mode 1 of `lowest` came from) under `model`'s damping law, the one an index harmonic of `cam` drives
    hardest (dynamics.scene.nearest_resonance); `lowest` is mode 1's LowestMode (machine_lowest_mode),
    kept as it is."""
    frequencies = machine_modes.lowest_frequencies_Hz(model.machine)
    # mode 1's damping ratio is `lowest`'s, computed there
    ratios = [lowest.damping_ratio] + [model.damping_ratio_at(2.0 * np.pi * f) for f in frequencies[1:]]
    return nearest_resonance(frequencies, ratios, cam, lowest)


def machine_linear_validity(
    model: ClearanceMachine, min_tension_N: float, peak_tension_N: float
) -> LinearModelValidity | None:
    """LinearModelValidity of the linear machine's span forces over [min_tension_N, peak_tension_N], on
    the chain's links and the sprocket's pitch (None without a sprocket: the machine's link drive)."""
    sprocket = model.machine.sprocket
    if sprocket is None:
        return None
    return linear_model_validity(min_tension_N, peak_tension_N, model.chain.stiffness_N_per_m, sprocket.pitch_m)


def _summary(out: _Outcome, cam, step_error_estimate: float | None = None) -> ContactSummary:
    """The ContactSummary of a run: its modes are those of the machine that ran, under its damping law;
    `step_error_estimate` the step control's (simulate_machine_to_accuracy; None: the step not controlled)."""
    model, chosen, run = out.model, out.chosen, out.window
    lin_min, lin_peak = out.linear_tension_N
    mode = machine_lowest_mode(out.ran, cam.cycle_s)
    return ContactSummary(
        *chosen,
        model.clearance_m,
        run.free_play_fraction > 0.0 or run.min_tension_N < 0.0,
        _free_play_fraction(model, chosen, run),
        run.impacts / run.cycles,
        run.impact_force_spike_N,
        run.peak_tension_N,
        run.min_tension_N,
        max(model.chain.preload_N - lin_min, 0.0),
        lin_min,
        out.steady_state,
        out.steps_per_output,
        impacts=impact_statistics(run, run.cycles),
        seating=run.seating,
        step_error_estimate=step_error_estimate,
        peak_sampling="output samples" if run.station_peaks is None else "every step",
        lowest_mode=mode,
        nearest_resonance=machine_nearest_resonance(out.ran, cam, mode),
        linear_model_validity=machine_linear_validity(model, lin_min, lin_peak),
    )


def simulate_machine_to_accuracy(
    model: ClearanceMachine, cam, t_eval_s, *, accuracy: float, links=None, **options
) -> tuple[ChainResponse, ContactSummary]:
    """simulate_machine with its step halved (the stability-set safety halved: twice the steps per
    output sample) until the stations' metrics change by at most `accuracy`, as
    dynamics.scene.simulate_chain(accuracy=) does for the single-link drive: the last change is the
    error estimate (ContactSummary.step_error_estimate; the scheme is second order, so it is about 3x
    the error left at the finer step once in the asymptotic range). The SteadyState's cycles are every
    level's search's (SteadyState.cycles), as the single-link drive's step control counts them."""
    from dynamics.response.fidelity import relative_change
    from dynamics.scene import MAX_STEP_DOUBLINGS

    if not (0 < accuracy < 1):
        raise DynamicsError(f"accuracy: expected a relative error in (0, 1), got {accuracy!r}")
    pred = options.pop("predictor", None)
    pred = verlet.default_predictor(model) if pred is None else pred
    safety = options.pop("safety", None)
    safety = verlet.default_safety(model, pred) if safety is None else safety
    out = _run_machine(model, cam, t_eval_s, safety=safety, predictor=pred, **options)
    response = _response(out, cam, None)
    coarse = _station_values(model, cam, t_eval_s, response)
    estimate = np.inf
    for _ in range(MAX_STEP_DOUBLINGS):
        safety /= 2.0
        # each level runs afresh from rest; its SteadyState counts the coarser levels' search cycles too
        before = 0 if out.steady_state is None else out.steady_state.cycles
        level = _run_machine(model, cam, t_eval_s, safety=safety, predictor=pred, **options)
        out = _counting_cycles_before(level, before, options.get("tol", DEFAULT_TOL))
        response = _response(out, cam, None)
        fine = _station_values(model, cam, t_eval_s, response)
        estimate = relative_change(fine, coarse)
        if estimate <= accuracy:
            break
        coarse = fine
    return (response if links is None else _select(response, links)), _summary(out, cam, estimate)


def _counting_cycles_before(out: _Outcome, before: int, tol: float) -> _Outcome:
    """`out` with its SteadyState counting `before` index cycles more (the step control's coarser levels'
    searches: SteadyState.cycles), its statement saying so. Every search of a level with its safety
    given runs to `tol` (no long-chain tolerance: that is the default step's), and a statement without
    a steady state names no tolerance."""
    ss = out.steady_state
    if ss is None:
        return out
    return replace(out, steady_state=_steady_state(ss.found, before + ss.cycles, ss.residual, tol))


def _station_values(model: ClearanceMachine, cam, t_eval_s, response: ChainResponse) -> np.ndarray:
    """dynamics.scene.station_values of a machine's response at its four stations (places), its peaks
    and RMS those over every step (the response's diagnostics "station_peaks", "station_rms")."""
    cols = list(model.machine.stations().values())
    values = station_values(cam, np.asarray(t_eval_s, dtype=float), response.x_m, response.v_m_s, response.a_m_s2, cols)
    every_step = every_step_metrics(response)
    names = [f.name for f in fields(LinkMetrics)]
    blocks = values.reshape(len(names), len(cols))
    for i, name in enumerate(names):
        if name in mv.PEAK_METRICS or name in mv.RMS_METRICS:
            blocks[i] = [every_step[station][name] for station in model.machine.stations()]
    return blocks.ravel()


def every_step_metrics(response: ChainResponse) -> dict[str, dict[str, float]]:
    """Per station (place) the metrics the machine's kernel took over every step (ContactSummary.
    peak_sampling): its peaks and RMS (the response's diagnostics "station_peaks", "station_rms")."""
    peaks = response.diagnostics.get("station_peaks") or {}
    rms = response.diagnostics.get("station_rms") or {}
    return {name: {**peaks.get(name, {}), **rms.get(name, {})} for name in {**peaks, **rms}}
