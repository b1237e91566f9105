"""Progress lines on stderr and per-stage wall times."""

from __future__ import annotations

import sys
import time


class Progress:
    """Stage lines with elapsed time on stderr, so stdout stays clean for the final summary."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.start = time.perf_counter()

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(f"[{self.elapsed():7.1f} s] {message}", file=sys.stderr, flush=True)


def timed(timing: dict, stage: str, progress: Progress, stage_function, *args):
    """Run one stage and add its wall time to timing[stage] (a stage may run more than once)."""
    start = progress.elapsed()
    result = stage_function(*args)
    timing[stage] = timing.get(stage, 0.0) + progress.elapsed() - start
    return result
