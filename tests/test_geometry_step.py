"""STEP import: units, healing of face-only files, and every kind of bad input."""

import gmsh
import pytest

from geometry import DEFAULT_LINK, GeometryError, load_link, nominal_volume_m3, write_step
from geometry.parametric import add_link
from geometry.session import gmsh_model
from geometry.step_io import write_model_step

COARSE = 0.01  # m: these tests look at the geometry, not at the mesh


def _write(path, build, unit="mm"):
    """Write a STEP file of the part that `build()` adds to a fresh gmsh model (model in metres)."""
    with gmsh_model("test-part"):
        build()
        gmsh.model.occ.synchronize()
        write_model_step(path, unit=unit)
    return path


def _box_with_holes(n_holes, radius=0.006):
    occ = gmsh.model.occ
    box = occ.addBox(0, 0, 0, 0.05 * (n_holes + 1), 0.04, 0.02)
    holes = [(3, occ.addCylinder(0.05 * (i + 1), 0.02, -0.01, 0, 0, 0.04, radius)) for i in range(n_holes)]
    if holes:
        occ.cut([(3, box)], holes)


def test_metre_file_declares_metres(tmp_path):
    text = write_step(DEFAULT_LINK, tmp_path / "m.step", unit="m").read_text()
    assert "SI_UNIT($,.METRE.)" in text and ".MILLI." not in text
    assert ".MILLI.,.METRE." in write_step(DEFAULT_LINK, tmp_path / "mm.step", unit="mm").read_text()


@pytest.mark.parametrize("order", [("mm", "m", "mm"), ("m", "mm", "m")])
def test_mm_and_metre_files_of_one_part_agree_in_either_order(tmp_path, order):
    # OCCTargetUnit sticks for the process: each import must still see its own file's unit.
    results = []
    for unit in order:
        path = write_step(DEFAULT_LINK, tmp_path / f"link_{unit}.step", unit=unit)
        link = load_link(path, mesh_size_m=COARSE)
        results.append((link.pitch_m, link.loaded_bore.radius_m, link.cad_volume_m3))
    for pitch, radius, volume in results:
        # Same exact geometry written with 15+ significant digits: agreement to rounding.
        assert pitch == pytest.approx(DEFAULT_LINK.pitch_m, rel=1e-9)
        assert radius == pytest.approx(DEFAULT_LINK.bore_radius_m, rel=1e-9)
        assert volume == pytest.approx(nominal_volume_m3(DEFAULT_LINK), rel=1e-9)


def test_face_only_file_is_sewn_into_the_solid(tmp_path):
    def faces_only():
        volume = add_link(DEFAULT_LINK)
        gmsh.model.occ.remove([(3, volume)])  # keep its faces

    path = _write(tmp_path / "faces.step", faces_only)
    with gmsh_model():
        gmsh.model.occ.importShapes(str(path))
        gmsh.model.occ.synchronize()
        assert gmsh.model.getEntities(3) == []  # the file really holds no solid
    link = load_link(path, mesh_size_m=COARSE)
    assert link.cad_volume_m3 == pytest.approx(nominal_volume_m3(DEFAULT_LINK), rel=1e-9)
    assert link.pitch_m == pytest.approx(DEFAULT_LINK.pitch_m, rel=1e-9)


def test_missing_file(tmp_path):
    missing = tmp_path / "nope.step"
    with pytest.raises(GeometryError, match="nope.step: no such file"):
        load_link(missing)


def test_text_file_is_not_step(tmp_path):
    path = tmp_path / "notes.step"
    path.write_text("this is not CAD\n")
    with pytest.raises(GeometryError, match="notes.step: not a STEP file"):
        load_link(path)


def test_truncated_step_is_reported(tmp_path):
    good = write_step(DEFAULT_LINK, tmp_path / "good.step").read_text()
    path = tmp_path / "cut.step"
    path.write_text(good[: len(good) // 3])
    with pytest.raises(GeometryError, match="cut.step"):
        load_link(path)


def test_step_without_a_solid(tmp_path):
    path = _write(tmp_path / "open.step", lambda: gmsh.model.occ.addRectangle(0, 0, 0, 0.1, 0.05))
    with pytest.raises(GeometryError, match="open.step: holds no solid"):
        load_link(path)


def test_step_with_two_solids(tmp_path):
    def two():
        gmsh.model.occ.addBox(0, 0, 0, 0.1, 0.05, 0.02)
        gmsh.model.occ.addBox(0.2, 0, 0, 0.1, 0.05, 0.02)

    # Two solids, neither with pin bores: no link body among them (assemblies: test_geometry_real_parts).
    path = _write(tmp_path / "two.step", two)
    with pytest.raises(
        GeometryError, match="two.step: none of its 2 solids holds a pair of equal parallel pin bores.*--body N"
    ):
        load_link(path)


@pytest.mark.parametrize("n_holes", [0, 1])
def test_part_without_two_bores(tmp_path, n_holes):
    path = _write(tmp_path / f"holes{n_holes}.step", lambda: _box_with_holes(n_holes))
    with pytest.raises(
        GeometryError, match="no pair of equal parallel full-round bores.*expected two pin bores.*--bores"
    ):
        load_link(path)


def test_three_equal_holes_in_a_row_give_the_outer_pair(tmp_path):
    link = load_link(_write(tmp_path / "holes3.step", lambda: _box_with_holes(3)), mesh_size_m=COARSE)
    assert link.pitch_m == pytest.approx(0.10, rel=1e-9)


def test_part_with_two_bores_loads(tmp_path):
    # The control for the test above: the same kind of part with two holes is accepted.
    link = load_link(_write(tmp_path / "holes2.step", lambda: _box_with_holes(2)), mesh_size_m=COARSE)
    assert link.pitch_m == pytest.approx(0.05, rel=1e-9)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"mesh_size_m": 0.0}, "mesh_size_m=0.0: expected a positive"),
        ({"mesh_size_m": -0.004}, "mesh_size_m=-0.004: expected a positive"),
        ({"mesh_size_m": float("nan")}, "mesh_size_m=nan"),
        ({"mesh_size_m": 4.0}, "mesh_size_m=4.0: larger than default"),  # millimetres by mistake
        ({"mesh_size_m": 1e-5}, "mesh_size_m=1e-05: would give about"),
        ({"order": 3}, "order=3: expected 1 or 2"),
        ({"bore_refinement": 0.0}, "bore_refinement=0.0"),
        ({"bore_refinement": 2.0}, "bore_refinement=2.0"),
    ],
)
def test_bad_mesh_settings(kwargs, match):
    with pytest.raises(GeometryError, match=match):
        load_link(**kwargs)


def test_bad_unit(tmp_path):
    with pytest.raises(GeometryError, match="unit='in'"):
        write_step(DEFAULT_LINK, tmp_path / "x.step", unit="in")
