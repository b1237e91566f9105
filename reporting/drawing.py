"""A run's figures drawn side by side, one process per core.

Every PNG of a run is independent of the others, and matplotlib draws one figure on one core: the
default run's 15 figures took 6.2 s of its outputs stage one after the other. The figures are
drawn in worker processes forked from the run (nothing to import again), each worker taking the
next figure as it finishes one. The workers find the jobs in the memory they share with the run at
the fork and are sent only a job's number: pickling the arguments (the histories, N-wide) sent
every figure of a 2,000-link run about 46 MB through a pipe, and made its outputs stage 23 s where
drawing the figures took 4 s.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Hashable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from processes import may_start_children, usable_cores


@dataclass(frozen=True)
class FigureJob:
    """One figure: a `reporting.plots` function and its arguments (the PNG's path among them)."""

    plot: Callable[..., Path]
    args: tuple

    def draw(self) -> Path:
        return self.plot(*self.args)


# The jobs of the draw_figures call in progress, for its forked workers (set before they fork)
_JOBS: list[FigureJob] = []


def draw_figures(jobs: dict[Hashable, FigureJob], workers: int | None = None) -> dict[Hashable, Path]:
    """Draw every job (in worker processes where there are several cores and fork exists, else here,
    one after the other); returns each job's PNG path under its key, in the jobs' order."""
    workers = min(usable_cores() if workers is None else workers, len(jobs))
    # a Dask worker drawing a study's best designs may not start children (processes.may_start_children)
    if workers < 2 or not may_start_children() or "fork" not in multiprocessing.get_all_start_methods():
        return {key: job.draw() for key, job in jobs.items()}
    _JOBS[:] = jobs.values()
    try:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork")) as pool:
            pending = {key: pool.submit(_draw_job, i) for i, key in enumerate(jobs)}
            return {key: future.result() for key, future in pending.items()}
    finally:
        _JOBS.clear()


def _draw_job(index: int) -> Path:
    """In a forked worker: the index-th job of the draw_figures call that forked it."""
    return _JOBS[index].draw()
