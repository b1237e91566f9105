"""Figures drawn side by side (reporting.drawing): every job drawn once, paths under their keys in
the jobs' order, the same files as drawn one after the other, a failing figure fails the run."""

from __future__ import annotations

import multiprocessing
import os
from pathlib import Path

import pytest

from fem.heap import release_free_memory
from reporting.drawing import FigureJob, draw_figures


def _write(text: str, path: Path) -> Path:
    path.write_text(f"{text} {os.getpid()}")
    return path


def _fail(path: Path) -> Path:
    raise ValueError(f"cannot draw {path.name}")


def _jobs(folder: Path) -> dict:
    return {("material", str(i)): FigureJob(_write, (f"figure {i}", folder / f"{i}.txt")) for i in range(5)}


@pytest.mark.parametrize("workers", [1, 2])
def test_every_figure_is_drawn_once_and_returned_under_its_key(tmp_path, workers):
    jobs = _jobs(tmp_path)
    paths = draw_figures(jobs, workers=workers)
    assert list(paths) == list(jobs)
    for (_, i), path in paths.items():
        assert path == tmp_path / f"{i}.txt" and path.read_text().startswith(f"figure {i} ")
    drawn_by = {int(path.read_text().split()[-1]) for path in paths.values()}
    assert (drawn_by == {os.getpid()}) == (workers == 1)  # side by side: in worker processes


def _draw_in_daemon(folder: Path, queue) -> None:
    paths = draw_figures(_jobs(folder), workers=2)
    queue.put(sorted({int(path.read_text().split()[-1]) for path in paths.values()}) == [os.getpid()])


def test_a_daemonic_process_draws_its_figures_itself(tmp_path):
    """A Dask worker (a daemonic process: it may not start children) drawing a study's best
    designs draws one figure after the other, in its own process."""
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    worker = context.Process(target=_draw_in_daemon, args=(tmp_path, queue), daemon=True)
    worker.start()
    drawn_by_itself = queue.get(timeout=60)
    worker.join(timeout=60)
    assert worker.exitcode == 0 and drawn_by_itself


def test_a_figure_that_fails_fails_the_drawing(tmp_path):
    jobs = _jobs(tmp_path) | {"bad": FigureJob(_fail, (tmp_path / "bad.png",))}
    with pytest.raises(ValueError, match="cannot draw bad.png"):
        draw_figures(jobs, workers=2)


def test_the_heap_gives_its_free_pages_back_on_glibc():
    import platform

    assert release_free_memory() == (platform.libc_ver()[0] == "glibc")


def test_a_figure_is_cropped_to_its_ink_and_padded_unless_the_ink_reaches_its_edge():
    import numpy as np

    from reporting.plots import cropped_to_ink

    white = np.array([255, 255, 255, 255], dtype=np.uint8)
    pixels = np.full((40, 60, 4), 255, dtype=np.uint8)
    pixels[10:20, 15:31] = (0, 0, 0, 255)
    cropped = cropped_to_ink(pixels, white, pad=3)
    assert cropped.shape == (10 + 2 * 3, 16 + 2 * 3, 4)
    assert (cropped[3:-3, 3:-3, :3] == 0).all() and (cropped[:3] == 255).all() and (cropped[:, -3:] == 255).all()
    pixels[0, 20] = (0, 0, 0, 255)  # ink on the top edge: something may lie outside the canvas
    assert cropped_to_ink(pixels, white, pad=3) is None
    assert cropped_to_ink(np.full((5, 5, 4), 255, dtype=np.uint8), white, pad=1) is None


def _call_and_write(make_text, path: Path) -> Path:
    return _write(make_text(), path)


def test_the_workers_get_the_jobs_by_fork_not_by_pickling_their_arguments(tmp_path):
    """A job's arguments (a long chain's N-wide histories) are not sent to the workers: a lambda,
    which pickle refuses, reaches them all the same."""
    jobs = {i: FigureJob(_call_and_write, (lambda i=i: f"figure {i}", tmp_path / f"{i}.txt")) for i in range(3)}
    paths = draw_figures(jobs, workers=2)
    assert [paths[i].read_text().split()[:2] for i in range(3)] == [["figure", str(i)] for i in range(3)]
    assert os.getpid() not in {int(path.read_text().split()[-1]) for path in paths.values()}
