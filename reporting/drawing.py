"""A run's figures drawn side by side, one process per core.

Every PNG of a run is independent of the others, and matplotlib draws one figure on one core: the
default run's 15 figures took 6.2 s of its outputs stage one after the other. The figures are
drawn in worker processes forked from the run (nothing to import again; the arguments are the
histories and metrics, pickled), each worker taking the next figure as it finishes one.
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


def draw_figures(jobs: dict[Hashable, FigureJob], workers: int | None = None) -> dict[Hashable, Path]:
    """Draw every job (in worker processes where there are several cores and fork exists, else here,
    one after the other); returns each job's PNG path under its key, in the jobs' order."""
    workers = min(usable_cores() if workers is None else workers, len(jobs))
    # a Dask worker drawing a study's best designs may not start children (processes.may_start_children)
    if workers < 2 or not may_start_children() or "fork" not in multiprocessing.get_all_start_methods():
        return {key: job.draw() for key, job in jobs.items()}
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork")) as pool:
        pending = {key: pool.submit(job.plot, *job.args) for key, job in jobs.items()}
        return {key: future.result() for key, future in pending.items()}
