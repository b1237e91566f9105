"""An axis's ticks made as copies while figures are drawn.

matplotlib makes an axis's ticks lazily, as many as its locator asks for on a draw
(`Axis.get_major_ticks`): each a new `Tick` (two tick lines, a grid line and two labels, each set up
from the axis's tick parameters and the rcParams: markers, font properties, transforms), whose
properties it then copies from the axis's first tick (`Axis._copy_tick_props`, which copies every
line's marker anew): 0.8-1 ms a tick, and 291 of the 423 ticks the default run's 15 figures make.
The other 132 are the first major and minor tick of each new axes's x and y axis, made from the
axis's tick parameters (`Axis._get_tick`). Making ticks was about 15 % of drawing the 15 figures
(py-spy).

`install_tick_copies()` (for the rest of a figure worker's life) or `copied_ticks()` (for a block)
make those ticks as copies instead (`copied_tick`: the tick and its five artists copied attribute by
attribute, each with its own callbacks, sticky edges and font properties, the only state of theirs
that is changed in place, sharing what matplotlib's own copy shares (transforms, clip box, path
effects) and what is only ever replaced, never changed (markers, data arrays, paths)):
- a tick an axis lacks: a copy of its first tick. matplotlib's copy gives the new tick every
  property of the first it draws with; this copy also gives it the first tick's position, string
  and data, which the axis sets anew on every tick it draws (`Axis._update_ticks`) before it is
  drawn. Where the first tick's label has a box (`Text.set_bbox`, a patch moved in place as the
  label is drawn), which matplotlib does not give the ticks it adds, matplotlib makes them;
- an axis's first tick: a copy of a tick matplotlib made for an axis of the same kind (x or y, major
  or minor) with the same tick parameters, kept unused and unchanged as a template, moved to the
  axis's axes and figure (their transforms in place of the template's, as its constructor sets
  them). Its other state comes from the tick parameters and the rcParams alone, which stay as they
  are while the figures are drawn (the report's plots set none).
The pixels are those of matplotlib's own ticks (tests/test_reporting_ticks.py).

It replaces matplotlib's `Axis.get_major_ticks` and `Axis._get_tick` on the matplotlib it was checked
against (`CHECKED_MATPLOTLIB`, 3.11; another version makes its ticks itself), for the x and y axes of
rectilinear axes (`XAxis`, `YAxis`: other projections' ticks are made by matplotlib).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

import matplotlib
from matplotlib import cbook
from matplotlib.axis import Axis, XAxis, XTick, YAxis
from matplotlib.text import Text

# The matplotlib whose Tick and Axis.get_major_ticks the copies were checked against, pixel for pixel:
# another version may give a tick other state, changed in place, that a copy would share
CHECKED_MATPLOTLIB = (3, 11)
_CHECKED = tuple(int(part) for part in matplotlib.__version__.split(".")[:2]) == CHECKED_MATPLOTLIB

_TICK_ARTISTS = ("tick1line", "tick2line", "gridline", "label1", "label2")

_installed = False  # matplotlib's Axis.get_major_ticks and Axis._get_tick replaced in this process
_MATPLOTLIB_GET_MAJOR_TICKS = Axis.get_major_ticks
_MATPLOTLIB_GET_TICK = Axis._get_tick
# the templates of first ticks, while installed, under their axis class, major or minor and tick parameters
_TEMPLATES: dict[tuple, object] = {}
_PLAIN = (str, int, float, bool, type(None))  # tick parameters' types compared for a template


def _copied_artist(artist):
    """A copy of the artist sharing its attributes but those changed in place."""
    copy = object.__new__(type(artist))
    copy.__dict__.update(artist.__dict__)
    copy._callbacks = cbook.CallbackRegistry(signals=["pchanged"])
    if artist._sticky_edges is not None:
        copy._sticky_edges = None
        copy.sticky_edges.x[:] = artist._sticky_edges.x
        copy.sticky_edges.y[:] = artist._sticky_edges.y
    if isinstance(artist, Text):
        copy._fontproperties = artist._fontproperties.copy()
    return copy


def copied_tick(tick):
    """A new tick of the same axis as `tick`, drawn as `tick` is until the axis places and labels it."""
    copy = _copied_artist(tick)
    for name in _TICK_ARTISTS:
        setattr(copy, name, _copied_artist(getattr(tick, name)))
    return copy


def _get_major_ticks(axis: Axis, numticks: int | None = None) -> list:
    """`Axis.get_major_ticks` with the ticks it lacks copied from its first (`copied_tick`) instead of
    made and given the first's properties."""
    if numticks is None:
        numticks = len(axis.get_majorticklocs())
    ticks = axis.majorTicks  # the first tick is made by matplotlib (a lazy list)
    if len(ticks) < numticks and _boxed(ticks[0]):
        return _MATPLOTLIB_GET_MAJOR_TICKS(axis, numticks)
    while len(ticks) < numticks:
        ticks.append(copied_tick(ticks[0]))
    return ticks[:numticks]


def _get_tick(axis: Axis, major: bool):
    """`Axis._get_tick`: a copy of the template tick of the axis's kind and tick parameters (made
    by matplotlib the first time), moved to the axis's axes (module docstring)."""
    parameters = axis._major_tick_kw if major else axis._minor_tick_kw
    # a parameter of another type (a colour as a tuple, an array) is not compared: matplotlib's tick
    if type(axis) not in (XAxis, YAxis) or any(type(value) not in _PLAIN for value in parameters.values()):
        return _MATPLOTLIB_GET_TICK(axis, major)
    # the value's type in the key: True, 1 and 1.0 are equal keys
    key = (type(axis), major, frozenset((name, type(value), value) for name, value in parameters.items()))
    template = _TEMPLATES.get(key)
    if template is None:
        template = _TEMPLATES[key] = _MATPLOTLIB_GET_TICK(axis, major)
    return _moved(copied_tick(template), axis)


def _moved(tick, axis: Axis):
    """A copy of a template tick put on the axis's axes and figure, with the transforms its
    constructor gives a tick of that axes (`XTick.__init__`, `YTick.__init__`)."""
    axes = axis.axes
    figure = axes.get_figure(root=False)
    tick._axes = axes  # the `axes` setter refuses a move; the copy is no one's yet
    tick._parent_figure = figure
    for name in _TICK_ARTISTS:
        getattr(tick, name)._parent_figure = figure
    lines_transform = axes.get_xaxis_transform if isinstance(tick, XTick) else axes.get_yaxis_transform
    tick.tick1line._transform = lines_transform("tick1")
    tick.tick2line._transform = lines_transform("tick2")
    tick.gridline._transform = lines_transform("grid")
    tick.label1._transform = tick._get_text1_transform()[0]
    tick.label2._transform = tick._get_text2_transform()[0]
    return tick


def _boxed(tick) -> bool:
    """The tick's labels drawn in a box (`Text.set_bbox`): a patch each label moves in place, made
    anew for each tick by matplotlib."""
    return tick.label1.get_bbox_patch() is not None or tick.label2.get_bbox_patch() is not None


def install_tick_copies() -> Callable[[], None]:
    """From now on, ticks are made as copies (module docstring); returns what puts matplotlib's own
    `Axis.get_major_ticks` and `Axis._get_tick` back and drops the templates. Where they are on
    already, or on a matplotlib other than CHECKED_MATPLOTLIB, nothing changes and the returned
    function does nothing."""
    global _installed
    if _installed or not _CHECKED:
        return lambda: None

    def uninstall() -> None:
        global _installed
        _installed = False
        Axis.get_major_ticks = _MATPLOTLIB_GET_MAJOR_TICKS
        Axis._get_tick = _MATPLOTLIB_GET_TICK
        _TEMPLATES.clear()

    Axis.get_major_ticks = _get_major_ticks
    Axis._get_tick = _get_tick
    _installed = True
    return uninstall


@contextmanager
def copied_ticks() -> Iterator[None]:
    """`install_tick_copies` while the block runs, matplotlib as before after it."""
    uninstall = install_tick_copies()
    try:
        yield
    finally:
        uninstall()
