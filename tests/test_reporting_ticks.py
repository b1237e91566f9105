"""reporting.ticks: an axis's ticks made as copies while figures are drawn, with the pixels of
matplotlib's own ticks."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.axis import Axis, XTick, YTick  # noqa: E402

from reporting import ticks  # noqa: E402
from reporting.ticks import copied_ticks  # noqa: E402

checked_only = pytest.mark.skipif(not ticks._CHECKED, reason="tick copies replace only the checked matplotlib")


def _figure():
    """Axes of every kind the report draws ticks on, and some it does not: shared rows and columns
    (inner labels hidden), a grid, tick parameters set per axes, a log axis (minor ticks), fixed
    rotated labels, a colorbar, labels in a box, a twin axis with ticks on the right."""
    fig, axes = plt.subplots(2, 3, figsize=(9, 5), dpi=110, sharex=True, sharey="row")
    t = np.linspace(0.0, 1.0, 200)
    for i, ax in enumerate(axes.flat):
        ax.plot(t, np.sin(2 * np.pi * (i + 1) * t) * 10.0 ** (i % 3), lw=0.9)
        ax.grid(alpha=0.3)
    axes[0, 1].tick_params(direction="in", color="tab:red", length=6, labelsize=7, labelrotation=30)
    axes[1, 0].set_yscale("symlog")
    axes[1, 1].set_xticks([0.1, 0.5, 0.9], ["one", "two", "three"], rotation=20)
    for label in axes[1, 2].get_yticklabels() + axes[1, 2].get_xticklabels()[:1]:
        label.set_bbox(dict(facecolor="0.9", pad=1.0))
    axes[0, 2].twinx().plot(t, t**2 * 1e3, color="k")
    image = axes[1, 2].inset_axes((0.6, 0.6, 0.35, 0.35)).imshow(np.outer(t[:20], t[:30]), aspect="auto")
    fig.colorbar(image, ax=axes[:, 2])
    logax = fig.add_axes((0.05, 0.05, 0.2, 0.1))
    logax.loglog(t[1:], t[1:] ** 3)
    return fig


def _pixels(fig) -> np.ndarray:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="rgba", dpi=110)
    return np.frombuffer(buffer.getvalue(), np.uint8)


def _drawn_twice(fig) -> tuple[np.ndarray, np.ndarray]:
    """The figure's pixels, then those with its views moved (more and other ticks on the same axes)."""
    first = _pixels(fig)
    for ax in fig.axes[:6]:
        low, high = ax.get_xlim()
        ax.set_xlim(low - 0.3, high + 0.05)
    return first, _pixels(fig)


def _ticks_made(monkeypatch) -> list:
    """The ticks matplotlib's constructors make from now on."""
    made = []
    for kind in (XTick, YTick):
        init = kind.__init__

        def counted(tick, *args, init=init, **kwargs):
            made.append(tick)
            init(tick, *args, **kwargs)

        monkeypatch.setattr(kind, "__init__", counted)
    return made


@checked_only
def test_ticks_copied_draw_the_pixels_of_ticks_made_by_matplotlib(monkeypatch):
    made = _ticks_made(monkeypatch)
    fig = _figure()
    own = _drawn_twice(fig)
    plt.close(fig)
    made_by_matplotlib = len(made)
    made.clear()
    with copied_ticks():
        fig = _figure()
        copied = _drawn_twice(fig)
        plt.close(fig)
    assert all(np.array_equal(a, b) for a, b in zip(own, copied))
    # only the templates (a few kinds of tick parameters) and the boxed labels' ticks are made
    assert 0 < len(made) < made_by_matplotlib / 4


@checked_only
def test_a_copied_tick_has_its_own_state_where_matplotlib_changes_it_in_place():
    fig, ax = plt.subplots()
    with copied_ticks():
        fig.canvas.draw()
        first, second = ax.xaxis.get_major_ticks(2)
    assert second is not first and second.axes is ax
    for name in ("tick1line", "tick2line", "gridline", "label1", "label2"):
        a, b = getattr(first, name), getattr(second, name)
        assert a is not b and a._callbacks is not b._callbacks
    assert second.label1.get_fontproperties() is not first.label1.get_fontproperties()
    second.label1.set_fontsize(20)
    assert first.label1.get_fontsize() != 20
    plt.close(fig)


def _boxes_of_ticks_made_after_a_boxed_first() -> list:
    fig, ax = plt.subplots()
    ax.xaxis.get_major_ticks(1)[0].label1.set_bbox(dict(facecolor="0.9"))
    fig.canvas.draw()
    boxes = [tick.label1.get_bbox_patch() for tick in ax.xaxis.get_major_ticks()]
    plt.close(fig)
    return boxes


@checked_only
def test_the_ticks_an_axis_with_a_boxed_first_label_lacks_are_made_by_matplotlib():
    """matplotlib does not give its new ticks the first's label box (a patch it moves in place to
    the label's place as it draws it); a copy would share it."""
    own = _boxes_of_ticks_made_after_a_boxed_first()
    with copied_ticks():
        copied = _boxes_of_ticks_made_after_a_boxed_first()
    assert len(own) > 2 and [box is None for box in copied] == [box is None for box in own]


@checked_only
def test_a_first_tick_moved_from_a_template_has_its_own_axes_transforms():
    fig, (left, right) = plt.subplots(1, 2)
    with copied_ticks():
        fig.canvas.draw()
        for ax in (left, right):
            tick = ax.yaxis.get_major_ticks()[0]
            assert tick.axes is ax
            assert tick.gridline.get_transform() == ax.get_yaxis_transform("grid")
            assert tick.label1.get_transform() == tick._get_text1_transform()[0]
    plt.close(fig)


@checked_only
def test_matplotlib_makes_its_ticks_itself_after_the_block_and_within_a_block_the_outer_one_decides():
    get_major_ticks, get_tick = Axis.get_major_ticks, Axis._get_tick
    outer = ticks.install_tick_copies()
    replaced = Axis.get_major_ticks
    assert replaced is not get_major_ticks and Axis._get_tick is not get_tick
    with copied_ticks():
        assert Axis.get_major_ticks is replaced
    assert Axis.get_major_ticks is replaced
    outer()
    assert Axis.get_major_ticks is get_major_ticks and Axis._get_tick is get_tick and not ticks._TEMPLATES


def test_another_matplotlib_makes_its_ticks_itself(monkeypatch):
    monkeypatch.setattr(ticks, "_CHECKED", False)
    get_major_ticks = Axis.get_major_ticks
    with copied_ticks():
        assert Axis.get_major_ticks is get_major_ticks
