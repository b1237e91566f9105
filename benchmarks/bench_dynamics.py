"""Dynamics benchmark: the default solver against the report's scheme and against scipy solve_ivp.

The report's 85-link case: the 2012 script's model (dynamics.mqp2012: its units, damping, preload and
Dynacam cam table), 0..180 cam degrees at 180 rpm from rest, 181 one-degree outputs, for each of the 5
cams x 2 materials the pipeline runs (10 scenarios). Solved by
- report-rk45: the report's scheme, MATLAB ode45 (RelTol 1e-3, AbsTol 1e-6) restarted every degree;
- exact (the default solver): first-order-hold matrix exponential. Its one-off set-up per material
  (the exponential) is shared by the 5 cams: reported cold (first cam of a material, set-up
  included), warm (cached) and amortised (all 10 scenarios' time / 10);
- rk45 and radau: scipy solve_ivp over the whole interval, scipy's default tolerances (1e-3, 1e-6).
Linear (friction 0) so that the reference is exact: the exact method with every interval split in 4
(different rounding). Errors are max |x - x_ref| over links and outputs, converted to metres (the
script works in mm). A second table runs the report's own friction (0.35, sign law) for report-rk45
and exact; its reference is exact with 16 sub-steps (an estimate: the sign law is discontinuous).
Peak memory: tracemalloc peak of one scenario's solve (numpy/scipy arrays; LAPACK's internal
workspace is not counted), in a separate run from the timings.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np

from dynamics.mqp2012 import CAMS, MATERIALS, dynacam_table, preload_vector, replica_system
from dynamics.solvers import exact as exact_solver
from dynamics.solvers import solve
from dynamics.system import SampledForce

N_LINKS = 85
RPM = 180.0
MM = 1e-3


def report_case(material: str, cam: str, friction: float):
    """(system, force, t) of the report script's run for one material and cam (its mm units)."""
    system, c = replica_system(material, N_LINKS, friction)
    stiffness, _ = MATERIALS[material]
    t = np.arange(181) * ((60.0 / RPM) / 360.0)
    table = dynacam_table(cam, RPM)
    forces = np.tile(preload_vector(N_LINKS), (t.size, 1))
    forces[:, 0] = c[0] * table.v_mm_s + stiffness * table.s_mm
    return system, SampledForce(t, forces), t


def _solve(case, method, **opts):
    system, force, t = case
    zero = np.zeros(N_LINKS)
    return solve(system, force, t, method=method, x0=zero, v0=zero, **opts).x


def _timed(case, method, **opts):
    start = time.perf_counter()
    x = _solve(case, method, **opts)
    return x, time.perf_counter() - start


def _peak_memory_MB(case, method, clear_cache: bool, **opts) -> float:
    if clear_cache:
        exact_solver._cache.clear()
    tracemalloc.start()
    _solve(case, method, **opts)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 1e6


def _scenarios(quick: bool):
    materials = tuple(MATERIALS)
    return [(m, c) for m in materials for c in CAMS], (1 if quick else 10)


def run(quick: bool) -> list[str]:
    lines = []
    scenarios, n_slow = _scenarios(quick)
    lines += _linear_table(scenarios, n_slow)
    lines += _friction_table(scenarios[:1] if quick else scenarios[:2])
    return lines


def _linear_table(scenarios, n_slow: int) -> list[str]:
    cases = {s: report_case(*s, friction=0.0) for s in scenarios}
    refs = {s: _solve(cases[s], "exact", substeps=4) for s in scenarios}

    # default solver: cold = first cam of each material (set-up included), then warm from the cache
    exact_solver._cache.clear()
    exact_times, exact_errs, cold, warm = [], [], [], []
    seen = set()
    for s in scenarios:
        x, wall = _timed(cases[s], "exact")
        exact_times.append(wall)
        exact_errs.append(np.max(np.abs(x - refs[s])) * MM)
        (warm if s[0] in seen else cold).append(wall)
        seen.add(s[0])
    amortised = sum(exact_times) / len(exact_times)

    # the slow methods on the first n_slow scenarios (each is a separate, uncached computation)
    slow = {}
    for method, opts in (("report-rk45", {}), ("rk45", {"rtol": 1e-3, "atol": 1e-6}),
                         ("radau", {"rtol": 1e-3, "atol": 1e-6})):
        times, errs = [], []
        for s in scenarios[:n_slow]:
            x, wall = _timed(cases[s], method, **opts)
            times.append(wall)
            errs.append(np.max(np.abs(x - refs[s])) * MM)
        slow[method] = (float(np.mean(times)), float(np.max(errs)))

    first = cases[scenarios[0]]
    mem = {
        "exact (cold)": _peak_memory_MB(first, "exact", True),
        "exact (warm)": _peak_memory_MB(first, "exact", False),
        "report-rk45": _peak_memory_MB(first, "report-rk45", False),
        "rk45": _peak_memory_MB(first, "rk45", False, rtol=1e-3, atol=1e-6),
        "radau": _peak_memory_MB(first, "radau", False, rtol=1e-3, atol=1e-6),
    }
    rep_t, rep_e = slow["report-rk45"]
    out = [
        f"Report's 85-link case, linear (friction 0), {len(scenarios)} scenarios (cam x material), "
        f"181 one-degree outputs; slow methods timed on {n_slow} scenario(s)",
        f"{'method':34s} {'time/scenario':>14s} {'max error (m)':>14s} {'speed-up vs report':>19s} {'peak mem':>9s}",
        f"{'report-rk45 (ode45 restarted/deg)':34s} {rep_t * 1e3:11.2f} ms {rep_e:14.3g} {1.0:18.1f}x "
        f"{mem['report-rk45']:6.1f} MB",
    ]
    for label, wall in (("exact, amortised over scenarios", amortised), ("exact, cold (set-up included)",
                                                                          float(np.mean(cold))),
                        ("exact, warm (cached set-up)", float(np.mean(warm)) if warm else np.nan)):
        memory = mem["exact (cold)"] if "cold" in label or "amortised" in label else mem["exact (warm)"]
        out.append(f"{label:34s} {wall * 1e3:11.2f} ms {max(exact_errs):14.3g} {rep_t / wall:18.1f}x "
                   f"{memory:6.1f} MB")
    for method, label in (("rk45", "scipy RK45, whole interval"), ("radau", "scipy Radau, whole interval")):
        wall, err = slow[method]
        out.append(f"{label:34s} {wall * 1e3:11.2f} ms {err:14.3g} {rep_t / wall:18.1f}x {mem[method]:6.1f} MB")
    out.append("(scipy tolerances: rtol 1e-3, atol 1e-6 in the script's mm units; reference: exact, 4 sub-steps)")
    return out


def _friction_table(scenarios) -> list[str]:
    out = [f"\nReport's case with its friction (mu 0.35, sign law), {len(scenarios)} scenario(s); "
           "reference: exact, 16 sub-steps (estimate)"]
    rep_times, exact_times, rep_errs, exact_errs = [], [], [], []
    for s in scenarios:
        case = report_case(*s, friction=0.35)
        ref = _solve(case, "exact", substeps=16)
        exact_solver._cache.clear()
        x, wall = _timed(case, "exact")
        exact_times.append(wall)
        exact_errs.append(np.max(np.abs(x - ref)) * MM)
        x, wall = _timed(case, "report-rk45")
        rep_times.append(wall)
        rep_errs.append(np.max(np.abs(x - ref)) * MM)
    rep, ex = float(np.mean(rep_times)), float(np.mean(exact_times))
    out.append(f"{'report-rk45':34s} {rep * 1e3:11.2f} ms {max(rep_errs):14.3g}")
    out.append(f"{'exact (Heun splitting), cold':34s} {ex * 1e3:11.2f} ms {max(exact_errs):14.3g} {rep / ex:18.1f}x")
    return out
