"""Time to a 1 % stiffness with its estimate, meshing included, on the default link (issue #13).

    python benchmarks/bench_fea_time_to_k.py [--repeats N] [--old-tree DIR]

Each path runs in a fresh process (imports timed apart), the paths alternate, and the median of
`--repeats` runs is reported with wall and CPU time (CPU is steadier when other jobs share the
machine):
- new default: `stiffness_study(None, al6061-t6)` (two levels relative to the part, 6 / 4.5 mm,
  solved side by side in two threads, finest first, the finest on the link's mirror half);
- the same on the whole link (`mirror_symmetry=False`, as `python -m fem --full-model` runs);
- the same with the levels one after the other (`concurrent_levels=False`, as the study's workers run);
- previous default levels on the same code: three uniform levels 6.5 / 4.5 / 3.5 mm;
- a second material: `stiffness_studies(None, [al6061-t6, ti-grade2])` less the first's time
  (the extra cost of titanium on the same meshes: shared assembly, CG on aluminium's factor);
- where the new default's time goes: its timing_s (meshing, basis and load, assembly, PARDISO, post)
  from the first run;
- this tree's own `python -m fem --json`, the whole process (imports included), as a user runs it;
- with --old-tree DIR (a checkout of the code before this change, e.g. `git worktree add DIR
  <commit>`): that tree's own `python -m fem --json` (its default: three levels, its geometry), the
  whole process, as a user runs it.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

STUDY = """
import json, os, resource, time
t0 = time.perf_counter()
import fem
from fem import get_material, stiffness_studies
t1 = time.perf_counter()
c1 = time.process_time()
materials = [get_material(n) for n in {materials!r}]
result = stiffness_studies(None, materials, mesh_sizes_m={sizes!r}, concurrent_levels={concurrent!r},
                           mirror_symmetry={mirror!r})
first = result[materials[0].name]
print(json.dumps({{"import_s": t1 - t0, "wall_s": time.perf_counter() - t1, "cpu_s": time.process_time() - c1,
                  "k": {{n: e.stiffness_N_per_m for n, e in result.items()}},
                  "estimate": {{n: e.stiffness_rel_error_estimate for n, e in result.items()}},
                  "dofs": [d for _, d, _ in first.levels], "parts_s": first.timing_s}}))
"""

PATHS = {  # materials, mesh sizes, levels solved side by side, mirror half
    "new default (2 relative levels)": (["al6061-t6"], None, True, True),
    "new default on the whole link": (["al6061-t6"], None, True, False),
    "new default, levels one after the other": (["al6061-t6"], None, False, True),
    "previous default levels (6.5/4.5/3.5 mm), same code, whole link": (
        ["al6061-t6"],
        (0.0065, 0.0045, 0.0035),
        True,
        False,
    ),
    "new default, aluminium + titanium": (["al6061-t6", "ti-grade2"], None, True, True),
}


def run_study(materials, sizes, concurrent, mirror) -> dict:
    code = STUDY.format(materials=materials, sizes=sizes, concurrent=concurrent, mirror=mirror)
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
        env={**__import__("os").environ, "PYTHONPATH": str(ROOT)},
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_cli(tree: Path) -> dict:
    """`python -m fem --json` of the tree, the whole process, as a user runs it."""
    start = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-m", "fem", "--json"],
        cwd=tree,
        capture_output=True,
        text=True,
        check=True,
        env={**__import__("os").environ, "PYTHONPATH": str(tree)},
    )
    wall = time.perf_counter() - start
    report = json.loads(out.stdout)
    return {
        "wall_s": wall,
        "k": report["stiffness_N_per_m"],
        "estimate": report["stiffness_rel_error_estimate"],
        "study_s": report["timing_s"].get("wall", report["timing_s"]["total"]),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old-tree", type=Path, help="checkout of the code before the change, for its python -m fem")
    args = parser.parse_args(argv)
    runs: dict[str, list[dict]] = {name: [] for name in PATHS}
    old: list[dict] = []
    cli: list[dict] = []
    for _ in range(args.repeats):
        for name, (materials, sizes, concurrent, mirror) in PATHS.items():
            runs[name].append(run_study(materials, sizes, concurrent, mirror))
        cli.append(run_cli(ROOT))
        if args.old_tree is not None:
            old.append(run_cli(args.old_tree))
    print("path | study wall s (median) | CPU s | imports s | k (N/m) | estimate | DOFs")
    medians = {}
    for name, results in runs.items():
        wall = statistics.median(r["wall_s"] for r in results)
        cpu = statistics.median(r["cpu_s"] for r in results)
        medians[name] = (wall, cpu)
        r = results[0]
        ks = ", ".join(f"{n} {k:.5g}" for n, k in r["k"].items())
        est = ", ".join(f"{e * 100:.2f} %" for e in r["estimate"].values())
        print(
            f"{name} | {wall:.2f} | {cpu:.2f} | {statistics.median(x['import_s'] for x in results):.2f} | {ks} | {est} | {r['dofs']}"
        )
    parts = runs["new default (2 relative levels)"][0]["parts_s"]
    print(
        "new default, where the study's time goes (first run, both levels; solve = PARDISO): "
        + ", ".join(f"{name} {seconds:.2f} s" for name, seconds in parts.items())
    )
    both, one = medians["new default, aluminium + titanium"], medians["new default (2 relative levels)"]
    print(f"titanium on aluminium's meshes: +{both[0] - one[0]:.2f} s wall, +{both[1] - one[1]:.2f} s CPU")
    prev = medians["previous default levels (6.5/4.5/3.5 mm), same code, whole link"]
    print(f"new default vs previous levels: {prev[0] / one[0]:.2f}x wall, {prev[1] / one[1]:.2f}x CPU")
    whole = medians["new default on the whole link"]
    print(
        f"mirror half vs whole link: {one[0]:.2f} vs {whole[0]:.2f} s wall ({whole[0] / one[0]:.2f}x), "
        f"CPU {one[1]:.2f} vs {whole[1]:.2f} s"
    )
    apart = medians["new default, levels one after the other"]
    print(
        f"levels side by side vs one after the other: {one[0]:.2f} vs {apart[0]:.2f} s wall "
        f"({apart[0] / one[0]:.2f}x), CPU {one[1]:.2f} vs {apart[1]:.2f} s"
    )
    walls = [c["wall_s"] for c in cli]
    print(
        f"this tree's python -m fem: {statistics.median(walls):.2f} s whole process (median; runs "
        f"{', '.join(f'{w:.2f}' for w in walls)} s), k {cli[0]['k']:.5g} +- {cli[0]['estimate'] * 100:.2f} %"
    )
    if old:
        wall = statistics.median(o["wall_s"] for o in old)
        study = statistics.median(o["study_s"] for o in old)
        print(
            f"old tree python -m fem: {wall:.2f} s whole process (its study {study:.2f} s), "
            f"k {old[0]['k']:.5g} +- {old[0]['estimate'] * 100:.2f} %"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
