"""The chart command: runs every benchmarks/chart_*.py and writes its PNGs into docs/charts/.

    python benchmarks/charts.py [--quick] [--only NAME[,NAME...]] ... [--out DIR]

NAME is a chart's module name without its `chart_` (`clearance` is benchmarks/chart_clearance.py) and
matches that module only; several: a comma list or --only repeated (as benchmarks/run.py's).

Each chart module offers `make(out_dir: pathlib.Path, quick: bool) -> list[str]`: it measures, writes
its PNG(s) into out_dir and returns lines stating what it measured (fits, limits, figures). Charts are
saved at dpi 100 so they stay commit-sized.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from run import run_each, single_threaded_blas  # noqa: E402  (benchmarks/ is not a package)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="coarse settings (a smoke run, minutes less)")
    parser.add_argument(
        "--only",
        action="append",
        metavar="NAME[,NAME...]",
        help="run only these charts (module names without chart_; repeat or comma-separate for several)",
    )
    parser.add_argument("--out", type=Path, default=HERE.parent / "docs" / "charts", help="output directory")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    with single_threaded_blas():
        return _make(args)


def _make(args) -> int:
    total = time.perf_counter()
    status = run_each("chart_", args.only, lambda module: module.make(args.out, args.quick), "benchmarks/charts.py")
    if status == 0:
        print(f"\nall charts: {time.perf_counter() - total:.1f} s, written to {args.out}")
    return status


if __name__ == "__main__":
    sys.exit(main())
