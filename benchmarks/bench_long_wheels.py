"""Long clearance chains on wheels (issue #24): N = 100 .. 10,000 links, the pipeline's scenario on
the machine on its wheels with clearance and steady state: time, memory, steady-state cycles, the
check against the dense damping.

    python benchmarks/run.py --only long_wheels
    BENCH_LONG_CHAIN_OLD_TREE=/tmp/old python benchmarks/run.py --only long_wheels   # old code beside
    python benchmarks/bench_long_wheels.py --links 1000 --old-tree /tmp/old [--repeats 3]   # one N, both trees

Each N: the default scene (default wheels: 12-tooth sprocket and idler wheel, 6 links seated on each,
the report's drive stiffness, polygonal feed), the default link's figures (benchmarks.defaults.MATERIALS,
friction 0.35, preload 2224 N, zeta 0.13), 0.094 mm free play, 180 rpm modified sine, the pipeline's
output grid (180 degrees at 4 per degree), `dynamics.scene.simulate_scene` with `--model auto` and
steady state, plus the machine's lowest natural frequencies (both are what the pipeline's dynamics
stage does per cam and material). Every run is its own process (python
benchmarks/bench_long_wheels.py N FORCE_O_N TREE): time is the wall and the CPU seconds (the
process's, time.process_time: on a shared machine the wall is the load's) of the scenario after a
40-link warm-up (numba cache warm), the median of REPEATS runs (one above 2,000 links), the load
average at the start of each N beside them; memory the
process's peak resident set (ru_maxrss) and what the scenario added to it. Check: where the dense
damping runs (N <= 400) the same run with the O(N) form forced, the worst relative difference of
the 20 station metrics; from there to SINGLE_PRECISION_FACTORS_ABOVE_LINKS the same run with the
O(N) form's factors in single precision (what longer chains take) against the double ones. With
BENCH_LONG_CHAIN_OLD_TREE set to a checkout of the old code, each N
also runs once with that code, in the same benchmark run, stopped after OLD_TIMEOUT_S.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script in a subprocess
    sys.path.insert(0, str(ROOT))

from benchmarks.bench_long_chain import KEYS, OLD_TREE_VARIABLE, SIZES, TARGETS_S, _rss_MB  # noqa: E402 (after sys.path)
from benchmarks.defaults import MATERIALS, PITCH_M  # noqa: E402

REPEATS = 3
REPEATED_UP_TO = 2000
# the old code at 10,000 links took 256 s of wall at load 10 (e143626)
OLD_TIMEOUT_S = 600.0
# the scenario's FORCE_O_N that also takes the O(N) form's factors in single precision (checked
# against the double factors where the default keeps them)
SINGLE_FACTORS = "single-factors"


def long_scene(links: int):
    """(chain, scene, cam, output times) of the scenario at `links` links: the default run on its
    wheels with the default link's FEA figures (aluminium), 180 rpm modified sine."""
    from dynamics.cams import CamProgram
    from dynamics.models.chain import ChainModel
    from settings import RunConfig
    from stages.chain import chain_scene, output_times_s

    k, mass = MATERIALS["al6061-t6"]
    cfg = RunConfig(links=links, drive="wheels")
    chain = ChainModel(
        links, mass, k, damping_ratio=cfg.damping, preload_N=cfg.preload_N, friction_coefficient=cfg.friction
    )
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=cfg.rpm)
    return chain, chain_scene(cfg, PITCH_M), cam, output_times_s(cfg.rpm, cfg.samples_per_degree)


def _scenario(n: int, force_o_n: bool) -> dict:
    """One scenario in this process: time, memory, the summary and the station metrics."""
    from dynamics.models import clearance_machine, machine_damping
    from dynamics.response.metrics import link_metrics
    from dynamics.scene import simulate_scene
    from stages.chain import natural_frequencies_Hz
    from stages.machine import machine_parts

    if force_o_n:
        clearance_machine.DENSE_LINK_LIMIT = 0
    if force_o_n == SINGLE_FACTORS:
        machine_damping.SINGLE_PRECISION_FACTORS_ABOVE_LINKS = 0

    def run(links):
        chain, scene, cam, t = long_scene(links)
        cols = [link - 1 for link in machine_parts(scene, chain).stations.values()]
        start, start_cpu = time.perf_counter(), time.process_time()
        r, contact = simulate_scene(scene, chain, cam, t, links=cols)
        natural_frequencies_Hz(scene, chain)
        wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
        lm = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, cam.dwell_mask(t))
        values = [[float(getattr(lm, k)[i]) for k in KEYS] for i in range(len(cols))]
        return wall, cpu, contact, values

    run(40)  # compile / load the numba cache
    before = _rss_MB()
    wall, cpu, contact, values = run(n)
    ss = contact.steady_state
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "added_MB": _rss_MB() - before,
        "peak_MB": _rss_MB(),
        "model": str(contact.model),
        "validity": str(contact.validity),
        "steps_per_output": contact.steps_per_output,
        "found": ss.found,
        "cycles": ss.cycles,
        "values": values,
    }


def _in_subprocess(n: int, force_o_n: bool = False, tree: Path = ROOT, timeout=None) -> dict | None:
    """The scenario in a fresh process with the code of `tree`; None when stopped at `timeout`."""
    # the tree's own script: this one imports this tree's code before it could put `tree` first
    args = [
        sys.executable,
        str(Path(tree) / "benchmarks" / Path(__file__).name),
        str(n),
        json.dumps(force_o_n),
        str(tree),
    ]
    env = dict(os.environ, PYTHONPATH=str(tree))
    try:
        out = subprocess.run(args, capture_output=True, text=True, check=True, cwd=tree, env=env, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def _median_run(n: int, repeats: int, **options) -> dict | None:
    runs = [_in_subprocess(n, **options) for _ in range(repeats)]
    if any(r is None for r in runs):
        return None
    out = dict(runs[len(runs) // 2])
    out["wall_s"] = statistics.median(r["wall_s"] for r in runs)
    out["cpu_s"] = statistics.median(r["cpu_s"] for r in runs)
    out["cpu_runs"] = [r["cpu_s"] for r in runs]
    out["runs"] = len(runs)
    return out


def _row(n, res, form, check, label="") -> str:
    if res is None:
        return f"| {n}{label} | - | {form} | not finished in {OLD_TIMEOUT_S:.0f} s | - | - | - | - | - |"
    target = TARGETS_S.get(n)
    mark = "" if target is None else f" (target {target:g} s: {'met' if res['cpu_s'] <= target else 'NOT met'})"
    state = f"{'found' if res['found'] else 'NOT found'} after {res['cycles']} index cycles"
    runs = (
        f"median of {res['runs']} ({', '.join(f'{c:.2f}' for c in res['cpu_runs'])})" if res["runs"] > 1 else "one run"
    )
    return (
        f"| {n}{label} | {res['model']} ({res['validity']}) | {form} | {res['cpu_s']:.2f} s{mark}, {runs} | "
        f"{res['wall_s']:.2f} s | {res['peak_MB']:.0f} MB (+{res['added_MB']:.0f}) | {state} | "
        f"{res['steps_per_output']} | {check} |"
    )


def run(quick: bool) -> list[str]:
    # imported here: the scenario's subprocess puts its tree first on sys.path before importing dynamics
    from dynamics.models.machine_damping import SINGLE_PRECISION_FACTORS_ABOVE_LINKS
    from dynamics.options import DEFAULT_PIN_CLEARANCE_M

    sizes = SIZES[:3] if quick else SIZES
    lines = [
        "Long clearance chains on wheels, the pipeline's scenario (default wheels and link, "
        f"{DEFAULT_PIN_CLEARANCE_M * 1e3:g} mm, 180 rpm, "
        "steady state) plus the lowest natural frequencies; the global damping dense up to 400 links, its O(N) "
        "form above (dynamics/models/machine_damping.py; its factors in single precision above "
        f"{SINGLE_PRECISION_FACTORS_ABOVE_LINKS} links)",
        "",
        "| N | model | damping form | CPU (scenario) | wall | peak RSS (added) | steady state | steps/sample | "
        "check vs dense C |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    old = os.environ.get(OLD_TREE_VARIABLE)
    for n in sizes:
        repeats = 1 if (quick or n > REPEATED_UP_TO) else REPEATS
        load = os.getloadavg()[0]
        res = _median_run(n, repeats)
        form = "O(N), 1e-5" if n > 400 else "dense"
        if n > SINGLE_PRECISION_FACTORS_ABOVE_LINKS:
            form += ", single-precision factors"
        check = "-"
        if n <= 400:
            reduced = _in_subprocess(n, True)
            a, b = np.array(res["values"]), np.array(reduced["values"])
            check = f"O(N) form: worst station metric {np.max(np.abs(b - a) / np.abs(a)):.1e}"
        elif n <= SINGLE_PRECISION_FACTORS_ABOVE_LINKS:
            single = _in_subprocess(n, SINGLE_FACTORS)
            a, b = np.array(res["values"]), np.array(single["values"])
            check = f"single-precision factors: worst station metric {np.max(np.abs(b - a) / np.abs(a)):.1e}"
        lines.append(_row(n, res, form, check))
        if old:
            old_res = _median_run(n, 1, tree=Path(old), timeout=OLD_TIMEOUT_S)
            lines.append(_row(n, old_res, "as the old tree's", "-", " (old tree)"))
        lines.append(f"| {n}: load average {load:.1f} at the start | | | | | | | | |")
    return lines


def compare_trees(n: int, old_tree: Path, repeats: int = 1, scenario=_in_subprocess) -> list[str]:
    """The scenario at `n` links with this tree's code and `old_tree`'s, each in its own process, the
    trees alternating `repeats` times: one line per run (wall and CPU seconds), then the medians."""
    trees = {"new": ROOT, "old": Path(old_tree)}
    runs: dict[str, list[dict]] = {name: [] for name in trees}
    lines = []
    for i in range(repeats):
        for name, tree in trees.items():
            res = scenario(n, tree=tree)
            runs[name].append(res)
            lines.append(f"run {i + 1}, {name} ({tree}): wall {res['wall_s']:.2f} s, CPU {res['cpu_s']:.2f} s")
    for name, done in runs.items():
        wall = statistics.median(r["wall_s"] for r in done)
        cpu = statistics.median(r["cpu_s"] for r in done)
        lines.append(f"{name}: median of {len(done)}: wall {wall:.2f} s, CPU {cpu:.2f} s, {n} links")
    return lines


def _compare_main(argv: list[str]) -> None:
    import argparse

    parser = argparse.ArgumentParser(description="the scenario at one N, this tree beside an old checkout")
    parser.add_argument("--links", type=int, required=True)
    parser.add_argument("--old-tree", type=Path, required=True, help="a checkout of the old code")
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args(argv)
    print("\n".join(compare_trees(args.links, args.old_tree, args.repeats)))


if __name__ == "__main__":
    if len(sys.argv) == 4 and not sys.argv[1].startswith("--"):
        sys.path.insert(0, sys.argv[3])  # the tree whose code runs the scenario
        print(json.dumps(_scenario(int(sys.argv[1]), json.loads(sys.argv[2]))))
    elif len(sys.argv) > 1:
        _compare_main(sys.argv[1:])
    else:
        print("\n".join(run(quick=False)))
