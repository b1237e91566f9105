"""The whole default job from an empty FEA cache: wall time and peak memory per stage (issue #24).

    python benchmarks/bench_whole_job.py [--repeats 3] [--old-tree DIR] [-- PIPELINE OPTIONS]

Runs `python pipeline.py --cache-dir EMPTY --out TMP` of this tree (and, with `--old-tree DIR`, of
another checkout, e.g. `git worktree add --detach /tmp/old main`) in fresh processes, the trees
alternating, each run with its own empty cache, after one untimed run of each tree at coarse FEA
levels (numba compiles and caches its kernels in the tree on its first run), and prints the
medians over `--repeats` runs:

- wall time per stage, from the run's own progress lines (`[  t s] ...`): start-up (interpreter
  and imports, before the run's clock starts), stiffness (the k levels, up to their `FEA level`
  lines), stress study (up to the last `stress level` line), rest of the FEA (deformed images,
  cache), dynamics, outputs (tables, figures, report), and the whole process;
- peak memory per stage: the largest resident set of the run's process sampled every 20 ms while
  the stage ran, and beside it the resident sets of its child processes (the outputs stage's
  figure workers, forked: their shared copy-on-write pages are counted in both, so the sum
  overstates the memory used); the whole run's peak from the OS (`ru_maxrss` of `wait4`, the
  largest single process of the run).

With `--study-point`, also the FEA of one design point of `python -m study` at the default
settings, as a study's worker runs it (`stages.fea.run_fea` with the levels one after the other, no
images, an empty cache; both materials, stiffness and stress study), in a fresh process per tree,
with its k and converged stress.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parent.parent
STAGES = ("start-up", "stiffness", "stress study", "rest of FEA", "dynamics", "outputs")
LINE = re.compile(r"^\[\s*([0-9.]+) s\] (.*)$")
SAMPLE_S = 0.02
WARM_UP_MESH_SIZE_MM = "12"  # a cheap FEA for the untimed first run of each tree


@dataclass
class Run:
    """One run: each stage's wall time (s) and peak resident memory (bytes) of the process and its children."""

    wall_s: dict[str, float] = field(default_factory=dict)
    rss: dict[str, int] = field(default_factory=dict)
    child_rss: dict[str, int] = field(default_factory=dict)
    total_s: float = 0.0
    maxrss: int = 0


def stage_of(message: str, current: str) -> str:
    """The stage a progress line ends (the stage after it is the next one's)."""
    if message.startswith("FEA level"):
        return "stiffness"
    if message.startswith("stress level"):
        return "stress study"
    if message.startswith("FEA ") and " k = " in message:
        return "rest of FEA"
    if message.startswith("dynamics"):
        return "dynamics"
    if message.startswith("done"):
        return "outputs"
    return current


def run_once(tree: Path, extra: list[str]) -> Run:
    with tempfile.TemporaryDirectory(prefix="whole-job-") as tmp:
        command = [sys.executable, "pipeline.py", "--cache-dir", f"{tmp}/cache", "--out", f"{tmp}/out", *extra]
        env = {**os.environ, "PYTHONPATH": str(tree)}
        start = time.perf_counter()
        proc = subprocess.Popen(command, cwd=tree, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        run = Run()
        state = {"stage": "start-up", "ended": {}}
        done = threading.Event()
        threading.Thread(target=_sample, args=(proc.pid, state, run, done), daemon=True).start()
        clock_start = None
        for line in proc.stdout:
            match = LINE.match(line)
            if not match:
                continue
            t, message = float(match.group(1)), match.group(2)
            if clock_start is None:  # the run's clock starts after its imports
                clock_start = time.perf_counter() - start - t
                state["ended"]["start-up"] = clock_start
                state["stage"] = "stiffness"
            ended = stage_of(message, "")
            if ended:
                state["ended"][ended] = clock_start + t
                following = STAGES.index(ended) + 1
                if following < len(STAGES):
                    state["stage"] = STAGES[following]
        _, status, usage = os.wait4(proc.pid, 0)
        run.total_s = time.perf_counter() - start
        done.set()
        if status != 0:
            raise SystemExit(f"{tree}: pipeline.py failed (status {status})")
        run.maxrss = usage.ru_maxrss * 1024
        previous = 0.0
        for stage in STAGES:
            end = state["ended"].get(stage, previous)
            run.wall_s[stage] = end - previous
            previous = end
        return run


def _sample(pid: int, state: dict, run: Run, done: threading.Event) -> None:
    try:
        process = psutil.Process(pid)
        while not done.is_set():
            stage = state["stage"]
            rss = process.memory_info().rss
            children = sum(_rss(c) for c in process.children(recursive=True))
            run.rss[stage] = max(run.rss.get(stage, 0), rss)
            run.child_rss[stage] = max(run.child_rss.get(stage, 0), children)
            time.sleep(SAMPLE_S)
    except psutil.Error:  # the run ended between two samples
        return


def _rss(process: psutil.Process) -> int:
    try:
        return process.memory_info().rss
    except psutil.Error:
        return 0


STUDY_POINT = """
import dataclasses, json, resource, sys, tempfile, time
from pathlib import Path
from settings import RunConfig
from stages.fea import run_fea
from stages.progress import Progress
with tempfile.TemporaryDirectory() as tmp:
    cfg = dataclasses.replace(RunConfig(), images=False, cache_dir=Path(tmp))
    start = time.perf_counter()
    fea = run_fea(cfg, Progress(True), concurrent_levels=False)
    wall = time.perf_counter() - start
print(json.dumps({"wall_s": wall, "maxrss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                  "k": {m: f.stiffness_N_per_m for m, f in fea.items()},
                  "k_estimate": {m: f.stiffness_rel_error_estimate for m, f in fea.items()},
                  "stress": {m: f.peak_von_mises_converged_Pa_per_N for m, f in fea.items()},
                  "stress_estimate": {m: f.peak_von_mises_converged_rel_change for m, f in fea.items()}}))
"""


def study_point(tree: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run(
        [sys.executable, "-c", STUDY_POINT], cwd=tree, env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def study_point_lines(points: dict[str, list[dict]]) -> list[str]:
    lines = [
        "| tree | study point FEA wall (s), median (runs) | peak MB | material: k (estimate), converged stress MPa/kN (estimate) |"
    ]
    lines.append("|---|---|---|---|")
    for name, runs in points.items():
        walls = ", ".join(f"{r['wall_s']:.1f}" for r in runs)
        last = runs[-1]
        answers = "; ".join(
            f"{m}: {last['k'][m]:.5g} N/m ({100 * last['k_estimate'][m]:.2g} %), "
            f"{last['stress'][m] / 1e3:.4g} ({100 * last['stress_estimate'][m]:.2g} %)"
            for m in last["k"]
        )
        wall = statistics.median(r["wall_s"] for r in runs)
        peak = statistics.median(r["maxrss"] for r in runs) / 1e6
        lines.append(f"| {name} | **{wall:.2f}** ({walls}) | {peak:.0f} | {answers} |")
    return lines


def _median(runs: list[Run], get) -> float:
    return statistics.median(get(r) for r in runs)


def report(results: dict[str, list[Run]]) -> list[str]:
    names = list(results)
    header = "| stage | " + " | ".join(f"{n}: wall (s) | {n}: peak MB (children)" for n in names) + " |"
    lines = [header, "|" + "---|" * (1 + 2 * len(names))]
    for stage in STAGES:
        cells = []
        for runs in results.values():
            cells.append(f"{statistics.median(r.wall_s.get(stage, 0.0) for r in runs):.2f}")
            rss = statistics.median(r.rss.get(stage, 0) for r in runs) / 1e6
            kids = statistics.median(r.child_rss.get(stage, 0) for r in runs) / 1e6
            cells.append(f"{rss:.0f}" + (f" ({kids:.0f})" if kids else ""))
        lines.append(f"| {stage} | " + " | ".join(cells) + " |")
    cells = []
    for runs in results.values():
        walls = ", ".join(f"{r.total_s:.1f}" for r in runs)
        cells.append(f"**{_median(runs, lambda r: r.total_s):.2f}** ({walls})")
        cells.append(f"**{_median(runs, lambda r: r.maxrss) / 1e6:.0f}** (ru_maxrss)")
    lines.append("| whole job | " + " | ".join(cells) + " |")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old-tree", type=Path, help="another checkout to time beside this one")
    parser.add_argument("--study-point", action="store_true", help="also time one study point's FEA")
    parser.add_argument("pipeline_options", nargs="*", help="passed to pipeline.py (after --)")
    args = parser.parse_args(argv)
    trees = {"new": ROOT} | ({"old": args.old_tree.resolve()} if args.old_tree else {})
    results: dict[str, list[Run]] = {name: [] for name in trees}
    for tree in trees.values():  # compile and cache each tree's numba kernels first (not timed)
        run_once(tree, [*args.pipeline_options, "--mesh-size", WARM_UP_MESH_SIZE_MM])
    for repeat in range(args.repeats):
        for name, tree in trees.items() if repeat % 2 == 0 else reversed(trees.items()):
            run = run_once(tree, args.pipeline_options)
            results[name].append(run)
            print(f"run {repeat + 1} {name}: {run.total_s:.1f} s, {run.maxrss / 1e6:.0f} MB", flush=True)
    print(f"medians of {args.repeats} runs from an empty FEA cache, trees alternating; cores: {os.cpu_count()}")
    print("\n".join(report(results)))
    if args.study_point:
        points: dict[str, list[dict]] = {name: [] for name in trees}
        for repeat in range(args.repeats):
            for name, tree in trees.items() if repeat % 2 == 0 else reversed(trees.items()):
                points[name].append(study_point(tree))
                print(f"study point {repeat + 1} {name}: {points[name][-1]['wall_s']:.1f} s", flush=True)
        print("\n".join(study_point_lines(points)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
