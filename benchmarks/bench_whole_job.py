"""The whole default job from an empty FEA cache: wall time per stage and peak memory (issue #24).

    python benchmarks/bench_whole_job.py [--repeats 3] [--old-tree DIR] [--study-point] [-- PIPELINE OPTIONS]

Runs `python pipeline.py --cache-dir EMPTY --out TMP` of this tree (and, with `--old-tree DIR`, of
another checkout, e.g. `git worktree add --detach DIR main`) in fresh processes, the trees
alternating, each run with its own empty cache, after one untimed run of each tree at coarse FEA
levels (numba compiles and caches its kernels in the tree on its first run, Python writes the
modules' bytecode outside the trees: `child_env`), and prints the medians over `--repeats` runs of:

- each stage's wall time, from the run's own progress lines (`[  t s] ...`), as the span from the
  line that ends the stage before it on the same path to the line that ends it. Since the FEA runs
  in a process beside the dynamics and the figures (stages.beside), stages overlap: the FEA's path
  is stiffness (to the last `FEA level` line), stress study (to the last `stress level` line),
  rest of the FEA (images, cache: to the FEA's last line, `FEA ...: k =` in a one-process run, the
  outputs' `FEA stress study and images: done` beside); the chain's path is start-up (interpreter
  and imports, before the run's clock starts), dynamics (from the stiffness, the last `FEA ...: k =`
  line, to the last `dynamics` line) and outputs (to `done`). The whole job is the process's wall
  time; the stages add up to more where they overlap;
- the whole job's CPU seconds (user and system, every process the run waited for: its own, the
  FEA's, the figure workers, the images'), from the timed runs;
- peak memory, sampled every 50 ms in runs of their own (each timed run is followed by a sampled
  run of the same tree, whose wall time is printed but not used: reading every process's PSS from
  /proc every 50 ms takes CPU from the run and holds its memory map's lock, and made the whole job
  about 4 s slower on a 2-core host): the run's process, its child processes (the FEA beside, the
  figure workers, the images' process) summed, and the whole run's proportional set size (PSS: pages shared between the
  processes counted once, split between them), the memory the run takes from the machine; beside
  it the summed resident sets (shared pages counted in each process: an overstatement). Each run's
  line also says when its PSS peaked (after which progress line) and of what it was made: the PSS
  of the run's process, of the FEA's process, of the run's forks (the figure workers and the
  process that draws the deformed images) and of the rest (`ROLES`).

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
import resource
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
SAMPLE_S = 0.05
WARM_UP_MESH_SIZE_MM = "12"  # a cheap FEA for the untimed first run of each tree
MEMORY = ("process", "children", "sum of resident sets", "PSS")
ROLES = ("run", "FEA", "forks (figures, images)", "other")  # the processes a PSS peak is split into


@dataclass
class Run:
    """One run: each stage's wall time (s), the peak memory (bytes) by MEMORY, and the whole job's wall."""

    wall_s: dict[str, float] = field(default_factory=dict)
    memory: dict[str, int] = field(default_factory=dict)
    total_s: float = 0.0
    cpu_s: float = 0.0  # the whole job's CPU: the run's process and every process it waited for
    peak_pss_by_role: dict[str, int] = field(default_factory=dict)  # at the PSS peak, by ROLES
    peak_after: str = ""  # the last progress line before the PSS peak
    peak_at_s: float = 0.0  # when the PSS peaked, from the process's start


def stage_ends(lines: list[tuple[float, str]]) -> dict[str, float]:
    """The run-clock time each path's marks are reached at, from its progress lines."""
    ends: dict[str, float] = {}
    for t, message in lines:
        if message.startswith("FEA level"):
            ends["stiffness"] = t
        elif message.startswith("stress level"):
            ends["stress study"] = t
        elif message.startswith("FEA ") and " k = " in message:
            ends["k known"] = t
        elif message.startswith("FEA stress study and images: done"):
            ends["fea done"] = t
        elif message.startswith("dynamics"):
            ends["dynamics"] = t
        elif message.startswith("done"):
            ends["outputs"] = t
    ends.setdefault("fea done", ends.get("k known", 0.0))  # one process: the k lines come last
    return ends


def stage_walls(ends: dict[str, float], start_up_s: float) -> dict[str, float]:
    stiffness = ends.get("stiffness", 0.0)
    stress = ends.get("stress study", stiffness)
    dynamics_from = ends.get("k known", stress)
    return {
        "start-up": start_up_s,
        "stiffness": stiffness,
        "stress study": stress - stiffness,
        "rest of FEA": ends["fea done"] - stress,
        "dynamics": ends.get("dynamics", dynamics_from) - dynamics_from,
        "outputs": ends.get("outputs", 0.0) - ends.get("dynamics", dynamics_from),
    }


def child_env(tree: Path, bytecode_dir: Path) -> dict[str, str]:
    """The environment of a run of `tree`: the modules' bytecode read from `bytecode_dir` and written
    there by a tree's first (untimed) run (PYTHONPYCACHEPREFIX: outside the trees, which are left as
    they are), as a user's second run of a checkout reads it from its __pycache__; without the
    caller's PYTHONDONTWRITEBYTECODE, with which every run compiled the project's modules again
    (about 150 of them between the run's and the FEA's processes, 0.6 CPU s)."""
    env = {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"}
    return env | {"PYTHONPATH": str(tree), "PYTHONPYCACHEPREFIX": str(bytecode_dir)}


def run_once(tree: Path, extra: list[str], bytecode_dir: Path, sample_memory: bool = False) -> Run:
    """One run of `tree`'s pipeline.py (`child_env`); with sample_memory its peak memory, else its time only."""
    with tempfile.TemporaryDirectory(prefix="whole-job-") as tmp:
        command = [sys.executable, "pipeline.py", "--cache-dir", f"{tmp}/cache", "--out", f"{tmp}/out", *extra]
        env = child_env(tree, bytecode_dir)
        cpu_before = _children_cpu_s()
        start = time.perf_counter()
        proc = subprocess.Popen(command, cwd=tree, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        run = Run()
        done = threading.Event()
        sampler = threading.Thread(target=_sample, args=(proc.pid, run, done, start), daemon=True)
        if sample_memory:
            sampler.start()
        lines, start_up_s, seen = [], None, []
        for line in proc.stdout:
            match = LINE.match(line)
            if not match:
                continue
            t = float(match.group(1))
            if start_up_s is None:  # the run's clock starts after its imports
                start_up_s = time.perf_counter() - start - t
            lines.append((t, match.group(2)))
            seen.append((time.perf_counter() - start, match.group(2)))
        status = proc.wait()
        run.total_s = time.perf_counter() - start
        run.cpu_s = _children_cpu_s() - cpu_before
        done.set()
        if sample_memory:
            sampler.join()
        if status != 0:
            raise SystemExit(f"{tree}: pipeline.py failed (status {status})")
        run.wall_s = stage_walls(stage_ends(lines), start_up_s or 0.0)
        run.peak_after = next((m for t, m in reversed(seen) if t <= run.peak_at_s), "start-up")
        return run


def _children_cpu_s() -> float:
    """User and system CPU of this process's waited-for children, theirs included (getrusage)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _sample(pid: int, run: Run, done: threading.Event, start: float) -> None:
    try:
        process = psutil.Process(pid)
        command = process.cmdline()
        while not done.is_set():
            children = process.children(recursive=True)
            own = _memory(process)
            theirs = [_memory(c) for c in children]
            sample = {
                "process": own[0],
                "children": sum(m[0] for m in theirs),
                "sum of resident sets": own[0] + sum(m[0] for m in theirs),
                "PSS": own[1] + sum(m[1] for m in theirs),
            }
            if sample["PSS"] > run.memory.get("PSS", 0):
                run.peak_at_s = time.perf_counter() - start
                run.peak_pss_by_role = dict.fromkeys(ROLES, 0) | {"run": own[1]}
                for child, memory in zip(children, theirs):
                    run.peak_pss_by_role[_role(child, command)] += memory[1]
            for key, value in sample.items():
                run.memory[key] = max(run.memory.get(key, 0), value)
            time.sleep(SAMPLE_S)
    except psutil.Error:  # the run ended between two samples
        return


def _role(child: psutil.Process, run_command: list[str]) -> str:
    """Which of ROLES a child of the run is: the FEA's process is an interpreter of its own
    (stages.beside: `_waiting_child`, or multiprocessing's spawn in trees before it), a figure
    worker or the images' process a fork of the run (the run's command line)."""
    try:
        command = child.cmdline()
    except psutil.Error:
        return "other"
    if command == run_command:
        return "forks (figures, images)"
    if any("_waiting_child" in part or "spawn_main" in part for part in command):
        return "FEA"
    return "other"  # multiprocessing's resource tracker (trees before stages.beside's own child)


def peak_line(run: Run) -> str:
    """When a run's PSS peaked and of what it was made (MB)."""
    parts = ", ".join(f"{role} {run.peak_pss_by_role.get(role, 0) / 1e6:.0f}" for role in ROLES)
    return f"PSS peak at {run.peak_at_s:.1f} s, after '{run.peak_after[:60]}': {parts} MB"


def _memory(process: psutil.Process) -> tuple[int, int]:
    """(resident set, proportional set size) of a process, 0 if it has ended."""
    try:
        info = process.memory_full_info()
        return info.rss, info.pss
    except psutil.Error:
        return 0, 0


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


def study_point(tree: Path, bytecode_dir: Path) -> dict:
    env = child_env(tree, bytecode_dir)
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


def report(results: dict[str, list[Run]], sampled: dict[str, list[Run]]) -> list[str]:
    """The stages' and the whole job's walls from the timed runs, the memory from the sampled ones."""
    names = list(results)
    lines = ["| stage | " + " | ".join(f"{n}: wall (s)" for n in names) + " |", "|" + "---|" * (1 + len(names))]
    for stage in STAGES:
        cells = [f"{statistics.median(r.wall_s.get(stage, 0.0) for r in runs):.2f}" for runs in results.values()]
        lines.append(f"| {stage} | " + " | ".join(cells) + " |")
    cells = []
    for runs in results.values():
        walls = ", ".join(f"{r.total_s:.1f}" for r in runs)
        cells.append(f"**{_median(runs, lambda r: r.total_s):.2f}** ({walls})")
    lines.append("| whole job | " + " | ".join(cells) + " |")
    cells = []
    for runs in results.values():
        cpus = ", ".join(f"{r.cpu_s:.1f}" for r in runs)
        cells.append(f"**{_median(runs, lambda r: r.cpu_s):.2f}** ({cpus})")
    lines.append("| whole job, CPU s | " + " | ".join(cells) + " |")
    lines += ["", "| peak memory (MB), sampled runs | " + " | ".join(names) + " |", "|" + "---|" * (1 + len(names))]
    for key in MEMORY:
        cells = [f"{statistics.median(r.memory.get(key, 0) for r in runs) / 1e6:.0f}" for runs in sampled.values()]
        lines.append(f"| {key} | " + " | ".join(cells) + " |")
    cells = [f"{_median(runs, lambda r: r.total_s):.2f}" for runs in sampled.values()]
    lines.append("| (the sampled runs' whole job, s) | " + " | ".join(cells) + " |")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old-tree", type=Path, help="another checkout to time beside this one")
    parser.add_argument("--study-point", action="store_true", help="also time one study point's FEA")
    parser.add_argument("pipeline_options", nargs="*", help="passed to pipeline.py (after --)")
    args = parser.parse_args(argv)
    trees = {"new": ROOT} | ({"old": args.old_tree.resolve()} if args.old_tree else {})
    with tempfile.TemporaryDirectory(prefix="whole-job-bytecode-") as bytecode_dir:
        return _compare(trees, args, Path(bytecode_dir))


def _compare(trees: dict[str, Path], args: argparse.Namespace, bytecode_dir: Path) -> int:
    results: dict[str, list[Run]] = {name: [] for name in trees}
    for tree in trees.values():  # compile and cache each tree's numba kernels and bytecode first (not timed)
        run_once(tree, [*args.pipeline_options, "--mesh-size", WARM_UP_MESH_SIZE_MM], bytecode_dir)
    sampled: dict[str, list[Run]] = {name: [] for name in trees}
    for repeat in range(args.repeats):
        for name, tree in trees.items() if repeat % 2 == 0 else reversed(trees.items()):
            run = run_once(tree, args.pipeline_options, bytecode_dir)
            results[name].append(run)
            memory = run_once(tree, args.pipeline_options, bytecode_dir, sample_memory=True)
            sampled[name].append(memory)
            print(
                f"run {repeat + 1} {name}: {run.total_s:.1f} s, {run.cpu_s:.1f} CPU s; sampled run {memory.total_s:.1f} s, "
                f"PSS {memory.memory.get('PSS', 0) / 1e6:.0f} MB; " + peak_line(memory),
                flush=True,
            )
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(
        f"medians of {args.repeats} runs from an empty FEA cache, trees alternating; cores: {os.cpu_count()}; load average now {load}"
    )
    print("\n".join(report(results, sampled)))
    if args.study_point:
        points: dict[str, list[dict]] = {name: [] for name in trees}
        for repeat in range(args.repeats):
            for name, tree in trees.items() if repeat % 2 == 0 else reversed(trees.items()):
                points[name].append(study_point(tree, bytecode_dir))
                print(f"study point {repeat + 1} {name}: {points[name][-1]['wall_s']:.1f} s", flush=True)
        print("\n".join(study_point_lines(points)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
