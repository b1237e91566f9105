"""The converged stress study of the default job, this tree beside another checkout (issue #24).

    python benchmarks/bench_stress_study.py [--repeats 3] [--old-tree DIR] [--step]

In a fresh process per run (the trees alternating): the stiffness study of the default link (both
materials, default levels, as `pipeline.py` runs it, untimed here), then `fem.stress.stress_study`
from its finest level, timed. Prints per tree the median wall time of the stress study, its
answer per material (peak MPa/kN, estimate, levels with their DOFs) and the load average before and
after, since the machine may be shared. `--step`: the example STEP link instead of the built-in.
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
STEP = ROOT / "geometry" / "data" / "example_link.step"

CHILD = """
import json, sys, time, warnings
import geometry
from fem import load_materials, stiffness_studies
from fem.settings import FeaSettings
from fem.stress import stress_study
warnings.simplefilter("ignore")
source = None if sys.argv[1] == "-" else sys.argv[1]
library = load_materials(None)
materials = [library["al6061-t6"], library["ti-grade2"]]
settings = FeaSettings()
part = geometry.as_part(source, symmetry=settings.mirror_symmetry)
studies = stiffness_studies(part, materials, settings)
finest = {name: study.finest for name, study in studies.items()}
start = time.perf_counter()
stresses = stress_study(part, materials, settings, base_mesh_size_m=next(iter(finest.values())).mesh_size_m, base=finest)
seconds = time.perf_counter() - start
print(json.dumps({"seconds": seconds, "materials": {
    name: {"peak_MPa_per_kN": s.peak_Pa_per_N * 1e-3, "estimate": s.rel_change, "converged": s.converged,
           "levels": [[size * 1e3, dofs, peak * 1e-3] for size, dofs, peak in s.levels]}
    for name, s in stresses.items()}}))
"""


def run_once(tree: Path, source: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    done = subprocess.run(
        [sys.executable, "-c", CHILD, source], cwd=tree, env=env, capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        raise SystemExit(f"bench_stress_study.py: the run in {tree} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old-tree", type=Path, default=None, help="another checkout to time beside this one")
    parser.add_argument("--step", action="store_true", help="the example STEP link instead of the built-in one")
    args = parser.parse_args(argv)
    source = str(STEP) if args.step else "-"
    trees = {"new": ROOT} | ({"old": args.old_tree.resolve()} if args.old_tree else {})
    runs: dict[str, list[dict]] = {name: [] for name in trees}
    load_before = os.getloadavg()
    for _ in range(args.repeats):
        for name, tree in trees.items():
            runs[name].append(run_once(tree, source))
    load_after = os.getloadavg()
    print(f"load average before {load_before[0]:.2f}, after {load_after[0]:.2f} (1 min)")
    for name, results in runs.items():
        seconds = [r["seconds"] for r in results]
        print(
            f"{name}: stress study {statistics.median(seconds):.2f} s (runs {', '.join(f'{s:.2f}' for s in seconds)})"
        )
        for material, answer in results[0]["materials"].items():
            levels = " / ".join(f"{size:.2g} mm {dofs} DOFs {peak:.4g}" for size, dofs, peak in answer["levels"])
            print(
                f"  {material}: {answer['peak_MPa_per_kN']:.4g} MPa/kN +- {answer['estimate'] * 100:.2g} % "
                f"({'converged' if answer['converged'] else 'NOT converged'}); levels {levels}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
