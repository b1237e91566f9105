"""Where the clearance chain's explicit integrator holds and where it fails, and what its accuracy costs.

Stability map (`step_map`): one index cycle from rest (180 rpm, modified sine, 10 links, friction
0.35) per link stiffness k, pin clearance g and step h = factor x the stability limit h_max
(dynamics.solvers.clearance_verlet.stable_step_s with safety 1: omega_max h_max from the step's
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
the event-located reference (dynamics.clearance_reference, rtol 1e-10, the same sampled cam input),
error in the station links' displacement and acceleration versus wall time; the reference's own
cost at looser tolerances for comparison.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dynamics.cams import CamProgram
from dynamics.chain import ChainModel
from dynamics.clearance import ClearanceChain
from dynamics.errors import SolverDivergedError
from dynamics.solvers import clearance_verlet as verlet

OUTCOMES = ("accurate", "inaccurate", "diverged")
STEP_FACTORS = (0.5, 0.9, 0.99, 1.01, 1.1, 1.5, 2.0)
STIFFNESSES_N_PER_M = (1e7, 1e8, 1e9)
CLEARANCES_M = (0.0, 94e-6, 376e-6)


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


def _final(model: ClearanceChain, h: float, duration: float) -> np.ndarray:
    n_steps = max(int(round(duration / h)), 1)
    tf = h * np.arange(n_steps + 1)
    _, v, a, _ = _cam().svaj(tf)
    n = model.n_links
    run = verlet.integrate(model, v, a, h, np.zeros(n), -v[0] * np.ones(n), out_every=n_steps)
    return run.y[-1]


def step_case(stiffness_N_per_m: float, clearance_m: float, factor: float, *, n_links: int = 10,
              accuracy: float = 1e-2, n_limit_steps: int = 4000) -> StepCase:
    """One case of the map: n_limit_steps steps at the limit's length (about one index cycle at 1e8 N/m)."""
    chain = ChainModel(n_links=n_links, link_mass_kg=2.0, stiffness_N_per_m=stiffness_N_per_m,
                       friction_coefficient=0.35)
    model = ClearanceChain(chain, clearance_m)
    h_max = verlet.stable_step_s(model, safety=1.0)
    duration = n_limit_steps * h_max
    ref = _final(model, h_max / 64, duration)
    try:
        y = _final(model, factor * h_max, duration)
    except SolverDivergedError:
        return StepCase(stiffness_N_per_m, clearance_m, factor, factor * h_max, "diverged", np.nan)
    rel = float(np.max(np.abs(y - ref)) / np.max(np.abs(ref)))
    return StepCase(stiffness_N_per_m, clearance_m, factor, factor * h_max,
                    "accurate" if rel <= accuracy else "inaccurate", rel)


def step_map(stiffnesses=STIFFNESSES_N_PER_M, clearances=CLEARANCES_M, factors=STEP_FACTORS) -> list[StepCase]:
    return [step_case(k, g, f) for k in stiffnesses for g in clearances for f in factors]


@dataclass(frozen=True)
class WorkPoint:
    label: str  # "fast, 8 steps/sample" or "reference, rtol 1e-6"
    wall_s: float
    error_x: float  # max |y - y_ref| / max |y_ref| over every link and output
    error_a: float  # same for the acceleration relative to the cam


def work_precision(n_links: int = 20, substeps=(4, 8, 16, 32, 64), rtols=(1e-6, 1e-8)) -> list[WorkPoint]:
    """Fast integrator and looser references against the reference at rtol 1e-10 (default link's k
    and mass, 0.094 mm, friction 0.35, modal zeta 0.13, 180 degrees from rest, 4 samples/degree)."""
    from dynamics.clearance_reference import reference_response

    chain = ChainModel(n_links=n_links, link_mass_kg=2.03, stiffness_N_per_m=9.0092e7, friction_coefficient=0.35)
    model = ClearanceChain(chain, 94e-6)
    t = np.arange(721) / 4 / (6 * 180.0)
    cam = _cam()
    _, v, a, _ = cam.svaj(t)
    c = model.chain

    def reference(rtol):
        return reference_response(
            n_links=n_links, link_mass_kg=c.link_mass_kg, stiffness_N_per_m=c.stiffness_N_per_m,
            drive_stiffness_N_per_m=c.drive_stiffness, preload_N=c.preload_N, clearance_m=model.clearance_m,
            cam=cam, t_eval_s=t, damping_matrix=model.damping_matrix, friction_force_N=c.coulomb_force_N,
            friction_velocity_scale_m_s=c.friction_velocity_scale_m_s, rtol=rtol)

    ref = reference(1e-10)
    sx, sa = np.max(np.abs(ref.y_m)), np.max(np.abs(ref.yddot_m_s2))
    points = []
    for sub in substeps:
        tf = np.linspace(t[0], t[-1], sub * (t.size - 1) + 1)
        zd, zdd = np.interp(tf, t, v), np.interp(tf, t, a)
        verlet.integrate(model, zd, zdd, tf[1] - tf[0], np.zeros(n_links), -v[0] * np.ones(n_links), out_every=sub)
        start = time.perf_counter()
        run = verlet.integrate(model, zd, zdd, tf[1] - tf[0], np.zeros(n_links), -v[0] * np.ones(n_links),
                               out_every=sub)
        wall = time.perf_counter() - start
        points.append(WorkPoint(f"fast, {sub} steps/sample", wall, float(np.max(np.abs(run.y - ref.y_m)) / sx),
                                float(np.max(np.abs(run.a - ref.yddot_m_s2)) / sa)))
    for rtol in rtols:
        start = time.perf_counter()
        loose = reference(rtol)
        wall = time.perf_counter() - start
        points.append(WorkPoint(f"reference, rtol {rtol:g}", wall, float(np.max(np.abs(loose.y_m - ref.y_m)) / sx),
                                float(np.max(np.abs(loose.yddot_m_s2 - ref.yddot_m_s2)) / sa)))
    return points
