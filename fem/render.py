"""Off-screen pictures of a solved link: the deformed shape, coloured by stress or displacement."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geometry.atomic import atomic_target

from .errors import FemError
from .fields import NodalFields

if TYPE_CHECKING:  # fem.link imports scikit-fem, which a process drawing `Drawing`s does not need
    from .link import LinkSolution

# Without a display VTK first tries X, warns, then falls back to EGL; asking for EGL directly
# skips that attempt. Must be set before VTK creates its first render window.
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
# Before its first Plotter pyvista checks whether the machine can plot: it runs `xset -q` and, with
# no display, makes a render window of its own to learn whether VTK draws through EGL (0.13-0.32 s
# of wall, 0.04 CPU s, measured under load); this module renders off screen through EGL regardless.
# pyvista's own switch skips the check (the first Plotter 0.54 instead of 0.94 s of wall, medians
# of 4 alternating, load average 11).
os.environ.setdefault("ALLOW_PLOTTING", "true")

SCALARS = ("von_mises", "displacement")
DEFORMATION_FRACTION = 0.06  # exaggerated peak displacement as a fraction of the part's size
# One sample per pixel instead of pyvista's default 8 (multisample anti-aliasing): without a GPU,
# Mesa's software rasteriser pays for every sample; the default run's two images took 1.40 CPU s
# with 8 samples and 0.80 s with one (medians of 3, benchmark's shared machine), the surfaces
# look the same and only the thin feature edges show steps.
MULTI_SAMPLES = 1
# zlib's fastest level, as the report's figures (reporting.plots): Pillow's default level 6 took
# about 0.2 CPU s per 1400 x 900 image for files a few percent smaller. (reporting/png.py's writer
# would save 0.03 CPU s more per image, but fem does not import reporting: the data flows one way.)
PNG_COMPRESS_LEVEL = 1
# The undeformed link's feature edges, drawn opaque in a dark grey: black at half opacity (as
# before) made VTK run its translucency pass (order-independent translucency) in every frame, its
# window-sized textures first touched in the first. Opaque, the default run's two frames took 0.65
# instead of 0.79 CPU s (medians of 5 alternating, load 6-8, 2026-11-27) and 4,700 fewer page
# faults. The grey reads as the blend did on the surface (half its colour), darker on the white
# background (where the blend was mid-grey); about 4,800 of the 1.26 million pixels differ, the
# edges' and the scalar bar's "above" label's, which without a translucency pass sits centred under
# its box.
EDGE_COLOR = (0.15, 0.15, 0.15)
TITLE_FONT_SIZE = 11  # pyvista's add_text font size of a picture's title (`_add_title`)
# vtkCornerAnnotation's largest font size in its search for the size that fills the window (`_add_title`)
_SEARCH_LIMIT_FONT_SIZE = 100


def nice_factor(raw: float) -> float:
    """The largest of 1, 2, 5 x 10^n not above `raw` (so the factor reads cleanly)."""
    exponent = math.floor(math.log10(raw))
    for mantissa in (5, 2, 1):
        if mantissa * 10.0**exponent <= raw:
            return mantissa * 10.0**exponent
    return 10.0**exponent


def exaggeration_factor(fields: NodalFields) -> float:
    points = fields.points_m
    size = float(np.linalg.norm(points.max(axis=1) - points.min(axis=1)))
    peak = float(np.max(np.linalg.norm(fields.displacement_m, axis=0)))
    return nice_factor(DEFORMATION_FRACTION * size / peak) if peak > 0 else 1.0


def _grid(fields: NodalFields):
    import pyvista as pv

    cell_type = pv.CellType.QUADRATIC_TETRA if fields.cells.shape[1] == 10 else pv.CellType.TETRA
    return pv.UnstructuredGrid({cell_type: fields.cells}, np.ascontiguousarray(fields.points_m.T))


@dataclass(frozen=True)
class Picture:
    """One PNG to render: a solved link, the path and its title (None: material, k and factor)."""

    solution: LinkSolution
    path: Path
    title: str | None = None

    def drawing(self) -> Drawing:
        from .link import whole_link_fields

        s = self.solution
        title = self.title if self.title is not None else f"{s.material.name}: k = {s.stiffness_N_per_m:.4g} N/m"
        return Drawing(
            whole_link_fields(s),  # a mirrored half pictured whole
            self.path,
            title,
            self.title is None,
            s.load_N,
            s.peak_von_mises_away_from_clamp_Pa_per_N,
        )


@dataclass(frozen=True)
class Drawing:
    """What a picture takes of its solved link: the whole link's fields and the numbers its title
    and colour scale show. Plain arrays and numbers, so a picture can be drawn in another process
    (stages.fea hands the deformed images to a process of the run's own, forked from it) without
    the solution, its basis or scikit-fem."""

    fields: NodalFields
    path: Path
    title: str  # the factor is appended: ", deformation xF" if `title_is_default`, else " (deformation xF)"
    title_is_default: bool
    load_N: float
    peak_away_from_clamp_Pa_per_N: float


def render_deformed(
    solution: LinkSolution,
    path: str | Path,
    *,
    scalar: str = "von_mises",
    title: str | None = None,
    window_size: tuple[int, int] = (1400, 900),
) -> float:
    """Write a PNG of the exaggerated deformed link; returns the exaggeration factor used."""
    return render_pictures([Picture(solution, Path(path), title)], scalar=scalar, window_size=window_size)[0]


def render_pictures(
    pictures: list[Picture], *, scalar: str = "von_mises", window_size: tuple[int, int] = (1400, 900)
) -> list[float]:
    """Write each picture's PNG of its exaggerated deformed link; returns their exaggeration factors.

    Solutions on one mesh (the materials of a level) share its surface: the curved elements' surface
    is extracted once with every solution's fields on it, and each picture warps that surface,
    instead of warping the volume mesh and extracting its surface again. The subdivided surface's
    points are the elements' quadratic interpolation of the nodes, linear in the nodal values, so
    warping before or after the extraction gives the same points (to float32 rounding: 1.5e-8 m on
    the default link; about 800 of the 1.26 million pixels differ, one of them by more than 16/255). The
    default run's two images: 1.63 instead of 2.12 CPU s, pyvista's import and first window
    included (medians of 3 alternating with e143626, the same solutions, loaded machine)."""
    _check(scalar, [picture.path for picture in pictures])
    return draw_pictures([picture.drawing() for picture in pictures], scalar=scalar, window_size=window_size)


def draw_pictures(
    drawings: list[Drawing], *, scalar: str = "von_mises", window_size: tuple[int, int] = (1400, 900)
) -> list[float]:
    """`render_pictures` of the pictures' drawings (`Picture.drawing`)."""
    _check(scalar, [drawing.path for drawing in drawings])
    if not drawings:  # no plotter: the FEA's process, its pictures drawn elsewhere, asks for none
        return []
    fields = [drawing.fields for drawing in drawings]
    factors: dict[int, float] = {}
    plotter = _plotter(window_size)  # one render window (one GL context) for every picture
    try:
        for group in _same_mesh(fields):
            undeformed, edges = _surface([fields[i] for i in group], scalar)
            for j, i in enumerate(group):
                factors[i] = _render_one(plotter, drawings[i], undeformed, edges, j, scalar)
    finally:
        plotter.close()
    return [factors[i] for i in range(len(drawings))]


def _check(scalar: str, paths: list[Path]) -> None:
    if scalar not in SCALARS:
        raise FemError(f"scalar must be one of {', '.join(SCALARS)}, got {scalar!r}")
    for path in paths:
        if path.suffix.lower() != ".png":
            raise FemError(f"image path {str(path)!r}: expected a .png file")


def _same_mesh(fields: list[NodalFields]) -> list[list[int]]:
    """The indices of the fields grouped by the mesh they are on (the same points and cells)."""
    groups: list[list[int]] = []
    for i, f in enumerate(fields):
        for group in groups:
            first = fields[group[0]]
            if _arrays_equal(first.points_m, f.points_m) and _arrays_equal(first.cells, f.cells):
                group.append(i)
                break
        else:
            groups.append([i])
    return groups


def _arrays_equal(a: np.ndarray, b: np.ndarray) -> bool:
    return a is b or (a.shape == b.shape and bool(np.array_equal(a, b)))


def _surface(fields: list[NodalFields], scalar: str = "von_mises"):
    """The undeformed outer surface (curved elements subdivided) carrying each solution's
    displacement `u{i}` and pictured scalar `{scalar}{i}` (`_scalar_values`), and its feature edges.
    Only the arrays drawn: the subdivision interpolates every array onto its new points (the default
    run's surface and edges took 0.02-0.03 CPU s more with the other scalar on them too)."""
    import pyvista as pv

    grid = _grid(fields[0])
    for i, f in enumerate(fields):
        grid.point_data[f"u{i}"] = np.ascontiguousarray(f.displacement_m.T)
        grid.point_data[f"{scalar}{i}"] = _scalar_values(f, scalar)
    subdivision = 2 if grid.celltypes[0] == pv.CellType.QUADRATIC_TETRA else 0
    undeformed = grid.extract_surface(algorithm="dataset_surface", nonlinear_subdivision=subdivision)
    return undeformed, undeformed.extract_feature_edges(30.0)


def _scalar_values(fields: NodalFields, scalar: str) -> np.ndarray:
    """The nodal values a picture is coloured by: von Mises stress in MPa or displacement magnitude in um."""
    if scalar == "von_mises":
        return fields.von_mises_Pa / 1e6
    return np.linalg.norm(fields.displacement_m, axis=0) * 1e6


def _plotter(window_size):
    """The off-screen plotter every picture of a call is drawn in, one after the other: Mesa's
    renderer is set up once (its context, shaders and the window's buffers), not once per picture;
    the default run's two images cost 1.77 instead of 2.07 CPU s in the run's fork (medians of 5
    alternating, load 3.4-5.8, 2026-11-27), the PNGs the same byte for byte."""
    import pyvista as pv

    theme = pv.themes.Theme()
    theme.multi_samples = MULTI_SAMPLES
    plotter = pv.Plotter(off_screen=True, window_size=list(window_size), theme=theme)
    plotter.set_background("white")
    return plotter


def _add_title(plotter, title: str):
    """The picture's title at the window's upper edge, as pyvista's `add_text(title,
    position="upper_edge", font_size=TITLE_FONT_SIZE, color="black")` draws it, without VTK's search
    for its font size in every picture: the title actor.

    That call makes a vtkCornerAnnotation. On the first frame it is in, the annotation renders its
    text at every font size from 12 upwards until the text is too high for the window or the size
    is 100 (the width of a text at an edge's centre is not checked), then draws it from a
    vtkTextMapper in a vtkActor2D at int(size ** 0.35 * font_size // 2) (its scale factors, capped by
    its maximum font size), centred, its top 5 pixels below the window's. That search rendered the
    title about 90 times per picture, a new font size each: a 1400 x 900 frame with it took 0.17-0.18
    CPU s, with the title drawn as here 0.10-0.11, without a title 0.095-0.10 (medians of 6, two
    runs, load 5). Here, where the title at size 100 is lower than the annotation's height limit
    (one line in the default 1400 x 900 window: 96 of 810 pixels), the search ends at 100 by the
    annotation's own rule, and the same mapper and actor are made at the size it ends with (the
    same pixels, tests/test_fem_render.py); otherwise the annotation itself draws the title."""
    import pyvista as pv
    from vtkmodules.vtkRenderingCore import vtkActor2D, vtkTextMapper

    annotation = pv.CornerAnnotation("upper_edge", title, linear_font_scale_factor=TITLE_FONT_SIZE // 2)
    annotation.prop = pv.TextProperty(color="black", font_family=None, orientation=0.0, font_file=None, shadow=False)
    mapper = vtkTextMapper()
    mapper.SetInput(title)
    style = mapper.GetTextProperty()
    style.ShallowCopy(annotation.GetTextProperty())
    style.SetJustificationToCentered()
    style.SetVerticalJustificationToTop()
    style.SetFontSize(_SEARCH_LIMIT_FONT_SIZE)
    width, height = plotter.window_size
    lines = title.count("\n") + 1
    # the annotation's limits on its texts' height at an edge's centre (vtkCornerAnnotation.cxx)
    height_limit = min(int(0.9 * height), int(height * annotation.GetMaximumLineHeight()) * lines)
    extent = [0, 0]
    mapper.GetSize(plotter.renderer, extent)
    if extent[1] >= height_limit:
        return plotter.add_text(title, position="upper_edge", font_size=TITLE_FONT_SIZE, color="black", render=False)
    size = int(
        _SEARCH_LIMIT_FONT_SIZE ** annotation.GetNonlinearFontScaleFactor() * annotation.GetLinearFontScaleFactor()
    )
    style.SetFontSize(min(size, annotation.GetMaximumFontSize()))
    actor = vtkActor2D()
    actor.SetMapper(mapper)
    actor.SetPosition(width // 2, height - 5)
    plotter.add_actor(actor, reset_camera=False, pickable=False, render=False)
    return actor


def _render_one(plotter, drawing: Drawing, undeformed, edges, i: int, scalar) -> float:
    from PIL import Image

    fields, path = drawing.fields, drawing.path
    factor = exaggeration_factor(fields)
    load = drawing.load_N
    deformed = undeformed.warp_by_vector(f"u{i}", factor=factor)
    if scalar == "von_mises":
        bar = f"von Mises stress [MPa] at {load:g} N"
        # The clamp rim is singular; scale the colours to the converged peak away from it.
        upper = drawing.peak_away_from_clamp_Pa_per_N * load / 1e6
        clim = (0.0, upper if np.isfinite(upper) and upper > 0 else float(np.max(fields.von_mises_Pa) / 1e6))
    else:
        bar = f"displacement [um] at {load:g} N"
        clim = (0.0, float(np.max(np.linalg.norm(fields.displacement_m, axis=0)) * 1e6))
    if drawing.title_is_default:
        title = f"{drawing.title}, deformation x{factor:g}"
    else:
        title = f"{drawing.title} (deformation x{factor:g})"

    # render=False throughout: once the first picture is drawn, pyvista renders the window again
    # on every actor added or removed (a whole frame each, in Mesa's software rasteriser)
    actors = [
        plotter.add_mesh(
            deformed,
            scalars=f"{scalar}{i}",
            cmap="turbo",
            clim=clim,
            above_color="magenta" if scalar == "von_mises" else None,
            scalar_bar_args={
                "title": bar,
                "color": "black",
                "fmt": "%.3g",
                "vertical": False,
                "position_x": 0.2,
                "position_y": 0.04,
                "width": 0.6,
                "title_font_size": 16,
                "label_font_size": 14,
                "render": False,
            },
            render=False,
        ),
        plotter.add_mesh(edges, color=EDGE_COLOR, line_width=1, render=False),
        _add_title(plotter, title),
    ]
    plotter.view_isometric(render=False)
    plotter.render()  # a later picture's frame; before the first, the screenshot renders it
    path.parent.mkdir(parents=True, exist_ok=True)
    pixels = plotter.screenshot(None, return_img=True)
    with atomic_target(path) as tmp:
        Image.fromarray(pixels).save(tmp, format="png", compress_level=PNG_COMPRESS_LEVEL)
    plotter.remove_scalar_bar(bar, render=False)
    plotter.remove_actor(actors, render=False)
    return factor
