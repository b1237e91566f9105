"""The process that draws the deformed images beside the run (stages.fea): Mesa's rasteriser in the
process's own thread, no cyclic collector, and the image the same as drawn in this process."""

import gc
import os
from pathlib import Path

import matplotlib.image
import numpy as np
from fem_plate import plate_link

from fem import analyse_link, get_material


def _settings_seen_by_the_drawing(monkeypatch) -> list[tuple[str | None, bool]]:
    from fem import render
    from stages import fea

    seen = []
    monkeypatch.setattr(
        render, "draw_pictures", lambda drawings: seen.append((os.environ.get("LP_NUM_THREADS"), gc.isenabled()))
    )
    try:
        assert list(fea._draw_steps([])) == [None]
    finally:
        gc.enable()
    return seen


def test_the_drawing_runs_with_one_rasteriser_thread_and_no_collector(monkeypatch):
    from stages import fea

    monkeypatch.setenv("LP_NUM_THREADS", "restored after the test")
    monkeypatch.delenv("LP_NUM_THREADS")
    assert fea.DRAWING_ENVIRONMENT == {"LP_NUM_THREADS": "0"}
    assert _settings_seen_by_the_drawing(monkeypatch) == [("0", False)]


def test_a_users_own_rasteriser_threads_are_kept(monkeypatch):
    monkeypatch.setenv("LP_NUM_THREADS", "3")
    assert _settings_seen_by_the_drawing(monkeypatch) == [("3", False)]


def test_the_forked_process_starts_no_rasteriser_thread_and_draws_the_same_image(tmp_path, monkeypatch):
    """The run's images' process (stages.fea._start_drawing, a fork of this one) has Mesa read the
    setting when VTK first opens its display: no `llvmpipe-N` thread of its own."""
    from fem import render
    from stages import fea

    monkeypatch.delenv("LP_NUM_THREADS", raising=False)  # this process's renders: Mesa's default threads
    solution = analyse_link(plate_link(0.01, order=2), get_material("ti-grade2"), order=2)
    forked, here = tmp_path / "forked.png", tmp_path / "here.png"
    threads = tmp_path / "threads.txt"
    real_render_one = render._render_one

    def render_and_list_threads(*args):
        factor = real_render_one(*args)  # the plotter still open: Mesa's threads, if any, still run
        threads.write_text("\n".join(p.read_text().strip() for p in Path("/proc/self/task").glob("*/comm")))
        return factor

    monkeypatch.setattr(render, "_render_one", render_and_list_threads)
    fea._start_drawing([render.Picture(solution, forked).drawing()]).close()
    monkeypatch.setattr(render, "_render_one", real_render_one)
    render.render_pictures([render.Picture(solution, here)])
    assert threads.read_text() and not [n for n in threads.read_text().split("\n") if n.startswith("llvmpipe")]
    assert np.array_equal(matplotlib.image.imread(forked), matplotlib.image.imread(here))
