"""How soon the FEA's process starts, and how soon its stiffness is ready (issue #24).

    python benchmarks/bench_startup.py [--repeats 5] [--old-tree DIR]

Runs `python pipeline.py --cache-dir EMPTY --out TMP` of this tree (and, with `--old-tree DIR`, of
another checkout, e.g. `git worktree add --detach DIR main`) in fresh processes, the trees
alternating, each run with its own empty cache, and stops each run (its process group) once the
stiffness of every material is handed over: the stiffness is on the job's critical path (the chain
waits for it) and every second before the FEA's process starts delays it. Prints, medians over
`--repeats` runs: the wall time from the launch to the `FEA: in process` line (interpreter, the
settings' checks and what pipeline.py imports before `stages.fea.start_fea` hands the FEA to its
process, which `python pipeline.py` starts before it reads its options: stages.fea.
waiting_fea_process), the run clock on that line (it starts after the command line is parsed and
checked), and the wall time from the launch to the last `FEA ...: k =` line (the stiffness ready).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
CLOCK = re.compile(r"\[\s*([\d.]+) s\]")


def run_once(tree: Path, materials: int = 2) -> tuple[float, float, float]:
    """(wall to the FEA's start, run clock on that line, wall to the stiffness ready), seconds."""
    work = Path(tempfile.mkdtemp(prefix="bench-startup-"))
    env = dict(os.environ, PYTHONPATH=str(tree))
    command = [sys.executable, "pipeline.py", "--cache-dir", str(work / "cache"), "--out", str(work / "out")]
    start = time.perf_counter()
    process = subprocess.Popen(
        command, cwd=tree, env=env, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, start_new_session=True
    )
    fea_start = clock = None
    handed = 0
    try:
        for line in process.stderr:
            if "FEA: in process" in line:
                fea_start, clock = time.perf_counter() - start, float(CLOCK.search(line).group(1))
            elif re.search(r"\] FEA [\w.-]+: k = ", line):
                handed += 1
                if handed == materials:
                    return fea_start, clock, time.perf_counter() - start
        raise RuntimeError(f"{tree}: the run ended before its stiffness was handed over (exit {process.wait()})")
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the run and the FEA's process: nothing after the stiffness is timed
        process.wait()
        shutil.rmtree(work, ignore_errors=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--old-tree", type=Path, help="another checkout to time beside this one")
    args = parser.parse_args(argv)
    trees = {"new": HERE} | ({"old": args.old_tree.resolve()} if args.old_tree else {})
    runs: dict[str, list[tuple[float, float, float]]] = {name: [] for name in trees}
    for _ in range(args.repeats):
        for name, tree in trees.items():
            runs[name].append(run_once(tree))
            print(f"{name}: FEA start {runs[name][-1][0]:.2f} s, stiffness ready {runs[name][-1][2]:.2f} s", flush=True)
    print("| tree | launch to the FEA handed over (s) | run clock on that line (s) | launch to stiffness ready (s) |")
    print("|---|---|---|---|")
    for name, measured in runs.items():
        medians = [statistics.median(m[i] for m in measured) for i in range(3)]
        print(f"| {name} | {medians[0]:.2f} | {medians[1]:.1f} | {medians[2]:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
