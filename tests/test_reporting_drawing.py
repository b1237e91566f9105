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


def _title_height_px(path: Path) -> int:
    """Rows from a PNG's first ink (its title's top) to the axes' top edge (the first row with an
    unbroken dark run over half the image's width: the frame, not a line of text)."""
    import numpy as np
    from PIL import Image

    dark = np.asarray(Image.open(path).convert("L")) < 128
    ink = np.flatnonzero(dark.any(axis=1))

    def longest_run(row: np.ndarray) -> int:
        edges = np.flatnonzero(np.diff(np.concatenate(([0], row.astype(np.int8), [0]))))
        return int(np.max(edges[1::2] - edges[::2], initial=0))

    frame = next(i for i, row in enumerate(dark) if longest_run(row) > dark.shape[1] / 2)
    return int(frame - ink[0])


def test_what_lies_outside_a_narrow_figure_is_drawn_in_one_draw(tmp_path, monkeypatch):
    """A y label left of a narrow figure's canvas is in the PNG, drawn once (no bbox_inches="tight"
    pass, which draws twice): the canvas is grown by reporting.plots.MARGIN_INCHES."""
    import matplotlib.figure
    from PIL import Image

    from reporting import plots

    draws = []
    original = matplotlib.figure.Figure.draw
    monkeypatch.setattr(matplotlib.figure.Figure, "draw", lambda fig, r: draws.append(1) or original(fig, r))
    fig, ax = plots.plt.subplots(figsize=(1.5, 1.5))
    ax.plot([0.0, 1.0], [-1.0, 1.0])
    ax.set_ylabel("a long label")
    path = plots._save(fig, tmp_path / "narrow.png")
    width_px = Image.open(path).size[0]
    assert len(draws) == 1 and width_px > 1.5 * plots.DPI  # wider than the figure: the label is in


def test_a_title_moves_above_a_y_offset_text_as_matplotlib_places_it(tmp_path):
    """Titles are placed without matplotlib's search unless an offset text stands where the title
    goes: then the figure is drawn with the search, and the title sits above the offset text."""
    from reporting import plots

    def figure(offset: bool):
        fig, ax = plots.plt.subplots(figsize=(4, 3))
        ax.plot([0.0, 1.0], [5.0 + 1e-5, 5.0 + 3e-5] if offset else [0.0, 1.0])
        ax.set_title("a title as wide as the axes, over the offset text")
        return fig

    plain = _title_height_px(plots._save(figure(False), tmp_path / "plain.png"))
    with_offset = _title_height_px(plots._save(figure(True), tmp_path / "offset.png"))
    reference = figure(True)
    reference.savefig(tmp_path / "reference.png", dpi=plots.DPI, bbox_inches="tight", pad_inches=plots.PAD_INCHES)
    plots.plt.close(reference)
    # within a pixel: the tight canvas's origin falls between pixels, the grown one's on a pixel
    assert abs(with_offset - _title_height_px(tmp_path / "reference.png")) <= 1 and with_offset > plain + 5


def _histories(material: str, scale: float, cams=("cycloidal", "poly-345")) -> list:
    """Small histories of 4 links: the second material's motion `scale` times the first's."""
    import numpy as np

    from reporting.history import CamHistory

    t = np.linspace(0.0, 0.5, 200)
    z = 0.03 * (1 - np.cos(2 * np.pi * t / 0.5)) / 2
    histories = []
    for i, cam in enumerate(cams):
        x = scale * (z[:, None] + 1e-4 * (i + 1) * np.sin(40 * t)[:, None] * np.arange(1, 5))
        tension = scale * 1e3 * np.cos(30 * t)[:, None] * np.arange(1, 5)
        histories.append(CamHistory(material, cam, t, z, np.gradient(z, t), z, x, x, x, tension, t > 0.4))
    return histories


def _reusing_plots(folder: Path, name: str, histories: list) -> list:
    from reporting import plots

    return [
        FigureJob(plots.plot_three_links, (histories, [1, 2, 4], folder / f"{name}_three.png"), batch="three"),
        FigureJob(plots.plot_link_vs_input, (histories, 2, folder / f"{name}_vs_input.png"), batch="vs input"),
        FigureJob(plots.plot_differences, (histories, 2, folder / f"{name}_differences.png"), batch="differences"),
        FigureJob(plots.plot_dwell_vibration, (histories, 2, folder / f"{name}_dwell.png"), batch="dwell"),
        FigureJob(plots.plot_tension, (histories, folder / f"{name}_tension.png"), batch="tension"),
    ]


def test_a_figure_drawn_on_the_axes_of_the_one_before_has_the_pixels_of_a_new_one(tmp_path):
    """A batch's second figure is drawn on the first's axes (reporting.plots keeps them): the
    same PNG as drawn on a figure of its own, though its data, limits, titles and ticks differ."""
    import numpy as np
    from PIL import Image

    from reporting import plots

    first, second = _histories("metal a", 1.0), _histories("metal b", 3.0)
    reused = {}
    for i, (a, b) in enumerate(zip(_reusing_plots(tmp_path, "a", first), _reusing_plots(tmp_path, "b", second))):
        reused |= {(i, "a"): a, (i, "b"): b}
    drawn = draw_figures(reused, workers=1)
    assert not plots._SPARE and not plots._LAYOUT_OF  # closed at the batch's end
    alone = tmp_path / "alone"
    alone.mkdir()
    for job in _reusing_plots(alone, "b", second):
        assert not plots._SPARE
        job.draw()
        plots.close_spare_figures()
    for (_, name), path in drawn.items():
        if name == "b":
            assert np.array_equal(np.asarray(Image.open(path)), np.asarray(Image.open(alone / path.name))), path.name


def test_the_jobs_of_a_batch_are_drawn_together_largest_batch_first(tmp_path):
    from reporting.drawing import batches

    jobs = _jobs(tmp_path)
    jobs = {key: FigureJob(job.plot, job.args, batch="pair" if key[1] in "13" else None) for key, job in jobs.items()}
    assert batches(jobs) == [
        [("material", "1"), ("material", "3")],
        [("material", "0")],
        [("material", "2")],
        [("material", "4")],
    ]
    paths = draw_figures(jobs, workers=2)
    assert list(paths) == list(jobs)
    pair = {int(paths["material", i].read_text().split()[-1]) for i in "13"}
    assert len(pair) == 1 and pair != {os.getpid()}  # one worker drew both


def test_a_figure_is_rendered_to_the_pixels_savefig_writes(tmp_path):
    """plots._rendered keeps the Agg renderer's own buffer from one savefig: the same bytes as
    savefig(format="rgba") writes to a file for the same grown canvas, in the renderer's shape."""
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.transforms import Bbox

    from reporting import plots

    for figsize in ((6.0, 4.0), (3.3, 2.7)):
        fig, ax = plt.subplots(figsize=figsize)
        ax.plot([0.0, 1.0], [0.0, 2e-3])
        ax.set_ylabel("a long y label")
        pixels = plots._rendered(fig).copy()
        width, height = figsize
        m = plots.MARGIN_INCHES
        path = tmp_path / "figure.rgba"
        fig.savefig(path, format="rgba", dpi=plots.DPI, bbox_inches=Bbox.from_extents(-m, -m, width + m, height + m))
        plt.close(fig)
        assert pixels.shape[2] == 4 and pixels.shape[1] > (width + 2 * m) * plots.DPI - 2
        assert np.array_equal(pixels.ravel(), np.fromfile(path, dtype=np.uint8))
