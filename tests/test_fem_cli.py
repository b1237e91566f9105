"""`python -m fem` end to end in a subprocess: success output and one-line errors (exit 2)."""

import json
import subprocess
import sys
from pathlib import Path

import gmsh
import meshio
import pytest

from geometry.session import initialize_gmsh

REPO = Path(__file__).resolve().parents[1]


def run_cli(*args, timeout=300):
    return subprocess.run(
        [sys.executable, "-m", "fem", *map(str, args)], cwd=REPO, capture_output=True, text=True, timeout=timeout
    )


def write_step(path, build):
    """A STEP file (mm) of whatever `build(occ)` adds to an empty OpenCASCADE model."""
    initialize_gmsh()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        build(gmsh.model.occ)
        gmsh.model.occ.synchronize()
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def plate_with_holes(n_holes):
    """n_holes equal holes at the corners of a 90 x 30 mm rectangle, in order (4: two equal diagonals)."""
    corners = [(30, 15), (120, 45), (120, 15), (30, 45)]

    def build(occ):
        plate = occ.addBox(0, 0, 0, 150, 60, 20)
        holes = [(3, occ.addCylinder(*corners[i], -5, 0, 0, 30, 8)) for i in range(n_holes)]
        if holes:
            occ.cut([(3, plate)], holes)

    return build


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    (d / "notes.step").write_text("this is not a STEP file\n")
    return {
        "missing file": d / "nowhere.step",
        "not STEP": d / "notes.step",
        "no solid": write_step(d / "face.step", lambda occ: occ.addRectangle(0, 0, 0, 100, 50)),
        "no bores": write_step(d / "block.step", plate_with_holes(0)),
        "one bore": write_step(d / "one.step", plate_with_holes(1)),
        "two equal pairs": write_step(d / "four.step", plate_with_holes(4)),
    }


@pytest.mark.parametrize("case", ["missing file", "not STEP", "no solid", "no bores", "one bore", "two equal pairs"])
def test_bad_file_is_one_line_error_exit_2(bad_files, case):
    result = run_cli(bad_files[case])
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert result.stdout.strip() == ""


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--material", "unobtainium"], "unknown material 'unobtainium'"),
        (["--mesh-size", "-2"], "--mesh-size"),
        (["--mesh-size", "fine"], "--mesh-size"),
        (["--order", "3"], "--order"),
        (["--materials-file", "/nonexistent/m.toml"], "cannot read"),
        (["--image", "out.jpg"], ".png"),
    ],
)
def test_bad_option_is_one_line_error_exit_2(args, fragment):
    result = run_cli(*args)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert fragment in result.stderr


def test_json_report_and_image_on_a_coarse_default_link(tmp_path):
    image, vtu = tmp_path / "link.png", tmp_path / "link.vtu"
    result = run_cli("--mesh-size", "9", "--json", "--image", image, "--vtu", vtu, "--material", "ti-grade2")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)  # stdout holds the JSON object only (no CAD-kernel banners)
    for key in (
        "stiffness_N_per_m",
        "stiffness_rel_error_estimate",
        "volume_m3",
        "mass_kg",
        "pitch_m",
        "bore_radius_m",
        "peak_von_mises_Pa_per_N",
        "dofs",
        "timing_s",
    ):
        assert key in report
    assert report["mass_kg"] == pytest.approx(4510.0 * report["volume_m3"], rel=1e-12)
    assert report["pitch_m"] == pytest.approx(0.1125, rel=1e-9)
    # two levels x4/3 apart, and a third where a thin wall is refined (the 2.535 mm rails at 9 mm)
    assert [level["mesh_size_m"] for level in report["levels"]] == pytest.approx([0.016, 0.012, 0.009])
    assert report["material"] == "ti-grade2"
    assert image.stat().st_size > 10_000
    written = meshio.read(vtu)  # the finest level, curved P2 cells, fields at the 1 kN default load
    assert written.cells[0].type == "tetra10"
    assert {"displacement_m", "von_mises_Pa"} <= set(written.point_data)
    # the solve ran on the link's mirror half; the file holds the whole link
    assert report["mirror_plane"] == "y = 0 mm"
    assert written.points[:, 1].min() == pytest.approx(-written.points[:, 1].max(), rel=1e-9)


def test_text_report_names_the_quantities_and_units(tmp_path):
    materials = tmp_path / "mine.toml"
    materials.write_text("[soft]\nyoungs_modulus_Pa = 1e9\npoisson_ratio = 0.3\ndensity_kg_per_m3 = 1000\n")
    result = run_cli("--mesh-size", "12", "--materials-file", materials, "--material", "soft", "--order", "1")
    assert result.returncode == 0, result.stderr
    for label in (
        "pitch",
        "bore radius",
        "volume",
        "mass",
        "N/m",
        "estimated discretisation error",
        "MPa per kN",
        "DOFs",
        "timing",
    ):
        assert label in result.stdout


def test_help_explains_units():
    result = run_cli("--help")
    assert result.returncode == 0
    assert "millimetres" in result.stdout and "N/m" in result.stdout


def test_converge_stress_reports_the_converged_peak_and_what_it_is():
    result = run_cli("--mesh-size", "9", "--order", "1", "--converge-stress", "--json", timeout=600)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["peak_von_mises_converged_Pa_per_N"] > 0
    assert isinstance(report["stress_converged"], bool)
    assert (report["peak_von_mises_converged_rel_change"] <= 0.05) == report["stress_converged"]
    assert "away from the clamped bore" in report["stress_description"]


def test_the_stiffness_levels_peak_stress_is_not_a_folded_cells_artefact():
    """The default study keeps nearly folded curved cells for the volume of the rounds they follow
    (fem.link.closest_to_cad): they carry the stiffness, but their stress is the map's, not the
    part's; on the default link's 4.5 mm level one gave 39.8 MPa/kN. The reported peak skips them
    and lies near the converged peak (13.84 MPa/kN +- 0.015 % on the whole link, the stress study's
    reference: docs/physics.md); 10 % is the coarse level's own discretisation (its levels moved 6-8 %)."""
    result = run_cli("--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["peak_von_mises_Pa_per_N"] == pytest.approx(13.84e3, rel=0.10)
