"""The default run's 15 figures drawn in one process, in CPU seconds, this tree beside another.

    python benchmarks/bench_figures.py [--repeats 3] [--old-tree DIR] [--cache-dir CACHE] [--keep DIR]
                                       [--workers N] [--jobs FILE]

First runs `pipeline.py` (the default job; `--cache-dir` a warm FEA cache makes it quicker) in this
process with `reporting.outputs.draw_figures` replaced by a recorder, and pickles the figure jobs
it was given (each plot function's module and name, its arguments: the histories, the tension
maps' free play, the residual vibration); `--jobs FILE` keeps that recording in FILE, or draws the
one FILE holds already without running the job again. Then, in a fresh process per run, this tree and DIR
alternating (the first tree first in odd repeats, last in even ones), imports the tree's `reporting.plots` (not timed), draws every recorded job with the
tree's own plot functions and `reporting.drawing.draw_figures(jobs, workers=1)` (one process, the
batches one after the other, as a figure worker draws them), and prints the CPU seconds
(`time.process_time`) of the drawing, per figure and in all, their medians and the ratio of the
medians. Last it says which PNGs of the trees' last runs differ and by how many pixels (`--keep
DIR` keeps them under DIR/new and DIR/old). With `--workers N` (N > 1) the figures are drawn as the
run draws them, in N forked workers (`draw_figures(jobs, workers=N)`), and the CPU seconds are the
workers' (user and system, `resource.getrusage(RUSAGE_CHILDREN)`), in all only.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# Run in a fresh interpreter with the tree first on sys.path: argv = the recorded jobs, the PNGs' folder
CHILD = """
import importlib, json, pickle, resource, sys, time
from pathlib import Path
import reporting.plots  # imported before the clock: pyplot and its fonts' list
from reporting.drawing import FigureJob, draw_figures
recorded, out, workers = pickle.loads(Path(sys.argv[1]).read_bytes()), Path(sys.argv[2]), int(sys.argv[3])
cpu_s = {}
def timed(key, plot):
    def draw(*args):
        start = time.process_time()
        try:
            return plot(*args)
        finally:
            cpu_s[key] = time.process_time() - start
    return draw
def here(value):  # a PNG's path moved into this run's folder
    return out / value.name if isinstance(value, Path) else value
jobs = {}
for key, (module, name, args, batch) in recorded.items():
    plot = getattr(importlib.import_module(module), name)
    jobs[key] = FigureJob(timed(" ".join(map(str, key)), plot), tuple(here(a) for a in args), batch)
def cpu_s_now():  # this process's, or its finished workers'
    if workers == 1:
        return time.process_time()
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime
start = cpu_s_now()
draw_figures(jobs, workers=workers)
print(json.dumps({"total": cpu_s_now() - start, "figures": cpu_s}))
"""


def record_jobs(pipeline_options: list[str], destination: Path) -> int:
    """Run the default job here, pickling the figure jobs its outputs stage draws; their number."""
    sys.path.insert(0, str(ROOT))
    import pipeline
    import reporting.outputs

    recorded = {}
    drawn = reporting.outputs.draw_figures

    def recorder(jobs, *args, **kwargs):
        recorded.update(
            {key: (job.plot.__module__, job.plot.__name__, job.args, job.batch) for key, job in jobs.items()}
        )
        return drawn(jobs, *args, **kwargs)

    reporting.outputs.draw_figures = recorder
    try:
        if pipeline.main(pipeline_options) != 0:
            raise SystemExit("the pipeline run failed")
    finally:
        reporting.outputs.draw_figures = drawn
    destination.write_bytes(pickle.dumps(recorded))
    return len(recorded)


def draw_once(tree: Path, jobs: Path, out: Path, workers: int = 1) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run(
        [sys.executable, "-c", CHILD, str(jobs), str(out), str(workers)],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise SystemExit(f"{tree}: drawing the figures failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def pixel_differences(new: Path, old: Path) -> dict[str, str]:
    """Per PNG of `new`: how it differs from the same file in `old` (nothing where equal)."""
    import numpy as np
    from PIL import Image

    found = {}
    for path in sorted(new.glob("*.png")):
        a, b = np.asarray(Image.open(path)), np.asarray(Image.open(old / path.name))
        if a.shape != b.shape:
            found[path.name] = f"size {a.shape[1]}x{a.shape[0]} against {b.shape[1]}x{b.shape[0]}"
        elif np.any(a != b):
            found[path.name] = f"{int(np.any(a != b, axis=-1).sum())} of {a.shape[0] * a.shape[1]} pixels"
    return found


def _runs(values: list[float]) -> str:
    return f"{statistics.median(values):.2f} ({', '.join(f'{v:.2f}' for v in values)})"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old-tree", type=Path, default=None, help="another checkout, drawn alternately")
    parser.add_argument("--cache-dir", type=Path, default=None, help="the FEA cache of the recording run")
    parser.add_argument("--keep", type=Path, default=None, help="keep each tree's last PNGs under DIR/<tree>")
    parser.add_argument("--workers", type=int, default=1, help="draw in N forked workers, as the run does")
    parser.add_argument("--jobs", type=Path, default=None, help="the recorded jobs: kept here, or reused if there")
    args = parser.parse_args(argv)
    if args.workers < 1:
        parser.error(f"--workers {args.workers}: expected a number of workers of at least 1")
    trees = {"new": ROOT} | ({"old": args.old_tree.resolve()} if args.old_tree else {})
    work = Path(tempfile.mkdtemp(prefix="bench-figures-"))
    try:
        jobs = args.jobs.resolve() if args.jobs else work / "jobs.pickle"
        if jobs.exists():
            print(f"{len(pickle.loads(jobs.read_bytes()))} figures recorded in {jobs}", flush=True)
        else:
            options = ["--out", str(work / "run"), "-q"]
            options += ["--cache-dir", str(args.cache_dir if args.cache_dir else work / "cache")]
            print(f"{record_jobs(options, jobs)} figures recorded from the default run", flush=True)
        folders = {name: (args.keep or work) / name for name in trees}
        runs: dict[str, list[dict]] = {name: [] for name in trees}
        for repeat in range(args.repeats):
            # the trees' order turned round every repeat: a drift in the host's load favours neither
            for name, tree in list(trees.items())[:: 1 if repeat % 2 == 0 else -1]:
                runs[name].append(draw_once(tree, jobs, folders[name], args.workers))
                print(f"run {repeat + 1} {name}: {runs[name][-1]['total']:.2f} CPU s", flush=True)
        print(f"medians of {args.repeats} runs, trees alternating; load average now {os.getloadavg()[0]:.1f}")
        print("| figure | " + " | ".join(f"{name}: CPU s (runs)" for name in trees) + " |")
        print("|---|" + "---|" * len(trees))
        for figure in runs["new"][0]["figures"]:
            print(f"| {figure} | " + " | ".join(_runs([r["figures"][figure] for r in runs[n]]) for n in trees) + " |")
        print("| **all** | " + " | ".join(_runs([r["total"] for r in runs[n]]) for n in trees) + " |")
        if "old" in trees:
            new, old = (statistics.median(r["total"] for r in runs[n]) for n in ("new", "old"))
            print(f"new / old: {new / old:.3f}")
            differing = pixel_differences(folders["new"], folders["old"])
            print("PNGs that differ: " + ("none" if not differing else ""))
            for name, how in differing.items():
                print(f"  {name}: {how}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
