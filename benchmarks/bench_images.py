"""The default run's deformed images, drawn as the run's images' process draws them: its CPU, this
tree beside another (issue #24).

    python benchmarks/bench_images.py [--repeats 5] [--old-tree DIR]

First runs `python pipeline.py` of this tree once (an empty FEA cache, a temporary output folder)
and keeps what its images' process was handed (the `fem.render.Drawing`s, pickled) and the modules
the run's process held when it forked that process. Then, per repeat, this tree and DIR
alternating, a fresh interpreter imports those modules, freezes them out of the collector's sight
(as the run does before the fork), forks, and the child draws the images as the run's images'
process does (`stages.fea._draw_steps`). Prints the child's CPU time (user and system, every
thread: wait4), its wall time and minor page faults, medians per tree, and the load average before
and after; checks that DIR's images have the same pixels as this tree's.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import importlib
import json
import os
import pickle
import runpy
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def capture(folder: Path) -> None:
    """Run the default pipeline here, the images' process keeping its drawings and the run's modules
    in `folder` (drawings.pkl, modules.json) before it draws."""
    import fem.render

    real_draw = fem.render.draw_pictures

    def keeping(drawings, **kwargs):  # in the images' process, forked from the run's
        (folder / "modules.json").write_text(json.dumps(sorted(sys.modules)))
        (folder / "drawings.pkl").write_bytes(pickle.dumps(drawings))
        return real_draw(drawings, **kwargs)

    fem.render.draw_pictures = keeping
    sys.argv = ["pipeline.py", "--cache-dir", str(folder / "cache"), "--out", str(folder / "out"), "-q"]
    runpy.run_path(str(ROOT / "pipeline.py"), run_name="__main__")


def draw(folder: Path, out: Path) -> None:
    """In this tree: the run's modules imported and frozen, a fork that draws; print its figures."""
    for name in json.loads((folder / "modules.json").read_text()):
        if name in sys.modules or name.startswith(("__main__", "__mp_main__")):
            continue
        try:
            importlib.import_module(name)
        except Exception:  # a module that only its importer's context can import (the run imported it)
            pass
    drawings = pickle.loads((folder / "drawings.pkl").read_bytes())
    drawings = [dataclasses.replace(d, path=out / f"{i}.png") for i, d in enumerate(drawings)]
    gc.freeze()
    pid = os.fork()
    if pid == 0:
        from stages.fea import _draw_steps

        list(_draw_steps(drawings))
        os._exit(0)
    start = time.perf_counter()
    _, status, usage = os.wait4(pid, 0)
    wall = time.perf_counter() - start
    if status != 0:
        raise SystemExit(f"the drawing process failed (status {status})")
    cpu = usage.ru_utime + usage.ru_stime
    print(json.dumps({"cpu_s": cpu, "wall_s": wall, "minor_faults": usage.ru_minflt}))


def _draw_in(tree: Path, folder: Path, out: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    command = [sys.executable, str(Path(__file__).resolve()), "--draw", str(folder), str(out)]
    result = subprocess.run(command, cwd=tree, env=env, capture_output=True, text=True, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def _same_pixels(a: Path, b: Path) -> bool:
    import numpy as np
    from PIL import Image

    with Image.open(a) as x, Image.open(b) as y:
        return np.array_equal(np.asarray(x.convert("RGB")), np.asarray(y.convert("RGB")))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--old-tree", type=Path, help="another checkout, drawn alternating with this tree")
    parser.add_argument("--capture", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--draw", nargs=2, type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.capture:
        capture(args.capture)
        return 0
    if args.draw:
        draw(*args.draw)
        return 0
    trees = {"this tree": ROOT} | ({str(args.old_tree): args.old_tree.resolve()} if args.old_tree else {})
    with tempfile.TemporaryDirectory(prefix="bench-images-") as tmp:
        folder = Path(tmp)
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        subprocess.run([sys.executable, __file__, "--capture", tmp], cwd=ROOT, env=env, check=True)
        load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
        print(f"the default run's images drawn in a fork, trees alternating; cores: {os.cpu_count()}; load now {load}")
        runs: dict[str, list[dict]] = {name: [] for name in trees}
        for _ in range(args.repeats):
            for name, tree in trees.items():
                out = folder / "images" / name.replace("/", "_")
                out.mkdir(parents=True, exist_ok=True)
                runs[name].append(_draw_in(tree, folder, out))
                r = runs[name][-1]
                print(f"  {name}: {r['cpu_s']:.2f} CPU s, {r['wall_s']:.2f} s wall, {r['minor_faults']} minor faults")
        for name, rs in runs.items():
            cpu = statistics.median(r["cpu_s"] for r in rs)
            wall = statistics.median(r["wall_s"] for r in rs)
            faults = statistics.median(r["minor_faults"] for r in rs)
            low, high = min(r["cpu_s"] for r in rs), max(r["cpu_s"] for r in rs)
            print(
                f"{name}: median {cpu:.2f} CPU s ({low:.2f}-{high:.2f}), {wall:.2f} s wall, {faults:.0f} minor faults"
            )
        ours = folder / "images" / "this tree"
        for name in list(trees)[1:]:
            theirs = folder / "images" / name.replace("/", "_")
            same = all(_same_pixels(p, theirs / p.name) for p in sorted(ours.glob("*.png")))
            print(f"{name}'s images: {'the same pixels' if same else 'DIFFERENT pixels'} as this tree's")
        load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
        print(f"load average at the end: {load}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
