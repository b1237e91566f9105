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


class _Cycle:
    def __init__(self) -> None:
        self.me = self


def _make_garbage(made: list, path: Path) -> Path:
    import gc
    import weakref

    made.append((weakref.ref(_Cycle()), gc.isenabled()))
    return _write("garbage", path)


def test_a_batch_is_drawn_with_the_collector_paused_and_its_garbage_collected(tmp_path):
    import gc

    made = []
    jobs = {i: FigureJob(_make_garbage, (made, tmp_path / f"{i}.txt"), batch="one") for i in range(2)}
    assert gc.isenabled()
    draw_figures(jobs, workers=1)
    assert [enabled for _, enabled in made] == [False, False]  # paused while drawing
    assert gc.isenabled() and all(ref() is None for ref, _ in made)  # on again, the cycles collected


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
    """The report's figures, batched as reporting.outputs batches them: a kind of its own, or the
    kinds that share a grid of axes (3 x 1, 1 x 1) together."""
    from reporting import plots

    return [
        FigureJob(plots.plot_three_links, (histories, [1, 2, 4], folder / f"{name}_three.png"), batch="three"),
        FigureJob(plots.plot_three_links, (histories, [3], folder / f"{name}_all_cams.png"), batch="3 x 1"),
        FigureJob(plots.plot_link_vs_input, (histories, 2, folder / f"{name}_vs_input.png"), batch="vs input"),
        FigureJob(plots.plot_differences, (histories, 2, folder / f"{name}_differences.png"), batch="3 x 1"),
        FigureJob(plots.plot_dwell_vibration, (histories, 2, folder / f"{name}_dwell.png"), batch="1 x 1"),
        FigureJob(plots.plot_tension, (histories, folder / f"{name}_tension.png"), batch="1 x 1"),
    ]


def test_a_batch_draws_the_figures_of_one_plot_one_after_the_other(tmp_path):
    """Material-major jobs of two kinds sharing a grid: each kind's figures together, in order."""
    from reporting import plots
    from reporting.drawing import batches

    a, b = _reusing_plots(tmp_path, "a", []), _reusing_plots(tmp_path, "b", [])
    jobs = {("a", "all cams"): a[1], ("a", "differences"): a[3], ("b", "all cams"): b[1], ("b", "differences"): b[3]}
    assert {job.batch for job in jobs.values()} == {"3 x 1"} and a[1].plot is plots.plot_three_links
    assert batches(jobs) == [[("a", "all cams"), ("b", "all cams"), ("a", "differences"), ("b", "differences")]]


def test_a_figure_drawn_on_the_axes_of_the_one_before_has_the_pixels_of_a_new_one(tmp_path):
    """A batch's figures are drawn each on the axes of the one before (reporting.plots keeps them),
    whether of the same kind (the other material's) or of another kind with the same grid of axes
    and another size: the same PNGs as drawn on figures of their own, though their data, limits,
    titles, labels and ticks differ."""
    import numpy as np
    from PIL import Image

    from reporting import plots
    from reporting.text_layout import cached_text_layout

    first, second = _histories("metal a", 1.0), _histories("metal b", 3.0)
    reused = {}
    for i, (a, b) in enumerate(zip(_reusing_plots(tmp_path, "a", first), _reusing_plots(tmp_path, "b", second))):
        reused |= {(i, "a"): a, (i, "b"): b}
    drawn = draw_figures(reused, workers=1)
    assert not plots._SPARE and not plots._LAYOUT_OF  # closed at the batch's end
    alone = tmp_path / "alone"
    alone.mkdir()
    with cached_text_layout():  # the text drawn as draw_figures draws it (at whole pixels)
        for job in [*_reusing_plots(alone, "a", first), *_reusing_plots(alone, "b", second)]:
            assert not plots._SPARE
            job.draw()
            plots.close_spare_figures()
    for path in drawn.values():
        assert np.array_equal(np.asarray(Image.open(path)), np.asarray(Image.open(alone / path.name))), path.name


def test_a_reused_figure_holds_the_lines_of_its_own_histories_only(tmp_path):
    """The link-versus-input figure drawn on the axes of another material's: each axes holds the
    cam input and the link's history of its own cam law, nothing left of the first figure."""
    import numpy as np

    from reporting import plots

    first, second = _histories("metal a", 1.0), _histories("metal b", 3.0)
    plots.plot_link_vs_input(first, 2, tmp_path / "a.png")
    plots.plot_link_vs_input(second, 2, tmp_path / "b.png")
    try:
        (fig,) = plots._SPARE.values()
        axes = np.array(fig.axes).reshape(3, len(second))
        for col, h in enumerate(second):
            for row, (x_link, z_input) in enumerate(
                ((h.x_m * 1e3, h.z_m * 1e3), (h.v_m_s, h.zdot_m_s), (h.a_m_s2, h.zddot_m_s2))
            ):
                lines = axes[row, col].get_lines()
                assert len(lines) == 2
                assert np.array_equal(lines[0].get_xdata(), h.t_s) and np.array_equal(lines[0].get_ydata(), z_input)
                assert np.array_equal(lines[1].get_ydata(), x_link[:, h.column(2)])
    finally:
        plots.close_spare_figures()


def test_the_link_versus_input_figure_draws_each_row_on_one_scale_labelled_in_its_first_column(tmp_path):
    """Every cam law's quantity on the row's one scale (the widest of the cam laws' ranges), the
    tick labels in the first column only, as the figure is drawn anew and on a kept figure."""
    import dataclasses

    import numpy as np

    from reporting import plots

    first = _histories("metal a", 1.0)
    # the second cam law's link moves 3 times as far: its range sets the row's scale
    h = first[1]
    first[1] = dataclasses.replace(h, x_m=3.0 * h.x_m, v_m_s=3.0 * h.v_m_s, a_m_s2=3.0 * h.a_m_s2)
    try:
        for name in ("new", "kept"):
            plots.plot_link_vs_input(first, 2, tmp_path / f"{name}.png")
            (fig,) = plots._SPARE.values()
            axes = np.array(fig.axes).reshape(3, len(first))
            fig.canvas.draw()
            for row in axes:
                limits = {ax.get_ylim() for ax in row}
                assert len(limits) == 1
                low, high = limits.pop()
                assert low <= min(line.get_ydata().min() for ax in row for line in ax.get_lines())
                assert high >= max(line.get_ydata().max() for ax in row for line in ax.get_lines())
                labelled = [
                    any(label.get_visible() and label.get_text() for label in ax.get_yticklabels()) for ax in row
                ]
                assert labelled == [True] + [False] * (len(row) - 1)
    finally:
        plots.close_spare_figures()


def test_the_in_view_locator_keeps_autolocators_ticks_inside_the_view():
    import matplotlib.ticker
    import numpy as np

    from reporting import plots

    fig, ax = plots.plt.subplots()
    try:
        # the views and how many of AutoLocator's ticks lie beyond them
        for low, high, beyond in ((-0.0083, 0.1743, 2), (3.0, 1234.5, 2), (-1.2e-5, 7.7e-5, 2), (0.0, 200.0, 0)):
            ax.set_ylim(low, high)
            ax.yaxis.set_major_locator(matplotlib.ticker.AutoLocator())
            every = ax.yaxis.get_majorticklocs()
            ax.yaxis.set_major_locator(plots.InViewLocator())
            in_view = ax.yaxis.get_majorticklocs()
            assert np.array_equal(in_view, every[(every >= low) & (every <= high)])
            assert len(every) - len(in_view) == beyond
    finally:
        plots.plt.close(fig)


def _sharex_figure(plots, locator):
    import numpy as np

    fig, axes = plots.plt.subplots(2, 2, figsize=(6, 4), sharex=True, squeeze=False)
    t = np.linspace(0.0, 0.17, 50)
    for i, ax in enumerate(fig.axes):
        ax.xaxis.set_major_locator(locator())
        ax.yaxis.set_major_locator(locator())
        ax.plot(t, (i + 1) * 1e-3 * np.sin(30 * t) + (500.0 if i == 3 else 0.0))
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("only this axes has a y label")
    axes[1, 0].set_xlabel("time (s)")
    return fig


def test_the_figures_ways_to_save_work_draw_the_pixels_matplotlib_draws(tmp_path):
    """Empty axis labels left unplaced and the in-view locator (plots._save): the pixels of the
    same figure drawn by matplotlib's own placement and locator (offset texts included)."""
    import matplotlib.ticker
    import numpy as np

    from reporting import plots

    mine = _sharex_figure(plots, plots.InViewLocator)
    reference = _sharex_figure(plots, matplotlib.ticker.AutoLocator)
    try:
        assert len(plots._fix_empty_label_positions(mine)) == 6  # 3 of the 4 x axes, 3 of the 4 y axes
        assert np.array_equal(plots._rendered(mine), plots._rendered(reference))
    finally:
        plots.plt.close(mine)
        plots.plt.close(reference)


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


def _write_layout_method(path: Path) -> Path:
    from matplotlib.text import Text

    return _write(Text._get_layout.__qualname__, path)


@pytest.mark.parametrize("workers", [1, 2])
def test_every_batch_lays_out_its_texts_from_the_drawing_s_cache_and_matplotlib_is_as_before_after(tmp_path, workers):
    """The text layout cache (reporting.text_layout) is on for every batch, in the workers or here,
    and off once the figures are drawn."""
    from matplotlib.text import Text

    before = Text._get_layout
    jobs = {i: FigureJob(_write_layout_method, (tmp_path / f"{i}.txt",)) for i in range(3)}
    methods = {path.read_text().split()[0] for path in draw_figures(jobs, workers=workers).values()}
    assert methods == {"install_text_layout_cache.<locals>.cached_layout"} and Text._get_layout is before


def _write_tick_method(path: Path) -> Path:
    from matplotlib.axis import Axis

    return _write(Axis.get_major_ticks.__module__, path)


@pytest.mark.parametrize("workers", [1, 2])
def test_every_batch_copies_its_ticks_and_matplotlib_makes_them_itself_after(tmp_path, workers):
    """The tick copies (reporting.ticks) are on for every batch, in the workers or here, and off
    once the figures are drawn."""
    from matplotlib.axis import Axis

    from reporting import ticks

    before = Axis.get_major_ticks
    jobs = {i: FigureJob(_write_tick_method, (tmp_path / f"{i}.txt",)) for i in range(3)}
    modules = {path.read_text().split()[0] for path in draw_figures(jobs, workers=workers).values()}
    assert modules == {"reporting.ticks" if ticks._CHECKED else "matplotlib.axis"} and Axis.get_major_ticks is before


def _record_collections(path: Path) -> Path:
    import gc

    return _write(f"{gc.isenabled()} {sum(generation['collections'] for generation in gc.get_stats())}", path)


def test_a_forked_worker_never_runs_the_collector(tmp_path):
    """A worker's garbage goes with it (reporting.drawing._start_worker): no collection in a
    worker, though one draws several batches (three batches, at most two workers)."""
    jobs = {i: FigureJob(_record_collections, (tmp_path / f"{i}.txt",), batch=i // 2) for i in range(6)}
    draw_figures(jobs, workers=2)
    records = [path.read_text().split() for path in sorted(tmp_path.glob("*.txt"))]
    pids = {pid for _, _, pid in records}
    assert pids and os.getpid() not in {int(pid) for pid in pids}
    assert all(enabled == "False" for enabled, _, _ in records)
    # no collection in a worker: its count is the one it was forked with, before and after a batch
    for pid in pids:
        assert len({count for _, count, p in records if p == pid}) == 1
