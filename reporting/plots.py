"""Matplotlib figures of the chain response: the 2012 report's figures plus residual vibration and tension.

Displacements are drawn in mm (cam lifts are tens of mm), velocities in m/s, accelerations in m/s^2,
tensions in kN. Every function writes one PNG and returns its path.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from reporting.history import CamHistory  # noqa: E402
from reporting.png import write_png  # noqa: E402

if TYPE_CHECKING:
    from dynamics.response.sweep import SweepResult

CAM_COLOURS = {
    "modified-sine": "tab:red",
    "modified-trapezoid": "tab:blue",
    "cycloidal": "tab:purple",
    "poly-345": "tab:green",
    "poly-4567": "black",
    "simple-harmonic": "tab:orange",
}
DPI = 110
PAD_INCHES = 0.1  # around what is drawn, as savefig's bbox_inches="tight" (its default pad)
# the canvas is drawn this much larger on every side than the figure, for what lies outside it (the
# y labels of a narrow figure, rotated tick labels): without it 3 of the default run's 15 figures
# were drawn twice more by bbox_inches="tight"
MARGIN_INCHES = 0.5
GRID_ALPHA = 0.3  # the grid lines' opacity on every axes of the report
QUANTITIES = (
    ("displacement (mm)", lambda h: h.x_m * 1e3, lambda h: h.z_m * 1e3),
    ("velocity (m/s)", lambda h: h.v_m_s, lambda h: h.zdot_m_s),
    ("acceleration (m/s²)", lambda h: h.a_m_s2, lambda h: h.zddot_m_s2),
)


def _colour(cam: str) -> str:
    return CAM_COLOURS.get(cam, "tab:gray")


def _save(fig, path: Path) -> Path:
    """The figure as a PNG cropped to what is drawn, in one draw.

    savefig's bbox_inches="tight" draws a figure twice (once to find the artists' extent, once to
    render): 4.1 of the 5.2 s of the widest figure, profiled. Here it is rendered once, at DPI, on
    a canvas grown by MARGIN_INCHES on every side (savefig with an explicit bbox_inches: everything
    stays where it is in inches, as bbox_inches="tight" keeps it), and the pixels are cropped to the
    ink plus savefig's pad (`cropped_to_ink`). Only a figure whose ink still reaches the grown
    canvas's edge is saved the two-draw way. Titles are placed without matplotlib's search for
    ticks above the axes (none here: the x ticks are at the bottom) unless a y-axis offset text
    stands where the title goes; then the figure is drawn again with the search (`_titles_clear`).
    Axes without an x or y label do not place it (`_fix_empty_label_positions`). The PNG is
    written by `reporting.png` (RGB where every pixel is opaque)."""
    titled = _fix_title_positions(fig)
    unlabelled = _fix_empty_label_positions(fig)
    pixels = _rendered(fig)
    if not _titles_clear(titled):
        for ax in titled:
            ax._autotitlepos = True  # matplotlib's own flag: place the title above the offset text
        pixels = _rendered(fig)
    for axis in unlabelled:
        axis._autolabelpos = True
    background = np.round(np.asarray(matplotlib.colors.to_rgba(fig.get_facecolor())) * 255).astype(np.uint8)
    cropped = cropped_to_ink(pixels, background, round(PAD_INCHES * DPI))
    if cropped is None:
        fig.savefig(path, dpi=DPI, bbox_inches="tight", pad_inches=PAD_INCHES)
    else:
        write_png(path, opaque(cropped), DPI)
    layout = _LAYOUT_OF.pop(fig, None)
    if layout is None:
        plt.close(fig)
    else:
        _SPARE[layout] = fig
    return path


# A drawn figure of each layout, kept for the next figure of the same grid of axes (reporting.drawing
# draws the figures of a layout one after the other): its axes and their ticks drawn again instead
# of created (a second 3 x 5 figure 0.42 instead of 0.66-0.76 CPU s, the same pixels)
_SPARE: dict[tuple, Figure] = {}
_LAYOUT_OF: dict[Figure, tuple] = {}


def _subplots(nrows: int, ncols: int, figsize: tuple[float, float], sharex: bool = False, sharey: bool | str = False):
    """plt.subplots(nrows, ncols, figsize=figsize, sharex=sharex, sharey=sharey, squeeze=False), every axes with
    the report's grid (GRID_ALPHA), or the spare figure the last call for the same grid drew (for any
    plot, at any size), emptied (`_emptied`) and set to `figsize` (the axes keep their places as
    fractions of the figure, as a new figure's); `_save` keeps the figure as the spare. The plot
    must set again everything it sets on the axes but their lines, legends and titles (the grid is
    the spare's already: set again on every tick of a spare, about 2 % of the figures' CPU in a profile)."""
    layout = (nrows, ncols, sharex, sharey)
    fig = _SPARE.pop(layout, None)
    if fig is None:
        fig, axes = plt.subplots(nrows, ncols, figsize=figsize, sharex=sharex, sharey=sharey, squeeze=False)
        for ax in fig.axes:
            ax.xaxis.set_major_locator(InViewLocator())
            ax.yaxis.set_major_locator(InViewLocator())
            ax.grid(alpha=GRID_ALPHA)
    else:
        axes = _emptied(fig).reshape(nrows, ncols)
        fig.set_size_inches(figsize)
    _LAYOUT_OF[fig] = layout
    return fig, axes


class InViewLocator(matplotlib.ticker.AutoLocator):
    """matplotlib's default tick locator, without the ticks it places beyond the axis's view.

    AutoLocator adds a tick past each end of the view, which matplotlib makes (three lines and
    two texts), positions and labels on every draw but does not draw: 30 % of the default run's
    figures' ticks. The formatter then sees only the ticks in view: its offset and order of
    magnitude came from those alone already, and its number of decimals (the fewest that write
    every tick it sees) is the same for ticks of one step. The ticks drawn and their labels are
    the same (the default run's PNGs pixel for pixel, benchmarks/bench_figures.py)."""

    def __call__(self):
        locs = super().__call__()
        low, high = sorted(self.axis.get_view_interval())
        # a tick a rounding error outside the view is kept: matplotlib's own test decides
        slack = 1e-9 * (high - low)
        return locs[(locs >= low - slack) & (locs <= high + slack)]


def _emptied(fig: Figure) -> np.ndarray:
    """The figure's axes (in the order made) without their lines, legends and titles, their data
    limits forgotten (as new axes' are), and the figure without its suptitle."""
    for ax in fig.axes:
        for line in list(ax.lines):
            line.remove()
        if ax.get_legend() is not None:
            ax.get_legend().remove()
        ax.set_title("")
        ax.relim()  # no lines: the null box, ignored by the next line's limits as a new axes' is
    if fig._suptitle is not None:
        fig._suptitle.set_text("")
    return np.array(fig.axes, dtype=object)


def close_spare_figures() -> None:
    """Close the figures kept for reuse (`_subplots`) and any left unsaved by a failed plot."""
    for fig in [*_SPARE.values(), *_LAYOUT_OF]:
        plt.close(fig)
    _SPARE.clear()
    _LAYOUT_OF.clear()


def _rendered(fig) -> np.ndarray:
    """The figure's RGBA pixels at DPI, drawn once on a canvas MARGIN_INCHES larger on every side."""
    from matplotlib.transforms import Bbox

    width, height = fig.get_size_inches()
    grown = Bbox.from_extents(-MARGIN_INCHES, -MARGIN_INCHES, width + MARGIN_INCHES, height + MARGIN_INCHES)
    # savefig is the public way to draw with an explicit bbox_inches; its "rgba" format writes the Agg
    # renderer's own buffer, which the sink keeps instead of a copy (the renderer's own size:
    # computing the canvas's width from the figure's inches disagreed with it by a pixel for some sizes)
    sink = _RendererPixels()
    fig.savefig(sink, format="rgba", dpi=DPI, bbox_inches=grown)
    return sink.pixels


class _RendererPixels(io.RawIOBase):
    """A file for savefig(format="rgba"): matplotlib's Agg canvas writes its renderer's buffer_rgba()
    (a height x width x 4 memoryview) to it once (`FigureCanvasAgg.print_raw`); kept as an array on
    that memory, not copied."""

    def __init__(self) -> None:
        super().__init__()
        self.pixels: np.ndarray | None = None

    def writable(self) -> bool:
        return True

    def write(self, data) -> int:
        pixels = np.asarray(data)
        if self.pixels is not None or pixels.ndim != 3 or pixels.shape[2] != 4:
            raise RuntimeError("savefig(format='rgba') did not write the renderer's RGBA buffer in one piece")
        self.pixels = pixels
        return pixels.nbytes


def _fix_title_positions(fig) -> list:
    """The axes with a title, their titles fixed at the axes' top (matplotlib's title position for
    axes without ticks above them, found without measuring every axis of the figure again)."""
    titled = [ax for ax in fig.axes if ax.get_title()]
    for ax in titled:
        ax.title.set_y(1.0)
        ax._autotitlepos = False
    return titled


def _fix_empty_label_positions(fig) -> list:
    """The axes' x and y axes without a label, matplotlib's placement of their (empty, undrawn)
    label turned off for one render; `_save` turns it on again (a reused figure may label them,
    and savefig's bbox_inches="tight" counts an empty label's position in the figure's extent).

    Placing an axis's label measures its tick labels and works out their ticks' positions a
    second and third time (`Axis._update_label_position`, the spine's extent): about a fifth of
    drawing the 3 x 5 link-versus-input figure (profiled), where 22 of its 30 axes have no label."""
    unlabelled = [
        axis for ax in fig.axes for axis in (ax.xaxis, ax.yaxis) if axis._autolabelpos and not axis.label.get_text()
    ]
    for axis in unlabelled:
        axis._autolabelpos = False  # matplotlib's own flag, False where a label's position was set
    return unlabelled


def _titles_clear(titled: list) -> bool:
    """No titled axes shows a y-axis offset text (e.g. "1e-3", "+5.002e1"), which matplotlib's
    title placement would have moved the title above."""
    return not any(ax.yaxis.offsetText.get_visible() and ax.yaxis.offsetText.get_text() for ax in titled)


def opaque(pixels: np.ndarray) -> np.ndarray:
    """RGBA pixels as RGB (a view) where every pixel is opaque (a quarter less to encode), else as
    they are."""
    if np.all(pixels[..., 3] == 255):
        return pixels[..., :3]
    return pixels


def cropped_to_ink(pixels: np.ndarray, background: np.ndarray, pad: int) -> np.ndarray | None:
    """The (rows, columns, 4) image cropped (a view) to its pixels that differ from `background`,
    plus `pad` pixels around them; None where the ink reaches the image's edge (or there is none)."""
    # one 32-bit comparison per RGBA pixel rather than four byte comparisons and a reduction
    ink = np.ascontiguousarray(pixels).view(np.uint32)[..., 0] != np.ascontiguousarray(background).view(np.uint32)[0]
    rows, columns = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    if rows.size == 0:
        return None
    top, bottom, left, right = rows[0], rows[-1], columns[0], columns[-1]
    if top == 0 or left == 0 or bottom == ink.shape[0] - 1 or right == ink.shape[1] - 1:
        return None
    return pixels[max(top - pad, 0) : bottom + pad + 1, max(left - pad, 0) : right + pad + 1]


def plot_three_links(histories: list[CamHistory], links: list[int], path: Path) -> Path:
    """Displacement, velocity and acceleration of several links (1-based), every cam law."""
    fig, axes = _subplots(3, len(links), (4.2 * len(links), 8), sharex=True)
    for col, link in enumerate(links):
        axes[0, col].set_title(f"link {link}")
        for row, (label, link_value, _) in enumerate(QUANTITIES):
            ax = axes[row, col]
            for h in histories:
                ax.plot(h.t_s, link_value(h)[:, h.column(link)], color=_colour(h.cam), lw=0.9, label=h.cam)
            ax.set_ylabel(label)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    axes[0, -1].legend(fontsize=8)
    fig.suptitle(f"{histories[0].material}: links {', '.join(map(str, links))}, all cam laws")
    return _save(fig, path)


def plot_link_vs_input(histories: list[CamHistory], link: int, path: Path) -> Path:
    """One column per cam law: the link's motion over the cam input it follows, each row's quantity on
    one scale for every cam law (the laws compared at a glance; the inner columns' tick labels, which
    overlapped the next axes, are not drawn: about 6 % of the CPU of the default run's 15
    figures, benchmarks/bench_figures.py)."""
    fig, axes = _subplots(3, len(histories), (3.6 * len(histories), 8), sharex=True, sharey="row")
    for col, h in enumerate(histories):
        axes[0, col].set_title(h.cam)
        for row, (label, link_value, input_value) in enumerate(QUANTITIES):
            ax = axes[row, col]
            ax.plot(h.t_s, input_value(h), color="0.4", lw=1.4, label="cam input")
            ax.plot(h.t_s, link_value(h)[:, h.column(link)], color=_colour(h.cam), lw=0.9, label=f"link {link}")
            if col == 0:
                ax.set_ylabel(label)
        axes[-1, col].set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(f"{histories[0].material}: link {link} against the cam input")
    return _save(fig, path)


def plot_differences(histories: list[CamHistory], link: int, path: Path) -> Path:
    """Link motion minus cam input (x - z, v - z', a - z'') for every cam law at one link."""
    fig, axes = _subplots(3, 1, (9, 8), sharex=True)
    axes = axes[:, 0]
    for row, (label, link_value, input_value) in enumerate(QUANTITIES):
        for h in histories:
            axes[row].plot(
                h.t_s, link_value(h)[:, h.column(link)] - input_value(h), color=_colour(h.cam), lw=0.9, label=h.cam
            )
        axes[row].set_ylabel(f"link − input\n{label}")
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(f"{histories[0].material}: link {link} minus cam input")
    return _save(fig, path)


def plot_residual_vibration(residual_m: dict[str, dict[str, float]], station: str, path: Path) -> Path:
    """Grouped bars: residual vibration in the dwell (max |x - z| inside dwells) per material and cam."""
    materials = list(residual_m)
    cams = list(next(iter(residual_m.values())))
    width = 0.8 / len(materials)
    fig, ax = plt.subplots(figsize=(max(6, 1.5 * len(cams)), 4.5))
    x = np.arange(len(cams))
    for i, material in enumerate(materials):
        values = [residual_m[material][c] * 1e3 for c in cams]
        ax.bar(x + (i - (len(materials) - 1) / 2) * width, values, width, label=material)
    ax.set_xticks(x, cams, rotation=20)
    ax.set_ylabel("residual vibration in dwell (mm)")
    ax.set_title(f"Residual vibration at the {station} station (max |x − z| inside dwells)")
    ax.grid(axis="y", alpha=GRID_ALPHA)
    ax.legend()
    return _save(fig, path)


def plot_dwell_vibration(histories: list[CamHistory], link: int, path: Path) -> Path:
    """x - z during the dwells only, so the residual vibration is visible at its own scale."""
    fig, axes = _subplots(1, 1, (9, 4.5))
    ax = axes[0, 0]
    for h in histories:
        dev_mm = (h.x_m[:, h.column(link)] - h.z_m) * 1e3
        ax.plot(h.t_s, np.where(h.dwell_mask, dev_mm, np.nan), color=_colour(h.cam), lw=0.9, label=h.cam)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("x − z in dwell (mm)")
    ax.set_title(f"{histories[0].material}: link {link} vibration during the dwells")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_tension(histories: list[CamHistory], path: Path) -> Path:
    """Peak and minimum tension of every link over the window, per cam law; below zero a span pushes."""
    fig, axes = _subplots(1, 1, (9, 4.5))
    ax = axes[0, 0]
    for h in histories:
        links = np.arange(1, h.tension_N.shape[1] + 1)
        ax.plot(links, h.tension_N.max(axis=0) / 1e3, color=_colour(h.cam), lw=1.0, label=f"{h.cam} max")
        ax.plot(links, h.tension_N.min(axis=0) / 1e3, color=_colour(h.cam), lw=1.0, ls="--")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("link")
    ax.set_ylabel("link tension (kN); dashed = minimum")
    ax.set_title(
        f"{histories[0].material}: link tension extremes (below zero: a span pushing through its closed free play)"
    )
    ax.legend(fontsize=8, ncol=2)
    return _save(fig, path)


def plot_tension_map(history: CamHistory, free_play: np.ndarray, path: Path, note: str = "") -> Path:
    """Span x time map of the span force (kN; red tension, blue compression through pushing contact),
    with the spans in free play (no force, pin joint open) in grey."""
    from matplotlib.colors import ListedColormap, TwoSlopeNorm

    tension_kN = history.tension_N / 1e3
    t_ms = history.t_s * 1e3
    n_spans = tension_kN.shape[1]
    extent = (t_ms[0], t_ms[-1], 0.5, n_spans + 0.5)
    low, high = min(float(tension_kN.min()), -1e-3), max(float(tension_kN.max()), 1e-3)
    fig, ax = plt.subplots(figsize=(10, 5))
    image = ax.imshow(
        tension_kN.T,
        aspect="auto",
        origin="lower",
        extent=extent,
        cmap="RdBu_r",
        norm=TwoSlopeNorm(0.0, low, high),
        interpolation="nearest",
    )
    if np.any(free_play):
        ax.imshow(
            np.where(free_play, 1.0, np.nan).T,
            aspect="auto",
            origin="lower",
            extent=extent,
            cmap=ListedColormap(["0.55"]),
            interpolation="nearest",
        )
    dwell = history.dwell_mask
    edges = np.flatnonzero(np.diff(dwell.astype(int)))
    for i in edges:
        ax.axvline(t_ms[i], color="k", lw=0.6, ls=":")
    fig.colorbar(image, ax=ax, label="span force (kN), tension positive")
    ax.set_xlabel("time (ms); dotted: start and end of dwells")
    ax.set_ylabel("span (link j to j + 1)")
    share = 100.0 * float(np.mean(free_play))
    ax.set_title(
        f"{history.material} / {history.cam}: span force; grey = free play ({share:.1f} % of span-time)"
        + (f"\n{note}" if note else "")
    )
    return _save(fig, path)


def plot_rpm_sweep(result: SweepResult, path: Path) -> Path:
    """Residual vibration (mm) and peak acceleration (m/s^2) versus cam speed, one line per cam,
    critical speeds as vertical lines (labelled mode/harmonic); written to `path` (PNG)."""
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7.5), sharex=True, dpi=100)
    for i, cam in enumerate(result.cam_ids):
        ax1.semilogy(result.rpm, result.residual_vibration_m[i] * 1e3, label=cam, lw=1.2)
        ax2.semilogy(result.rpm, result.peak_acceleration_m_s2[i], label=cam, lw=1.2)
    for c in result.critical_speeds:
        for ax in (ax1, ax2):
            ax.axvline(c.rpm, color="0.5", lw=0.8, ls="--", alpha=max(0.25, 1.0 / c.harmonic))
        ax1.annotate(
            f"m{c.mode}/h{c.harmonic}",
            (c.rpm, 1.0),
            xycoords=("data", "axes fraction"),
            fontsize=7,
            rotation=90,
            va="top",
            ha="right",
            color="0.35",
        )
    ax1.set_ylabel("residual vibration in dwell, max |x - z| (mm)")
    ax2.set_ylabel("peak |acceleration| (m/s²)")
    ax2.set_xlabel("cam speed (rev/min)")
    ax1.set_title(
        f"Speed sweep at {result.station} (link {result.station_link}): {result.model}, friction 0\n"
        "periodic steady state; dashed: critical speeds, harmonic h of the index frequency = natural frequency "
        "of mode m",
        fontsize=9,
    )
    ax1.legend(fontsize=8, ncol=3)
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=GRID_ALPHA)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
