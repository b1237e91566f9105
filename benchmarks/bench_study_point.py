"""What one design point's FEA costs a study: this tree beside another checkout (issue #24).

    python benchmarks/bench_study_point.py [--repeats 3] [--old-tree DIR]

In a fresh process per run (the trees alternating), the study's FEA task (`study.tasks.fea_task`:
the built-in link at the study's default settings, both default materials, stiffness and converged
stress, no FEA cache, one thread per library as on a worker) after its imports; prints per tree the
medians of the task's wall and CPU seconds and of the process's peak resident set (VmHWM, the
imports included: a worker holds them too), with the runs, and the load average before and after.
DIR: e.g. `git worktree add --detach /tmp/old main`.
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

CHILD = """
import json
from study.spec import Settings
from study.tasks import fea_task
out = fea_task({}, ("al6061-t6", "ti-grade2"), Settings(fea_cache=False))
assert out["reason"] is None, out["reason"]
with open("/proc/self/status") as status:
    hwm_kB = next(int(line.split()[1]) for line in status if line.startswith("VmHWM:"))
print(json.dumps({"seconds": out["seconds"], "cpu_seconds": out["cpu_seconds"], "peak_MB": hwm_kB / 1024}))
"""


def one_run(tree: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, "-c", CHILD], cwd=tree, env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def summary(runs: list[dict]) -> str:
    def med(key, fmt):
        values = [r[key] for r in runs]
        return f"{fmt.format(statistics.median(values))} ({', '.join(fmt.format(v) for v in values)})"

    return f"{med('seconds', '{:.2f}')} s, {med('cpu_seconds', '{:.2f}')} CPU s, {med('peak_MB', '{:.0f}')} MB"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old-tree", type=Path, default=None)
    args = parser.parse_args()
    trees = {"this tree": ROOT} | ({"old tree": args.old_tree.resolve()} if args.old_tree else {})
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    runs = {name: [] for name in trees}
    for _ in range(args.repeats):
        for name, tree in trees.items():
            runs[name].append(one_run(tree))
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    for name, tree_runs in runs.items():
        print(f"{name}: {summary(tree_runs)}")


if __name__ == "__main__":
    main()
