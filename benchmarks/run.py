"""The benchmark command: runs every benchmarks/bench_*.py and prints what each measured.

    python benchmarks/run.py [--quick] [--only NAME[,NAME...]] ...

NAME is a benchmark's module name without its `bench_` (`machine` is benchmarks/bench_machine.py;
`bench_machine` is taken too) and matches that module only: `--only machine` does not run
bench_machine_long. Several: a comma list or --only repeated (`--only machine,machine_long`, or
`--only machine --only machine_long`). An unknown name is an error that lists the names.

Each bench module offers `run(quick: bool) -> list[str]` (its table lines; ratios are measured within
one run of that module). The machine is printed first: figures are only comparable on the same one.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import platform
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


class UnknownName(ValueError):
    """An --only name that is no module's; the message lists the names there are."""


def module_name(prefix: str, path: Path) -> str:
    """The name --only takes for benchmarks/<prefix>NAME.py: NAME."""
    return path.stem.removeprefix(prefix)


def modules(prefix: str, only: list[str] | None = None) -> list[Path]:
    """benchmarks/<prefix>*.py, sorted; with `only`, those named in it (each entry a name, or a comma
    list of names: a module's name without `prefix`, or with it), each whole. A name that is no
    module's: UnknownName."""
    found = sorted(HERE.glob(f"{prefix}*.py"))
    if only is None:
        return found
    wanted = {name.strip().removeprefix(prefix) for entry in only for name in entry.split(",") if name.strip()}
    names = [module_name(prefix, p) for p in found]
    unknown = sorted(wanted.difference(names))
    if unknown or not wanted:
        raise UnknownName(
            f"--only {','.join(unknown) or repr(','.join(only))}: not the name of a benchmarks/{prefix}*.py; "
            f"expected one or more of {', '.join(names)}"
        )
    return [p for p, name in zip(found, names) if name in wanted]


def load(path: Path):
    spec = importlib.util.spec_from_file_location(f"benchmarks_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    # dataclasses look their module up in sys.modules while the module body runs
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _has_threadpoolctl() -> bool:
    return importlib.util.find_spec("threadpoolctl") is not None


def machine_lines() -> list[str]:
    import numpy
    import scipy

    return [
        f"machine: {cpu_model()}, {os.cpu_count()} logical cores, {platform.system()} {platform.release()}",
        "BLAS limited to 1 thread for every measurement"
        if _has_threadpoolctl()
        else "BLAS threads NOT limited (threadpoolctl missing): timings are noisier",
        f"python {platform.python_version()}, numpy {numpy.__version__}, scipy {scipy.__version__}",
    ]


def single_threaded_blas():
    """BLAS limited to one thread: the default solver runs that way anyway (dynamics.solvers'
    serial_blas), and on a shared 2-core machine threaded BLAS timings swing by 10x."""
    import scipy.linalg  # noqa: F401  (load scipy's own BLAS first: limits apply to loaded libraries only)

    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: without it BLAS keeps its own threading (noted in the header)
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer scenarios and repeats (a smoke run)")
    parser.add_argument(
        "--only",
        action="append",
        metavar="NAME[,NAME...]",
        help="run only these benchmarks (module names without bench_; repeat or comma-separate for several)",
    )
    args = parser.parse_args(argv)
    sys.path.insert(0, str(HERE.parent))
    with single_threaded_blas():
        return _run(args)


def _run(args) -> int:
    return run_each("bench_", args.only, lambda module: module.run(args.quick))


def run_each(prefix: str, only: list[str] | None, lines_of, command: str = "benchmarks/run.py") -> int:
    """Print the machine, then the lines `lines_of(module)` of each benchmarks/<prefix>*.py module
    (those named in `only`, if given: see `modules`) with its wall time; 2, with a one-line error and
    nothing run, where `only` names a module that does not exist (the error starts with `command`)."""
    try:
        found = modules(prefix, only)
    except UnknownName as exc:
        print(f"{command}: error: {exc}", file=sys.stderr)
        return 2
    for line in machine_lines():
        print(line)
    for path in found:
        start = time.perf_counter()
        print(f"\n== {path.stem} ==", flush=True)
        for line in lines_of(load(path)):
            print(line, flush=True)
        print(f"({path.stem}: {time.perf_counter() - start:.1f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
