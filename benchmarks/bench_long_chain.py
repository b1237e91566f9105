"""Long clearance chains (issue 24): N = 100 .. 10,000 links with clearance, time, memory, the check
against the dense damping.

    python benchmarks/run.py --only long_chain

Each N: the default scene's link (aluminium FEA k and lumped mass, friction 0.35), 0.094 mm free play,
180 rpm modified sine, the pipeline's output grid (180 degrees at 4 per degree), `simulate_chain` with
the model chosen automatically and the linear chain solved as the pipeline does (its 400 lowest
modes above 400 links), the global damping law dense up to 400 links and in its O(N) form above.
Every N runs in its own process (python benchmarks/bench_long_chain.py N): time is the wall
seconds of the scenario (numba cache warm, after a 40-link warm-up run), split into the linear chain
and the rest; memory is the process's peak resident set (ru_maxrss) minus its resident set before
the scenario (the table shows both: the peak, and in brackets what the scenario added). Check: where
the dense damping runs (N <= 400), the same run with the O(N) form at its default 1e-4, the worst
relative difference of the 20 station metrics. With BENCH_LONG_CHAIN_OLD_TREE set to a checkout of the
old code, each N also runs with that code, in the same benchmark run.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script in a subprocess
    sys.path.insert(0, str(ROOT))

KEYS = (
    "rms_displacement_m",
    "rms_velocity_m_s",
    "rms_acceleration_m_s2",
    "max_abs_acceleration_m_s2",
    "residual_vibration_m",
)
SIZES = (100, 400, 1000, 2000, 10000)
# Above this the steady-state search is not run (10,000 links: 10 s per cam cycle on a loaded 2-core
# machine, times the cycles the search takes, 18 at 2,000 links): the window alone is timed (two cam
# cycles from the linear chain's periodic state), with its time per cam cycle.
STEADY_STATE_UP_TO = 2000
TARGETS_S = {1000: 2.0, 10000: 20.0}
# A checkout of the old code (e.g. `git worktree add /tmp/old main`): each N is run with it too, in
# the same benchmark run, one row below the new one.
OLD_TREE_VARIABLE = "BENCH_LONG_CHAIN_OLD_TREE"


def _rss_MB() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def _scenario(n: int, damping_tolerance=None, steady_state=True) -> dict:
    """One scenario in this process: times, memory, the summary and the station metrics."""
    from benchmarks.defaults import DEFAULT_RUN, MATERIALS, PITCH_M
    from dynamics import scene
    from dynamics.cams import CamProgram
    from dynamics.models.chain import ChainModel
    from dynamics.models.clearance import ClearanceChain
    from dynamics.models.reduction import modes_to_keep
    from dynamics.response.metrics import link_metrics, station_links
    from stages.chain import output_times_s

    k, mass = MATERIALS["al6061-t6"]

    def run(links, tolerance, steady):
        chain = ChainModel(
            n_links=links, link_mass_kg=mass, stiffness_N_per_m=k, friction_coefficient=DEFAULT_RUN.friction
        )
        model = ClearanceChain(chain, DEFAULT_RUN.pin_clearance_m, damping_tolerance=tolerance)
        t = output_times_s(DEFAULT_RUN.rpm, DEFAULT_RUN.samples_per_degree)
        cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=DEFAULT_RUN.rpm)
        cols = [link - 1 for link in station_links(links).values()]
        clock = {"linear": 0.0}
        inner = scene.simulate

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return inner(*args, **kwargs)
            finally:
                clock["linear"] += time.perf_counter() - start

        scene.simulate = timed  # the linear chain's share of the time
        try:
            start = time.perf_counter()
            r, contact = scene.simulate_chain(
                model, cam, t, n_modes=modes_to_keep(links), links=cols, steady_state=steady
            )
            wall = time.perf_counter() - start
        finally:
            scene.simulate = inner
        lm = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, cam.dwell_mask(t))
        values = [[float(getattr(lm, k)[i]) for k in KEYS] for i in range(len(cols))]
        return wall, clock["linear"], contact, values

    run(40, None, True)  # compile / load the numba cache
    run(40, 1e-4, True)
    before = _rss_MB()
    wall, lin, contact, values = run(n, damping_tolerance, steady_state)
    ss = contact.steady_state
    return {
        "wall_s": wall,
        "linear_s": lin,
        "added_MB": _rss_MB() - before,
        "peak_MB": _rss_MB(),
        "model": str(contact.model),
        "steps_per_output": contact.steps_per_output,
        "found": None if ss is None else ss.found,
        "cycles": 0 if ss is None else ss.cycles,
        "values": values,
    }


def _in_subprocess(n: int, damping_tolerance=None, steady_state=True, tree: Path = ROOT) -> dict:
    """The scenario in a fresh process, with the code of `tree` (a checkout of the project)."""
    # the tree's own script, so that nothing of this tree is imported in the old tree's process
    script = Path(tree) / "benchmarks" / Path(__file__).name
    args = [sys.executable, str(script), str(n), json.dumps(damping_tolerance), json.dumps(steady_state), str(tree)]
    out = subprocess.run(args, capture_output=True, text=True, check=True, cwd=tree)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _row(n, res, form, check, steady, label="") -> str:
    cycles = res["cycles"] + 2  # the window is two cam cycles
    per_cycle = (res["wall_s"] - res["linear_s"]) / cycles
    target = TARGETS_S.get(n)
    mark = "" if target is None else f" (target {target:g} s: {'met' if res['wall_s'] <= target else 'NOT met'})"
    state = (
        f"{'found' if res['found'] else 'NOT found'} after {res['cycles']} cycles"
        if steady
        else "not searched (window only)"
    )
    return (
        f"| {n}{label} | {res['model']} | {form} | {res['wall_s']:.2f} s{mark} | {res['linear_s']:.2f} s | "
        f"{per_cycle:.2f} s | {res['peak_MB']:.0f} MB (+{res['added_MB']:.0f}) | {state} | "
        f"{res['steps_per_output']} | {check} |"
    )


def run(quick: bool) -> list[str]:
    from dynamics.options import DEFAULT_PIN_CLEARANCE_M

    sizes = SIZES[:3] if quick else SIZES
    lines = [
        "Long clearance chains, one scenario each in its own process (default link, "
        f"{DEFAULT_PIN_CLEARANCE_M * 1e3:g} mm, 180 rpm); the "
        "global damping law in its O(N) form above 400 links (dynamics/models/reduced_damping.py)",
        "",
        "| N | model | damping form | time (whole scenario) | of which linear chain | clearance chain per cam "
        "cycle | peak RSS (added) | steady state | steps/sample | check vs dense C |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    old = os.environ.get(OLD_TREE_VARIABLE)
    for n in sizes:
        steady = n <= STEADY_STATE_UP_TO
        res = _in_subprocess(n, None, steady)
        form = "O(N), 1e-4" if n > 400 else "dense"
        check = "-"
        if n <= 400:
            reduced = _in_subprocess(n, 1e-4, steady)
            a, b = np.array(res["values"]), np.array(reduced["values"])
            check = f"O(N) form: worst station metric {np.max(np.abs(b - a) / np.abs(a)):.1e}"
        lines.append(_row(n, res, form, check, steady))
        if old:
            lines.append(_row(n, _in_subprocess(n, None, steady, Path(old)), form, "-", steady, " (old tree)"))
    return lines


if __name__ == "__main__":
    if len(sys.argv) == 5:
        sys.path.insert(0, sys.argv[4])  # the tree whose code runs the scenario
        result = _scenario(int(sys.argv[1]), json.loads(sys.argv[2]), json.loads(sys.argv[3]))
        print(json.dumps(result))
    else:
        print("\n".join(run(quick=False)))
