"""CPU seconds of one pipeline run, split between its own process and its children (the FEA's process
beside it, the figure workers): docs/performance.md's CPU tables, measured under load.

    python benchmarks/run_cpu.py [PIPELINE OPTIONS]      e.g. --cache-dir CACHE --out OUT -q

Runs `pipeline.main(PIPELINE OPTIONS)` in this process as `python pipeline.py` does and prints two lines from getrusage (user +
system): the run's process from the interpreter's start (imports, dynamics, tables, report; the
teardown not included) and the children it waited for during the run. With a warm FEA cache the
figure workers are the only children. Run it for each tree (e.g. an old checkout beside this one,
`cd OLD && PYTHONPATH=OLD python /path/to/benchmarks/run_cpu.py ...`), alternating, and quote medians.
"""

from __future__ import annotations

import resource
import sys
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))


def _cpu_s(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def cpu_seconds(run: Callable[[], object]) -> tuple[float, float]:
    """(this process's CPU seconds from its start to the end of `run()`, the CPU seconds of the
    children `run()` waited for)."""
    children_before = _cpu_s(resource.RUSAGE_CHILDREN)
    run()
    return _cpu_s(resource.RUSAGE_SELF), _cpu_s(resource.RUSAGE_CHILDREN) - children_before


def _main_as_the_command_line(options: list[str]) -> int:
    """pipeline.main as `python pipeline.py` calls it: with the FEA's process started before the
    options are read (stages.fea.waiting_fea_process), where the tree has one."""
    import pipeline
    import stages.fea

    if not hasattr(stages.fea, "waiting_fea_process"):  # an older tree
        return pipeline.main(options)
    return pipeline.main(options, fea_process=stages.fea.waiting_fea_process())


def main(argv: list[str] | None = None) -> int:
    options = sys.argv[1:] if argv is None else argv
    status = {}
    own, children = cpu_seconds(lambda: status.setdefault("code", _main_as_the_command_line(options)))
    print(f"the run's process: {own:.2f} CPU s")
    print(f"its children (FEA beside, figure workers): {children:.2f} CPU s")
    return status["code"]


if __name__ == "__main__":
    sys.exit(main())
