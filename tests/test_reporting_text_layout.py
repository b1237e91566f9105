"""reporting.text_layout: texts measured and shaped once per key while a batch is drawn, with the
extents of matplotlib's own drawing and its pixels with each text's origin at the nearest whole
pixel."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.text import Text  # noqa: E402

from reporting import text_layout  # noqa: E402
from reporting.text_layout import cached_text_layout  # noqa: E402

# texts of every kind the layout is computed from: rotation, alignments, lines, math, font, spacing
_TEXTS = [
    dict(s="0.25"),
    dict(s="−500", fontsize=8),
    dict(s="rotated", rotation=45, ha="right", va="top"),
    dict(s="upright", rotation=90, rotation_mode="anchor", ha="left", va="baseline"),
    dict(s="two lines\nthe second longer", multialignment="right", linespacing=1.6),
    dict(s="two lines\ncentred", ha="center", va="center_baseline"),
    dict(s=r"$x^2 - z$ (mm)", family="serif", weight="bold"),
    dict(s=r"$\frac{x}{2} \sqrt{z}$"),  # mathtext with rules (boxes) beside its glyphs
    dict(s="a long text that wraps where it stands " * 3, wrap=True),
    dict(s="0.25", family="monospace", style="italic"),
    dict(s="0.25", rotation=30),  # one string in several fonts and directions: a layout each
    dict(s="0.25", rotation=30, ha="right"),
    dict(s="0.25", va="top"),
    dict(s="0.25", rotation=30, ha="right", fontsize=14),
    dict(s="two lines\nthe second longer", multialignment="right"),
    dict(s="two lines\nthe second longer", multialignment="center", linespacing=1.6),
    dict(s="upright", rotation=90, ha="left", va="baseline"),
]


def _figure():
    fig = plt.figure(figsize=(5, 5), dpi=110)
    for i, spec in enumerate(_TEXTS):
        spec = dict(spec)
        fig.text(0.05 + 0.12 * (i % 3), 0.03 + 0.06 * i, spec.pop("s"), **spec)
    ax = fig.add_axes((0.55, 0.2, 0.4, 0.6))
    ax.plot([0.0, 1.0, 2.0], [-500.0, 0.25, 100.0], label="a line")
    ax.set_ylabel("y (mm)")
    ax.legend()
    return fig


def _pixels(fig) -> np.ndarray:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="rgba", dpi=110)
    return np.frombuffer(buffer.getvalue(), np.uint8)


def _extents(fig) -> list:
    renderer = fig.canvas.get_renderer()
    return [text.get_window_extent(renderer).bounds for text in fig.findobj(Text) if text.get_text()]


def _at_whole_pixels(monkeypatch) -> None:
    """matplotlib's own text drawing with every (non-math) text's origin rounded to a whole pixel."""
    from matplotlib.backends.backend_agg import RendererAgg

    draw_text = RendererAgg.draw_text

    def rounded(renderer, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if not ismath:
            x, y = round(x), round(y)
        return draw_text(renderer, gc, x, y, s, prop, angle, ismath, mtext)

    monkeypatch.setattr(RendererAgg, "draw_text", rounded)


def test_texts_are_laid_out_as_matplotlib_lays_them_out_and_drawn_at_whole_pixels(monkeypatch):
    fig = _figure()
    with monkeypatch.context() as patch:
        if text_layout._WHOLE_STRINGS:
            _at_whole_pixels(patch)
        pixels = _pixels(fig)
    extents = _extents(fig)
    with cached_text_layout():
        twice = [(_pixels(fig), _extents(fig)) for _ in range(2)]  # measured, then from the caches
    plt.close(fig)
    for cached_pixels, cached_extents in twice:
        assert np.array_equal(cached_pixels, pixels)
        assert cached_extents == extents


def test_a_string_measured_again_is_laid_out_once_and_a_changed_text_anew(monkeypatch):
    laid_out = []
    original = Text._get_layout
    monkeypatch.setattr(
        Text, "_get_layout", lambda text, renderer: laid_out.append(text.get_text()) or original(text, renderer)
    )
    fig = plt.figure(figsize=(3, 2), dpi=110)
    first, second = fig.text(0.1, 0.2, "0.25"), fig.text(0.6, 0.7, "0.25")
    renderer = fig.canvas.get_renderer()
    with cached_text_layout():
        box = first.get_window_extent(renderer)
        moved = second.get_window_extent(renderer)
        # the same box at another place (its size read from the moved corners: equal to rounding)
        assert laid_out == ["0.25"] and (box.width, box.height) == pytest.approx((moved.width, moved.height))
        second.set_fontsize(20)
        bigger = second.get_window_extent(renderer)
        second.set_rotation(90)
        turned = second.get_window_extent(renderer)
    plt.close(fig)
    assert laid_out == ["0.25"] * 3
    assert bigger.width > moved.width and turned.height == pytest.approx(bigger.width)


def test_matplotlib_works_as_before_after_the_batch():
    from matplotlib.backends.backend_agg import RendererAgg

    get_layout, prepare_font, draw_text = Text._get_layout, RendererAgg._prepare_font, RendererAgg.draw_text
    try:
        with cached_text_layout():
            assert Text._get_layout is not get_layout
            raise ValueError("a figure failed")
    except ValueError:
        pass
    assert Text._get_layout is get_layout and RendererAgg._prepare_font is prepare_font
    assert RendererAgg.draw_text is draw_text


def _rendered_glyphs(monkeypatch) -> list:
    from matplotlib.ft2font import FT2Font

    rendered = []
    render = FT2Font._render_glyph
    monkeypatch.setattr(FT2Font, "_render_glyph", lambda font, *args: rendered.append(1) or render(font, *args))
    return rendered


# texts' origins (pixels): three whole pixels apart, two at sub-pixel offsets
PLACES_PX = [(20.0, 30.0), (57.0, 30.0), (20.0, 91.0), (20.25, 150.5), (140.0, 200.75)]


def _drawn_both_ways(fig, rendered: list, monkeypatch, whole_pixels: bool) -> tuple[np.ndarray, int, np.ndarray, int]:
    """(pixels, glyph renders) of the figure drawn by matplotlib (each text's origin rounded to a
    whole pixel where `whole_pixels`), then (pixels, glyph renders) drawn with the caches; closes it."""
    with monkeypatch.context() as patch:
        if whole_pixels:
            _at_whole_pixels(patch)
        pixels = _pixels(fig)
    glyphs = len(rendered)
    with cached_text_layout():
        rendered.clear()
        cached = _pixels(fig)
    plt.close(fig)
    return pixels, glyphs, cached, len(rendered)


@pytest.mark.skipif(not text_layout._WHOLE_STRINGS, reason="the string cache is on for CHECKED_MATPLOTLIB only")
def test_a_string_is_rendered_once_per_direction_and_drawn_at_the_nearest_whole_pixel(monkeypatch):
    """One string at places whole pixels apart and at sub-pixel offsets, upright and turned: its
    glyphs rendered once per direction, the pixels of matplotlib's own drawing at the rounded places."""
    from matplotlib.transforms import IdentityTransform

    rendered = _rendered_glyphs(monkeypatch)
    fig = plt.figure(figsize=(3, 3), dpi=110)
    for x, y in PLACES_PX:
        for rotation in (0, 30, 90):
            fig.text(x + 60 * (rotation > 0) + rotation, y, "0.25", rotation=rotation, transform=IdentityTransform())
    pixels, glyphs, cached, cached_glyphs = _drawn_both_ways(fig, rendered, monkeypatch, whole_pixels=True)
    assert np.array_equal(cached, pixels)
    # "0.25": 4 glyphs at each of 5 places in 3 directions (60 renders); cached, 4 per direction
    assert glyphs == 4 * 5 * 3 and cached_glyphs == 4 * 3


@pytest.mark.skipif(not text_layout._GLYPH_BY_GLYPH, reason="the glyph cache is on for CHECKED_MATPLOTLIB only")
def test_a_mathtext_glyph_moved_by_whole_pixels_is_rendered_once_and_drawn_as_matplotlib_draws_it(monkeypatch):
    """Mathtext (drawn glyph by glyph) at places a whole number of pixels apart (one bitmap per
    glyph) and at sub-pixel offsets (a bitmap each): the pixels of matplotlib's own drawing."""
    from matplotlib.transforms import IdentityTransform

    rendered = _rendered_glyphs(monkeypatch)
    fig = plt.figure(figsize=(3, 3), dpi=110)
    for x, y in PLACES_PX:
        fig.text(x, y, "$xz$", transform=IdentityTransform())
    pixels, glyphs, cached, cached_glyphs = _drawn_both_ways(fig, rendered, monkeypatch, whole_pixels=False)
    assert np.array_equal(cached, pixels)
    # 2 glyphs at each of 5 places; the first three places, whole pixels apart, share their bitmaps
    assert glyphs == 2 * 5 and cached_glyphs == 2 * 3


def test_overlapping_glyphs_combine_as_one_drawn_over_the_other():
    """Two glyphs' coverages a and b where they overlap: 1 - (1 - a)(1 - b), as Agg blends the
    second over the first; the bitmap's corner is the glyphs' top left, rows downwards."""
    font = object()
    first, second = np.full((2, 3), 255 // 2, np.uint8), np.full((2, 2), 255, np.uint8)
    second[1, 0] = 51  # coverage 0.2 over the first's 127/255: 0.6, 153

    def key(glyph, place):
        return (font, 10.0, 110.0, glyph, 0, 0.0, 1.0, place[0] & 63, place[1] & 63, "flags", True)

    # glyph 1 at the origin, its corner 4 above the baseline; glyph 2 two pixels right, 5 above
    bitmaps = {key(1, (0, 0)): (first, 0, 4), key(2, (128, 0)): (second, 0, 5)}
    bitmap, left, top = text_layout.string_bitmap(
        [(font, 10.0, 1, 0.0, 0.0), (font, 10.0, 2, 2.0, 0.0)], 0, bitmaps, 110.0, "flags", True
    )
    assert (left, top) == (0, -5)
    expected = np.array([[0, 0, 255, 255], [127, 127, 153, 255], [127, 127, 127, 0]], np.uint8)
    assert np.array_equal(bitmap, expected)


def test_caches_switched_on_within_caches_leave_matplotlib_as_it_was_when_the_first_ends():
    """A draw_figures call within another (or in another thread): the inner one uses the outer's
    caches, and matplotlib's own methods are back once the outer one ends, whatever the order."""
    original = Text._get_layout
    outer = text_layout.install_text_layout_cache()
    cached = Text._get_layout
    with cached_text_layout():
        assert Text._get_layout is cached
    assert Text._get_layout is cached
    outer()
    assert Text._get_layout is original
    with cached_text_layout():
        inner = text_layout.install_text_layout_cache()
    assert Text._get_layout is original
    inner()  # after the first one's end: nothing to undo
    assert Text._get_layout is original


def test_the_shaping_and_glyph_caches_replace_only_the_checked_matplotlib():
    version = tuple(int(part) for part in matplotlib.__version__.split(".")[:2])
    checked = version == text_layout.CHECKED_MATPLOTLIB
    assert text_layout._GLYPH_BY_GLYPH == checked
    assert text_layout._SHAPES_STRINGS == checked
