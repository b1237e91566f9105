"""Text measured, shaped and rendered once per string and glyph while figures are drawn.

matplotlib works out a text's layout (its lines' extents: the font looked up, two of its tables
read, the string measured by FreeType) every time it needs the text's extent: 2-4 times per tick
label in one draw (the tick labels' boxes, the axis label's placement, the draw itself), again on
every figure (its metrics cache lives with one renderer, and each figure's canvas has its own); the
Agg renderer shapes every string again when it draws it (HarfBuzz, about 0.6 ms for "0.25"), and
renders every glyph again (FreeType loads, hints and rasterises it, reading the font file). The
default run's 15 figures draw 648 texts of 131 strings (4,238 glyphs, 2,006 of them distinct to
the sub-pixel), and measure texts 1,766 times.

`install_text_layout_cache()` (for the rest of a figure worker's life) or `cached_text_layout()` (for a
block) keep
- a text's layout (`Text._get_layout`: its box and lines relative to its anchor) under what it is
  computed from: the string, the font properties, the rotation, the alignments, the line spacing,
  the figure's and the renderer's dpi (texts that wrap, whose lines depend on where they stand, and
  TeX texts are measured as before);
- a string's shaping by the Agg renderer (the glyphs and their offsets from `FT2Font._layout`)
  under the font properties, the dpi and the shaping's arguments;
- a glyph's bitmap under its font, size, direction and place modulo whole pixels (`_glyph_bitmap`);
- a string's bitmap (its glyphs composited) under the font properties, the dpi, the direction and
  the shaping's arguments, drawn with the text's origin at the nearest whole pixel
  (`_string_drawer`): one image draw per text instead of one per glyph, and the glyphs rendered
  once per string instead of once per sub-pixel offset. Mathtext is drawn glyph by glyph.
Each is a pure function of its key, so the pixels are those of matplotlib's own drawing with every
text's origin rounded to a whole pixel (a text moves by at most half a pixel each way;
tests/test_reporting_text_layout.py). The
caches hold what one draw_figures call draws (a few hundred strings, a few thousand glyph bitmaps of
a few dozen bytes), during which the rcParams stay as they are (the report's plots set none).

They rely on matplotlib's private `Text._get_layout` and, for the shaping, the glyphs and the
strings, `RendererAgg._prepare_font`, `RendererAgg._draw_text_glyphs_and_boxes`, `FT2Font._layout`
and `FT2Font._render_glyph` (matplotlib 3.11, `CHECKED_MATPLOTLIB`), and replace the Agg renderer's
`draw_text`; with another matplotlib the shaping, glyphs and strings are matplotlib's own.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import matplotlib
import numpy as np
from matplotlib import ft2font
from matplotlib.backends.backend_agg import RendererAgg, get_hinting_flag
from matplotlib.text import Text

# The matplotlib whose private drawing methods the shaping and glyph caches replace, and were
# checked against pixel for pixel (tests/test_reporting_text_layout.py): another version (pyproject
# allows matplotlib>=3.8) may keep a method's name and change what it does, so there matplotlib draws
# its text itself.
CHECKED_MATPLOTLIB = (3, 11)
_CHECKED = tuple(int(part) for part in matplotlib.__version__.split(".")[:2]) == CHECKED_MATPLOTLIB

# matplotlib 3.11's glyph-by-glyph Agg text drawing and string shaping (older versions have neither)
_GLYPH_BY_GLYPH = _CHECKED and all(
    (
        hasattr(ft2font, "RenderMode"),
        hasattr(ft2font.FT2Font, "_render_glyph"),
        hasattr(RendererAgg, "_draw_text_glyphs_and_boxes"),
    )
)
_SHAPES_STRINGS = _CHECKED and hasattr(ft2font.FT2Font, "_layout") and hasattr(RendererAgg, "_prepare_font")
# a text's string drawn as one bitmap at a whole pixel: needs both
_WHOLE_STRINGS = _GLYPH_BY_GLYPH and _SHAPES_STRINGS

_installed = False  # the caches are on (matplotlib's methods replaced) in this process

# What Text._get_layout reads of a text besides its string, font, rotation and dpi (matplotlib 3.11);
# an attribute an older matplotlib lacks is None in the key
_LAYOUT_ATTRIBUTES = (
    "_horizontalalignment",
    "_verticalalignment",
    "_multialignment",
    "_rotation_mode",
    "_linespacing",
    "_parse_math",
    "_features",
    "_language",
)


def _font_key(properties) -> tuple:
    """A FontProperties' state (family, style, weight, size, file...), as its own hash reads it."""
    return tuple(vars(properties).items())


def _layout_key(text: Text, renderer) -> tuple | None:
    """What `text`'s layout is computed from, or None where it depends on more (wrapped or TeX text)."""
    if text.get_wrap() or text.get_usetex():
        return None
    return (
        type(text),
        text.get_text(),
        _font_key(text.get_fontproperties()),
        text.get_rotation(),
        text.get_figure(root=True).dpi,
        type(renderer),
        getattr(renderer, "dpi", None),
        *(getattr(text, name, None) for name in _LAYOUT_ATTRIBUTES),
    )


def _glyph_bitmap(bitmaps: dict, font, size, dpi, glyph, angle, slant, extend, place, flags, antialiased):
    """A glyph's coverage bitmap placed at `place` (1/64 pixel, FreeType's y upwards) and its corner
    relative to the place's whole pixel (left, top), rendered once per font, size, direction and
    sub-pixel offset: FreeType rasterises a glyph at its place given in 1/64 pixel, and a glyph moved
    by whole pixels is the same bitmap moved by them."""
    key = (font, size, dpi, glyph, angle, slant, extend, place[0] & 63, place[1] & 63, flags, antialiased)
    drawn = bitmaps.get(key)
    if drawn is None:
        cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
        font.set_size(size, dpi)
        matrix = 0x10000 * np.array([[cos, -sin], [sin, cos]]) @ [[extend, extend * slant], [0, 1]]
        font._set_transform(matrix.round().astype(int), list(place))
        bitmap = font._render_glyph(glyph, flags, ft2font.RenderMode.NORMAL if antialiased else ft2font.RenderMode.MONO)
        buffer = bitmap.buffer if antialiased else bitmap.buffer * 0xFF
        drawn = bitmaps[key] = (buffer, bitmap.left - (place[0] >> 6), bitmap.top - (place[1] >> 6))
    return drawn


def _glyph_drawer(draw_glyphs_and_boxes, bitmaps: dict):
    """RendererAgg._draw_text_glyphs_and_boxes (matplotlib 3.11; mathtext's glyphs) with each glyph's
    bitmap from `_glyph_bitmap`. The boxes (mathtext's rules) are matplotlib's own."""

    def draw(renderer, gc, x, y, angle, glyphs, boxes):
        cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
        flags, antialiased = get_hinting_flag(), gc.get_antialiased()
        for font, size, glyph, slant, extend, dx, dy in glyphs:  # dy upwards, as FreeType's y
            place = (
                round(0x40 * (x + dx * cos - dy * sin)),
                round(0x40 * (renderer.height - y + dx * sin + dy * cos)),
            )
            buffer, left, top = _glyph_bitmap(
                bitmaps, font, size, renderer.dpi, glyph, angle, slant, extend, place, flags, antialiased
            )
            # draw_text_image's y is downwards, at the bitmap's bottom
            bottom = int(renderer.height) - (top + (place[1] >> 6)) + buffer.shape[0]
            renderer._renderer.draw_text_image(buffer, left + (place[0] >> 6), bottom, 0, gc)
        boxes = list(boxes)
        if boxes:
            draw_glyphs_and_boxes(renderer, gc, x, y, angle, (), boxes)

    return draw


def string_bitmap(glyphs, angle: float, bitmaps: dict, dpi: float, flags, antialiased: bool):
    """A shaped string's glyphs (FT2Font._layout's items: font, glyph index, offset in pixels, y
    upwards) composited into one coverage bitmap for a text whose origin is a whole pixel, and the
    bitmap's left column and top row (downwards) relative to that pixel; None for a string without
    ink. Each glyph is placed as matplotlib places it (to 1/64 pixel, `_glyph_bitmap`); where two
    glyphs' bitmaps overlap, their coverages combine as Agg blends one over the other."""
    cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    placed = []
    for font, size, glyph, dx, dy in glyphs:
        place = (round(0x40 * (dx * cos - dy * sin)), round(0x40 * (dx * sin + dy * cos)))
        buffer, left, top = _glyph_bitmap(bitmaps, font, size, dpi, glyph, angle, 0.0, 1.0, place, flags, antialiased)
        if buffer.size:
            placed.append((buffer, left + (place[0] >> 6), -(top + (place[1] >> 6))))  # row downwards
    if not placed:
        return None
    left = min(column for _, column, _ in placed)
    top = min(row for _, _, row in placed)
    width = max(column + buffer.shape[1] for buffer, column, _ in placed) - left
    height = max(row + buffer.shape[0] for buffer, _, row in placed) - top
    clear = np.ones((height, width))  # 1 - coverage
    for buffer, column, row in placed:
        clear[row - top : row - top + buffer.shape[0], column - left : column - left + buffer.shape[1]] *= (
            1.0 - buffer / 255.0
        )
    return np.round(255.0 * (1.0 - clear)).astype(np.uint8), left, top


def _string_drawer(draw_text, bitmaps: dict, strings: dict):
    """RendererAgg.draw_text with a text's origin at the nearest whole pixel and its string drawn as
    one bitmap (`string_bitmap`), made once per string, font properties, dpi, direction and shaping
    arguments: one Agg image draw per text instead of one per glyph, and the bitmaps rendered once
    per string instead of once per glyph and sub-pixel offset (the texts of a run's figures stand at
    as many sub-pixel offsets as they have glyphs). A text moves by at most half a pixel each way
    from where matplotlib 3.11 draws it (matplotlib before 3.11 drew text at whole pixels too).
    Mathtext is drawn by `draw_text` (matplotlib's, with the glyph cache)."""

    def draw(renderer, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if ismath:
            return draw_text(renderer, gc, x, y, s, prop, angle, ismath, mtext)
        features = mtext.get_fontfeatures() if mtext is not None else None
        language = mtext.get_language() if mtext is not None else None
        flags, antialiased = get_hinting_flag(), gc.get_antialiased()
        key = (
            _font_key(prop),
            renderer.dpi,
            s,
            angle,
            flags,
            antialiased,
            None if features is None else tuple(features),
            language,
        )
        if key not in strings:
            items = renderer._prepare_font(prop)._layout(s, flags=flags, features=features, language=language)
            size = prop.get_size_in_points()
            glyphs = [(item.ft_object, size, item.glyph_index, item.x, item.y) for item in items]
            strings[key] = string_bitmap(glyphs, angle, bitmaps, renderer.dpi, flags, antialiased)
        drawn = strings[key]
        if drawn is None:
            return
        buffer, left, top = drawn
        # y is downwards here; draw_text_image's y is at the bitmap's bottom
        renderer._renderer.draw_text_image(buffer, round(x) + left, round(y) + top + buffer.shape[0], 0, gc)

    return draw


class _PreparedFont:
    """What RendererAgg._prepare_font returns, the font prepared (looked up, cleared, sized) only
    when it is used for more than a string's shaping, and the shaping served from `shapes`."""

    def __init__(self, prepare, key: tuple, shapes: dict) -> None:
        self._prepare, self._key, self._shapes, self._font = prepare, key, shapes, None

    def _prepared(self):
        if self._font is None:
            self._font = self._prepare()
        return self._font

    def _layout(self, text, flags, features=None, language=None):
        key = (self._key, text, flags, None if features is None else tuple(features), language)
        items = self._shapes.get(key)
        if items is None:
            items = self._shapes[key] = tuple(
                self._prepared()._layout(text, flags=flags, features=features, language=language)
            )
        return items

    def __getattr__(self, name):
        return getattr(self._prepared(), name)


def install_text_layout_cache() -> Callable[[], None]:
    """From now on, texts' layouts, the Agg renderer's shaping of strings and its glyphs' bitmaps are
    computed once per key (module docstring); returns what puts matplotlib's own methods back and
    drops the caches. Where they are on already (a draw_figures call within another, or in another
    thread) nothing changes, and the returned function does nothing: the first one's undo is the
    undo."""
    global _installed
    if _installed:
        return lambda: None
    get_layout = Text._get_layout
    prepare_font = getattr(RendererAgg, "_prepare_font", None)
    draw_glyphs_and_boxes = getattr(RendererAgg, "_draw_text_glyphs_and_boxes", None)
    draw_text = RendererAgg.draw_text
    layouts: dict[tuple, tuple] = {}
    shapes: dict[tuple, tuple] = {}
    bitmaps: dict[tuple, tuple] = {}
    strings: dict[tuple, tuple | None] = {}

    def cached_layout(text, renderer):
        key = _layout_key(text, renderer)
        if key is None:
            return get_layout(text, renderer)
        layout = layouts.get(key)
        if layout is None:
            layout = layouts[key] = get_layout(text, renderer)
        box, lines, descent = layout
        return box.frozen(), list(lines), descent  # the callers' own copies: they may move the box

    def lazily_prepared_font(renderer, properties):
        return _PreparedFont(lambda: prepare_font(renderer, properties), (_font_key(properties), renderer.dpi), shapes)

    def uninstall() -> None:
        global _installed
        _installed = False
        Text._get_layout = get_layout
        if _SHAPES_STRINGS:
            RendererAgg._prepare_font = prepare_font
        if _GLYPH_BY_GLYPH:
            RendererAgg._draw_text_glyphs_and_boxes = draw_glyphs_and_boxes
        if _WHOLE_STRINGS:
            RendererAgg.draw_text = draw_text
        for cache in (layouts, shapes, bitmaps, strings):
            cache.clear()

    Text._get_layout = cached_layout
    if _SHAPES_STRINGS:
        RendererAgg._prepare_font = lazily_prepared_font
    if _GLYPH_BY_GLYPH:
        RendererAgg._draw_text_glyphs_and_boxes = _glyph_drawer(draw_glyphs_and_boxes, bitmaps)
    if _WHOLE_STRINGS:
        RendererAgg.draw_text = _string_drawer(draw_text, bitmaps, strings)
    _installed = True
    return uninstall


@contextmanager
def cached_text_layout() -> Iterator[None]:
    """`install_text_layout_cache` while the block runs, matplotlib as before after it."""
    uninstall = install_text_layout_cache()
    try:
        yield
    finally:
        uninstall()
