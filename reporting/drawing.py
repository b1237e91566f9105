"""A run's figures drawn side by side, one process per core.

Every PNG of a run is independent of the others, and matplotlib draws one figure on one core: the
default run's 15 figures took 6.2 s of its outputs stage one after the other. The figures are
drawn in worker processes forked from the run (nothing to import again), each worker taking the
next batch of figures as it finishes one. The workers find the jobs in the memory they share with
the run at the fork and are sent only a batch's number: pickling the arguments (the histories,
N-wide) sent every figure of a 2,000-link run about 46 MB through a pipe, and made its outputs
stage 23 s where drawing the figures took 4 s.

Jobs of one batch (the figures with the same grid of axes: the same figure for each material, or
kinds that share a grid) are drawn one after the other in one process, so that each draws on the
axes of the one before (reporting.plots keeps a drawn figure for the next of the same grid):
creating the axes and their ticks is 40-45 % of drawing the figure that creates them. A worker (or
this process, drawing the figures itself) lays out and shapes each string and renders each glyph
once for all its figures (reporting.text_layout), and makes an axis's ticks as copies
(reporting.ticks).
"""

from __future__ import annotations

import gc
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from pathlib import Path

from processes import forked_map, may_fork_children, usable_cores


@dataclass(frozen=True)
class FigureJob:
    """One figure: a `reporting.plots` function and its arguments (the PNG's path among them).
    Jobs with the same `batch` (not None) are drawn one after the other in one process, in the
    order given."""

    plot: Callable[..., Path]
    args: tuple
    batch: Hashable = None

    def draw(self) -> Path:
        return self.plot(*self.args)


def batches(jobs: dict[Hashable, FigureJob]) -> list[list[Hashable]]:
    """The jobs' keys grouped by batch (a job without one alone), the largest batches first (the
    longest work first keeps both workers busy to the end), else in the jobs' order. Within a
    batch the jobs of one plot function come one after the other, in the jobs' order: a figure
    drawn on the axes of another kind (another size, other ticks) makes ticks and a canvas anew."""
    groups: dict[Hashable, list[Hashable]] = {}
    for key, job in jobs.items():
        groups.setdefault(("batch", job.batch) if job.batch is not None else ("job", key), []).append(key)
    for keys in groups.values():
        first_of = {}
        for key in keys:
            first_of.setdefault(jobs[key].plot, len(first_of))
        keys.sort(key=lambda key: first_of[jobs[key].plot])
    return sorted(groups.values(), key=len, reverse=True)


def draw_figures(jobs: dict[Hashable, FigureJob], workers: int | None = None) -> dict[Hashable, Path]:
    """Draw every job (in worker processes where there are several cores and fork exists, else here,
    one after the other); returns each job's PNG path under its key, in the jobs' order."""
    grouped = batches(jobs)
    workers = min(usable_cores() if workers is None else workers, len(grouped))
    # a Dask worker drawing a study's best designs may not start children (processes.may_fork_children)
    if workers < 2 or not may_fork_children():
        from reporting.text_layout import cached_text_layout
        from reporting.ticks import copied_ticks

        with cached_text_layout(), copied_ticks():
            drawn = {key: path for keys in grouped for key, path in zip(keys, _draw_batch([jobs[k] for k in keys]))}
        return {key: drawn[key] for key in jobs}
    # the run's objects out of the collector's sight: a collection in a worker would otherwise touch every
    # one of them and copy the run's pages into it (copy on write)
    paths = forked_map(
        _draw_batch,
        [[jobs[k] for k in keys] for keys in grouped],
        workers,
        initializer=_start_worker,
        freeze_collector=True,
    )
    drawn = {key: path for keys, batch in zip(grouped, paths) for key, path in zip(keys, batch)}
    return {key: drawn[key] for key in jobs}


def _draw_batch(batch: list[FigureJob]) -> list[Path]:
    """The batch's figures drawn with the cyclic garbage collector paused: matplotlib's artists make
    reference cycles by the thousand, and the collector's passes over them took 0.13-0.26 CPU s of
    the default run's 15 figures (168 passes). Everything the batch made is still in the collector's
    youngest generation at its end (no pass moved it on): where the collector runs in this process,
    the batch's garbage (about 25 MB for the 15 figures) is collected there, without a pass over the
    run's objects. A forked worker does not run the collector at all (`_start_worker`)."""
    from reporting.plots import close_spare_figures

    was_enabled = gc.isenabled()
    gc.disable()
    try:
        return [job.draw() for job in batch]
    finally:
        close_spare_figures()
        if was_enabled:
            gc.collect(0)
            gc.enable()


def _start_worker() -> None:
    """A forked worker's start: its texts laid out, shaped and rendered once for all its batches
    (the worker ends with the draw_figures call; matplotlib's fonts are opened anew after a fork),
    its ticks made as copies, and the cyclic garbage collector off for its life. Its garbage goes with it: the worker ends
    with the call and its memory is given back whole, unfreed (multiprocessing ends a forked
    process with os._exit), so collecting each batch's garbage (about 0.15 CPU s of the default
    run's 15 figures, 7 collections of 3,000-34,000 objects) bought nothing but the memory it held
    until then: about 25 MB for the 15 figures across the workers, while the run's peak is at the
    stiffness levels."""
    from reporting.text_layout import install_text_layout_cache
    from reporting.ticks import install_tick_copies

    gc.disable()
    install_text_layout_cache()
    install_tick_copies()
