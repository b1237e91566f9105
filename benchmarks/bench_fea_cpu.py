"""The FEA's process of the whole job in CPU seconds: its stiffness step, then its stress study and
images (issue #24).

    python benchmarks/bench_fea_cpu.py [--repeats 3] [--old-tree DIR]

Runs `stages.fea._fea_steps` on the default run from an empty cache, as `pipeline.py`'s process
beside the chain runs it (stiffness levels concurrent, then the stress study and the two deformed
images), in a fresh process per run, this tree and DIR alternating, and prints the CPU seconds (the
process's, all threads) of the first step (the stiffness, with the process's imports and the part's
measurement), of the stress study (`fem.stress.stress_study`, timed around its call) and of the
rest of the second step (the images), with their medians, each run's k and each tree's last k and
converged stress to the last digit. The whole job keeps both cores busy, so its wall time follows
its CPU time; CPU times are also steadier than wall times on a shared machine.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STEPS = ("stiffness", "stress study", "images (the rest of the second step)")

CHILD = """
import dataclasses, json, shutil, tempfile, time
from pathlib import Path
start = time.process_time()
from fem import load_materials
from settings import RunConfig
from stages import fea
from stages.geometry import inspect_geometry
from stages.progress import Progress
import fem.stress
stress_study, stress_cpu = fem.stress.stress_study, []
def timed_stress_study(*args, **kwargs):  # _fea_steps imports it from fem.stress when it runs
    begin = time.process_time()
    try:
        return stress_study(*args, **kwargs)
    finally:
        stress_cpu.append(time.process_time() - begin)
fem.stress.stress_study = timed_stress_study
tmp = tempfile.mkdtemp(prefix="bench-fea-cpu-")
cfg = dataclasses.replace(RunConfig(), cache_dir=Path(tmp) / "cache", out=Path(tmp) / "out")
quiet = Progress(True)
cfg, part = inspect_geometry(cfg, quiet)
library = load_materials(cfg.materials_file)
images = {m: Path(tmp) / f"{m}.png" for m in cfg.materials}
steps = fea._fea_steps(part, fea.fea_settings(cfg), [library[m] for m in cfg.materials], None, None, images,
                       quiet, cfg.max_fea_dofs)
stiffness, _ = next(steps)
after_stiffness = time.process_time()
stresses, _ = next(steps)
end = time.process_time()
shutil.rmtree(tmp, ignore_errors=True)
print(json.dumps({
    "cpu_s": [after_stiffness - start, sum(stress_cpu), end - after_stiffness - sum(stress_cpu)],
    "k": {m: r["stiffness_N_per_m"] for m, r in stiffness.items()},
    "stress": {m: s.peak_Pa_per_N for m, s in stresses.items()},
}))
"""


def run_once(tree: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, "-c", CHILD], cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{tree}: the FEA steps failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old-tree", type=Path, default=None, help="another checkout, run alternately")
    args = parser.parse_args(argv)
    trees = {"new": ROOT} | ({"old": args.old_tree.resolve()} if args.old_tree else {})
    runs: dict[str, list[dict]] = {name: [] for name in trees}
    for repeat in range(args.repeats):
        for name, tree in trees.items():
            runs[name].append(run_once(tree))
            cpu = ", ".join(f"{c:.2f}" for c in runs[name][-1]["cpu_s"])
            k = ", ".join(f"{m} {v!r}" for m, v in runs[name][-1]["k"].items())
            print(f"run {repeat + 1} {name}: CPU s {cpu}; k (N/m) {k}", flush=True)
    print(f"medians of {args.repeats} runs, trees alternating; load average now {os.getloadavg()[0]:.1f}")
    print("| step | " + " | ".join(f"{name}: CPU s (runs)" for name in trees) + " |")
    print("|---|" + "---|" * len(trees))
    for i, step in enumerate(STEPS):
        cells = []
        for name in trees:
            values = [r["cpu_s"][i] for r in runs[name]]
            cells.append(f"{statistics.median(values):.2f} ({', '.join(f'{v:.2f}' for v in values)})")
        print(f"| {step} | " + " | ".join(cells) + " |")
    for name in trees:
        last = runs[name][-1]
        answers = ", ".join(f"{m} k {last['k'][m]!r} N/m, stress {last['stress'][m]!r} Pa/N" for m in last["k"])
        print(f"{name}: {answers}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
