"""Off-screen rendering of a solved link (no display needed)."""

import matplotlib.image
import numpy as np
import pytest
from fem_plate import plate_link

from fem import FemError, analyse_link, get_material, render_deformed
from fem.render import nice_factor


@pytest.fixture(scope="module", params=[1, 2], ids=["P1", "P2-curved"])
def solution(request):
    order = request.param
    return analyse_link(plate_link(0.01, order=order), get_material("ti-grade2"), order=order)


@pytest.mark.parametrize("scalar", ["von_mises", "displacement"])
def test_png_is_written_with_a_coloured_link(tmp_path, solution, scalar):
    path = tmp_path / "link.png"
    factor = render_deformed(solution, path, scalar=scalar)
    image = matplotlib.image.imread(path)[..., :3]
    not_background = np.any(image < 0.98, axis=-1).mean()
    saturated = (image.max(axis=-1) - image.min(axis=-1) > 0.3).mean()  # colour-mapped pixels
    assert not_background > 0.05 and saturated > 0.02
    assert factor >= 1 and factor == nice_factor(factor)
    assert not list(tmp_path.glob(".*tmp*"))  # written atomically, no leftovers


def test_image_is_rendered_with_one_sample_per_pixel_as_rgb(tmp_path, solution, monkeypatch):
    # Mesa's software rasteriser pays for every sample (fem.render.MULTI_SAMPLES)
    import pyvista

    from fem import render

    samples = []

    class Recording(pyvista.Plotter):
        def screenshot(self, *args, **kwargs):
            samples.append(self.render_window.GetMultiSamples())
            return super().screenshot(*args, **kwargs)

    monkeypatch.setattr(pyvista, "Plotter", Recording)
    render_deformed(solution, tmp_path / "link.png", window_size=(320, 200))
    assert render.MULTI_SAMPLES == 1 and samples in ([0], [1])  # pyvista asks VTK for 0 (off) for one sample
    from PIL import Image

    with Image.open(tmp_path / "link.png") as image:
        assert (image.mode, image.size) == ("RGB", (320, 200))


def test_frame_has_no_translucent_geometry(tmp_path, solution, monkeypatch):
    # a translucent actor makes VTK run its translucency pass every frame (fem.render.EDGE_COLOR)
    import pyvista

    translucent = []

    class Recording(pyvista.Plotter):
        def screenshot(self, *args, **kwargs):
            props = self.renderer.GetViewProps()
            translucent.append(
                [props.GetItemAsObject(i).HasTranslucentPolygonalGeometry() for i in range(props.GetNumberOfItems())]
            )
            return super().screenshot(*args, **kwargs)

    monkeypatch.setattr(pyvista, "Plotter", Recording)
    render_deformed(solution, tmp_path / "link.png", window_size=(320, 200))
    assert len(translucent) == 1 and len(translucent[0]) >= 3 and not any(translucent[0])


def test_bad_scalar_and_suffix_are_fem_errors(tmp_path, solution):
    with pytest.raises(FemError, match="scalar"):
        render_deformed(solution, tmp_path / "a.png", scalar="strain")
    with pytest.raises(FemError, match=".png"):
        render_deformed(solution, tmp_path / "a.jpg")


@pytest.mark.parametrize("raw, nice", [(1234.0, 1000.0), (0.37, 0.2), (5.0, 5.0), (99.0, 50.0), (1.0, 1.0)])
def test_nice_factor(raw, nice):
    assert nice_factor(raw) == pytest.approx(nice)


def test_solution_vtu_round_trips_through_meshio(tmp_path, solution):
    import meshio

    from fem.export import write_solution_vtu

    path = write_solution_vtu(solution, tmp_path / "link.vtu")
    back = meshio.read(path)
    assert np.allclose(back.point_data["displacement_m"], solution.displacement_m.T, rtol=0, atol=1e-15)
    assert np.allclose(back.points, solution.basis.doflocs.T)
    assert back.cells[0].type == ("tetra10" if solution.order == 2 else "tetra")
    with pytest.raises(FemError, match=".vtu"):
        write_solution_vtu(solution, tmp_path / "link.vtk")


def test_pyvista_does_not_probe_the_display_before_rendering(tmp_path, solution, monkeypatch):
    """fem.render renders off screen through EGL: pyvista's check for a display (`xset -q`, then a
    render window of its own to learn whether VTK uses EGL) is skipped by its ALLOW_PLOTTING switch."""
    import subprocess

    import pyvista.plotting.plotter
    import pyvista.plotting.tools

    probes = []
    monkeypatch.setattr(pyvista.plotting.tools, "SUPPORTS_PLOTTING", None)  # not yet asked in this process
    monkeypatch.delattr(pyvista.plotting.plotter._warn_xserver, "has_support", raising=False)
    monkeypatch.setattr(pyvista.plotting.plotter, "uses_egl", lambda: probes.append("egl window") or True)
    real_popen = subprocess.Popen
    monkeypatch.setattr(subprocess, "Popen", lambda args, *a, **k: probes.append(args) or real_popen(args, *a, **k))
    render_deformed(solution, tmp_path / "link.png", window_size=(320, 200))
    assert probes == []


def test_warping_the_surface_gives_the_warped_volume_mesh_surface(solution):
    """fem.render warps the extracted (subdivided) surface instead of the volume mesh: the points
    are the same, to float32 rounding, since the subdivision interpolates linearly in nodal values."""
    from fem.link import whole_link_fields
    from fem.render import _grid, _surface

    fields = whole_link_fields(solution)
    undeformed, _ = _surface([fields])
    factor = 1000.0
    grid = _grid(fields)
    grid.point_data["u"] = np.ascontiguousarray(fields.displacement_m.T)
    subdivision = 2 if solution.order == 2 else 0
    expected = grid.warp_by_vector("u", factor=factor).extract_surface(
        algorithm="dataset_surface", nonlinear_subdivision=subdivision
    )
    warped = undeformed.warp_by_vector("u0", factor=factor)
    size = np.ptp(np.asarray(expected.points), axis=0).max()
    assert warped.n_points == expected.n_points
    assert np.abs(np.asarray(warped.points) - np.asarray(expected.points)).max() < 1e-6 * size


def test_materials_on_one_mesh_share_its_surface_and_render_as_alone(tmp_path, monkeypatch):
    from fem import render
    from fem.link import analyse_link_materials, whole_link_fields

    order = 2
    solutions = analyse_link_materials(
        plate_link(0.01, order=order), [get_material("ti-grade2"), get_material("al6061-t6")], order=order
    )
    alone = {name: tmp_path / f"alone-{name}.png" for name in solutions}
    for name, solution in solutions.items():
        render_deformed(solution, alone[name], window_size=(320, 200))
    surfaces = []
    real_surface = render._surface
    monkeypatch.setattr(
        render, "_surface", lambda fields, scalar: surfaces.append(len(fields)) or real_surface(fields, scalar)
    )
    pictures = [render.Picture(s, tmp_path / f"together-{name}.png") for name, s in solutions.items()]
    factors = render.render_pictures(pictures, window_size=(320, 200))
    assert surfaces == [2]  # one surface for both materials
    assert factors == [render.exaggeration_factor(whole_link_fields(s)) for s in solutions.values()]
    for name, picture in zip(solutions, pictures):
        assert np.array_equal(matplotlib.image.imread(picture.path), matplotlib.image.imread(alone[name]))


def test_pictures_share_one_render_window_and_each_is_rendered_once(tmp_path, monkeypatch):
    """fem.render draws a call's pictures one after the other in one plotter (Mesa's renderer set up
    once); pyvista would render the window again on every actor added or removed after the first
    picture. Pictures on two meshes, drawn together, are the same as drawn alone."""
    import pyvista

    from fem import render

    solutions = [
        analyse_link(plate_link(0.01, order=2), get_material("ti-grade2"), order=2),
        analyse_link(plate_link(0.012, order=1), get_material("al6061-t6"), order=1),
    ]
    alone = [tmp_path / f"alone-{i}.png" for i in range(2)]
    for solution, path in zip(solutions, alone):
        render_deformed(solution, path, window_size=(320, 200))
    windows, renders = [], []

    class Counting(pyvista.Plotter):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            windows.append(self.render_window)
            self.render_window.AddObserver("StartEvent", lambda *_: renders.append(len(windows)))

    monkeypatch.setattr(pyvista, "Plotter", Counting)
    pictures = [render.Picture(s, tmp_path / f"together-{i}.png") for i, s in enumerate(solutions)]
    render.render_pictures(pictures, window_size=(320, 200))
    assert len(windows) == 1 and renders == [1, 1]
    for picture, path in zip(pictures, alone):
        assert np.array_equal(matplotlib.image.imread(picture.path), matplotlib.image.imread(path))


def test_no_pictures_open_no_plotter(monkeypatch):
    """The FEA's process beside the run, its images drawn by another process, asks for none."""
    import pyvista

    from fem import render

    monkeypatch.setattr(pyvista, "Plotter", lambda *args, **kwargs: pytest.fail("a plotter was opened"))
    assert render.render_pictures([]) == [] and render.draw_pictures([]) == []


@pytest.mark.parametrize("window_size, annotation", [((320, 200), False), ((1400, 900), False), ((320, 100), True)])
def test_title_is_drawn_as_pyvistas_upper_edge_annotation(tmp_path, solution, monkeypatch, window_size, annotation):
    """fem.render._add_title draws the title without vtkCornerAnnotation's font-size search where
    the search's end is known (size 100), the same pixels as pyvista's add_text; in a window too low
    for that the annotation draws it."""
    import pyvista

    from fem import render

    titles = []
    real_add_title = render._add_title
    monkeypatch.setattr(render, "_add_title", lambda p, t: _recorded(titles, real_add_title(p, t)))
    ours = render_deformed(solution, tmp_path / "ours.png", window_size=window_size)
    assert [isinstance(t, pyvista.CornerAnnotation) for t in titles] == [annotation]

    def pyvistas_title(plotter, title):
        return plotter.add_text(
            title, position="upper_edge", font_size=render.TITLE_FONT_SIZE, color="black", render=False
        )

    monkeypatch.setattr(render, "_add_title", pyvistas_title)
    theirs = render_deformed(solution, tmp_path / "theirs.png", window_size=window_size)
    assert ours == theirs
    assert np.array_equal(
        matplotlib.image.imread(tmp_path / "ours.png"), matplotlib.image.imread(tmp_path / "theirs.png")
    )


def _recorded(found: list, actor):
    found.append(actor)
    return actor
