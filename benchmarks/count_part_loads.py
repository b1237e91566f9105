"""How often one pipeline run loads the part into gmsh and chooses its pin bores (issue #21).

    python benchmarks/count_part_loads.py [PIPELINE OPTIONS]
    e.g. python benchmarks/count_part_loads.py --geometry geometry/data/example_link.step --materials al6061-t6 --serial

Counts are of this process only: pass --serial, or the FEA runs in a process of its own
(stages.beside) whose translations are not counted (1 instead of 4 on the example STEP).

Runs `pipeline.main` once with the given options, --no-images and a fresh temporary cache (so the
stiffness and the stress studies both run), and counts, with the seconds spent in each:
- STEP translations by OpenCASCADE (gmsh.model.occ.importShapes): every gmsh load of a STEP part;
- hole detections (geometry.assembly.find_holes) and pin-bore choices (select_pin_bores).
It patches only gmsh and geometry.assembly, so the same command counts an older tree's run too
(run it from that tree's root with PYTHONPATH set to it).
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))

import gmsh  # noqa: E402

import geometry.assembly  # noqa: E402
import pipeline  # noqa: E402

COUNTED = (
    (gmsh.model.occ, "importShapes", "STEP translations (importShapes)"),
    (geometry.assembly, "find_holes", "hole detections (find_holes)"),
    (geometry.assembly, "select_pin_bores", "pin-bore choices (select_pin_bores)"),
)


def count(argv: list[str]) -> tuple[Counter, Counter]:
    calls, seconds = Counter(), Counter()

    def counted(function, key):
        def wrapper(*args, **kwargs):
            calls[key] += 1
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                seconds[key] += time.perf_counter() - start

        return wrapper

    for owner, name, key in COUNTED:
        setattr(owner, name, counted(getattr(owner, name), key))
    with tempfile.TemporaryDirectory(prefix="count-part-") as folder:
        code = pipeline.main([*argv, "-q", "--no-images", "--out", f"{folder}/out", "--cache-dir", f"{folder}/cache"])
    if code != 0:
        raise SystemExit(code)
    return calls, seconds


def main() -> None:
    calls, seconds = count(sys.argv[1:])
    for _, _, key in COUNTED:
        print(f"{key}: {calls[key]} calls, {seconds[key]:.2f} s")


if __name__ == "__main__":
    main()
