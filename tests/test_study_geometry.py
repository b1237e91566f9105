"""Studies of a designer's own link: `geometry` (a STEP file, or a list of CAD variants) in the
study file, checked on the client, its bytes sent with the FEA task; a refused variant is an
infeasible point; the same table on a LocalCluster and on `dask worker` processes that run in
another folder (no shared path to the STEP files). Also the tensioner as study variables."""

from __future__ import annotations

import re
import subprocess
import tomllib
from dataclasses import replace

import gmsh
import numpy as np
import pyarrow.parquet as pq
import pytest
from study_cluster import COARSE, ROOT, ExternalCluster, env, study_command

from geometry import DEFAULT_LINK, write_step
from geometry.session import gmsh_model
from geometry.step_io import write_model_step
from study.cli import main
from study.spec import StudyError, parse_study

VARIANTS = """
[study]
name = "three CAD variants"
report_best = 0

[variables]
geometry = {geometry}
rpm = [150.0, 180.0]
{coarse}
levels = 2

[objectives]
minimise = ["body_mass_kg", "residual_vibration_m"]
"""


def _coarse() -> str:
    return COARSE.replace("[fixed]\n", '[fixed]\ncam = "modified-sine"\n')


def _one_hole_plate(path):
    """A plate with one hole: no pin-bore pair, so the geometry stage refuses it."""
    with gmsh_model("one-hole"):
        occ = gmsh.model.occ
        box = occ.addBox(0, 0, 0, 0.1, 0.04, 0.02)
        occ.cut([(3, box)], [(3, occ.addCylinder(0.05, 0.02, -0.01, 0, 0, 0.04, 0.006))])
        occ.synchronize()
        write_model_step(path, unit="mm")
    return path


@pytest.fixture(scope="module")
def variants(tmp_path_factory):
    """A study folder with three STEP variants: two links (5 and 9 mm webs) and a refused plate."""
    folder = tmp_path_factory.mktemp("variants")
    (folder / "cad").mkdir()
    write_step(replace(DEFAULT_LINK, web_thickness_m=0.005), folder / "cad" / "thin.step")
    write_step(replace(DEFAULT_LINK, web_thickness_m=0.009), folder / "cad" / "thick.step")
    _one_hole_plate(folder / "cad" / "plate.step")
    study = folder / "variants.toml"
    study.write_text(
        VARIANTS.format(geometry='["cad/thin.step", "cad/thick.step", "cad/plate.step"]', coarse=_coarse())
    )
    return study


def _run(command, cache, cwd=ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(command, cwd=cwd, env=env(cache), capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def local_variants(variants, tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "out"
    result = _run(study_command(variants, out, "--workers", "2"), out.parent / "cache")
    assert result.returncode == 0, result.stderr
    return out


def _rows(out) -> list[dict]:
    return pq.read_table(out / "results.parquet").to_pylist()


def test_variants_two_feasible_sets_and_one_refusal(local_variants):
    rows = _rows(local_variants)
    assert [r["geometry_file"] for r in rows] == ["cad/thin.step", "cad/thick.step", "cad/plate.step"] * 2
    by_file = {
        f: [r for r in rows if r["geometry_file"] == f] for f in ("cad/thin.step", "cad/thick.step", "cad/plate.step")
    }
    for name in ("cad/thin.step", "cad/thick.step"):
        assert all(r["status"] == "ok" and r["stiffness_N_per_m"] > 1e7 for r in by_file[name])
        assert len({r["geometry"] for r in by_file[name]}) == 1  # one FEA group per file
    # the thicker web is the heavier and stiffer link
    assert by_file["cad/thick.step"][0]["body_mass_kg"] > by_file["cad/thin.step"][0]["body_mass_kg"]
    assert by_file["cad/thick.step"][0]["stiffness_N_per_m"] > by_file["cad/thin.step"][0]["stiffness_N_per_m"]
    refused = by_file["cad/plate.step"]
    assert all(r["status"] == "infeasible" and not r["feasible"] and np.isnan(r["stiffness_N_per_m"]) for r in refused)
    reason = refused[0]["reason"]
    assert (
        reason.startswith("geometry: cad/plate.step: no pair of equal parallel full-round bores") and "\n" not in reason
    )
    assert "/tmp" not in reason and "study-fea" not in reason  # the study's file, not the worker's copy
    assert "cad/plate.step" in (local_variants / "index.html").read_text()


def test_same_table_on_workers_in_another_folder(variants, local_variants, tmp_path):
    """`dask worker` processes started in an empty folder of their own: the STEP files reach them
    only as the bytes sent with their FEA tasks."""
    elsewhere = tmp_path / "workers"
    elsewhere.mkdir()
    cluster = ExternalCluster(workers=2, cache=tmp_path / "cache", worker_cwd=elsewhere)
    try:
        result = _run(study_command(variants, tmp_path / "out", "--scheduler", cluster.address), tmp_path / "cache")
    finally:
        cluster.close()
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "out" / "results.csv").read_text() == (local_variants / "results.csv").read_text()
    assert not any(p.suffix == ".step" for p in elsewhere.rglob("*"))  # the workers kept no copy


def test_step_of_the_builtin_link_is_the_builtin_link(tmp_path):
    """The reduction: a study's FEA task on a STEP file of the default link (its bytes only, in a
    worker folder without the file) gives the built-in default link's mass and pitch exactly, and its
    stiffness within the FEA's own error estimate (the two meshes differ: gmsh meshes the imported
    solid, not the parametric one)."""
    from study.spec import PartFile, Settings
    from study.tasks import fea_task, part_payload

    path = write_step(DEFAULT_LINK, tmp_path / "default.step")
    data = path.read_bytes()
    settings = Settings(mesh_size_m=0.014, order=1, samples_per_degree=1, fea_cache=False)
    part = part_payload(PartFile("default.step", path, "", data), {})
    path.unlink()  # the task has the bytes, not the path
    builtin = fea_task({}, ("al6061-t6",), settings)["fea"]["al6061-t6"]
    step = fea_task({}, ("al6061-t6",), settings, part)
    assert step["reason"] is None, step["reason"]
    fea = step["fea"]["al6061-t6"]
    assert fea.body_mass_kg == pytest.approx(builtin.body_mass_kg, rel=1e-9)
    assert fea.pitch_m == pytest.approx(builtin.pitch_m, rel=1e-9)
    tolerance = fea.stiffness_rel_error_estimate + builtin.stiffness_rel_error_estimate
    assert fea.stiffness_N_per_m == pytest.approx(builtin.stiffness_N_per_m, rel=tolerance)


# --- the study file's geometry, checked on the client ------------------------------------------

FIXED = """
[variables]
rpm = [150.0, 180.0]
[fixed]
geometry = {geometry}
cam = "modified-sine"
{extra}
"""


@pytest.fixture
def step_folder(tmp_path):
    write_step(DEFAULT_LINK, tmp_path / "link.step")
    (tmp_path / "cad").mkdir()
    (tmp_path / "notes.step").write_text("solid link\nendsolid\n")
    return tmp_path


@pytest.mark.parametrize(
    "geometry, table, message",
    [
        ('"missing.step"', "fixed", "fixed.geometry: no such file 'missing.step'"),
        ('"cad"', "fixed", "fixed.geometry: 'cad' is a folder; expected a STEP file"),
        ('"notes.step"', "fixed", "fixed.geometry: 'notes.step' is not a STEP file"),
        (
            '["link.step", "./link.step"]',
            "variables",
            "variables.geometry: 'link.step' and './link.step' are the same file",
        ),
        (
            '["link.step", "copy.step"]',
            "variables",
            "variables.geometry: 'link.step' and 'copy.step' are files with the same contents",
        ),
        ('["link.step", "missing.step"]', "variables", "variables.geometry[1]: no such file 'missing.step'"),
    ],
)
def test_bad_geometry_is_refused_before_anything_is_written(step_folder, capsys, geometry, table, message):
    (step_folder / "copy.step").write_bytes((step_folder / "link.step").read_bytes())
    text = (FIXED if table == "fixed" else VARIANTS).format(geometry=geometry, extra="", coarse=_coarse())
    study = step_folder / "bad.toml"
    study.write_text(text)
    out = step_folder / "out"
    assert main([str(study), "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err, err
    assert not out.exists()


def test_bad_study_file_exits_2_from_the_command_line(step_folder):
    study = step_folder / "bad.toml"
    study.write_text(FIXED.format(geometry='"cad"', extra=""))
    result = subprocess.run(
        study_command(study, step_folder / "out"),
        cwd=ROOT,
        env=env(step_folder / "cache"),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "is a folder" in result.stderr
    assert not (step_folder / "out").exists()


def test_paths_are_relative_to_the_study_file(step_folder, monkeypatch):
    monkeypatch.chdir(step_folder / "cad")
    from study.spec import load_study

    (step_folder / "ok.toml").write_text(FIXED.format(geometry='"link.step"', extra=""))
    spec = load_study(step_folder / "ok.toml")
    assert spec.fixed["geometry_file"] == "link.step" and spec.parts["link.step"].path == step_folder / "link.step"


@pytest.mark.parametrize(
    "extra, message",
    [
        ("web_thickness_m = 0.006", "fixed.web_thickness_m: a dimension of the built-in link"),
        ('bores = "0,0,8"', "--bores '0,0,8'"),
        ('pitch = "-3"', "--pitch '-3': expected a positive length in mm"),
        ('hardware_material = "unobtainium"', "fixed.hardware_material: unknown material 'unobtainium'"),
        ("hardware_from_step = true", "fixed.hardware_from_step: the hardware solids need a material"),
        (
            'hardware_material = "al6061-t6"\nhardware_from_step = true\nhardware_mass_kg = 0.5',
            "fixed.hardware_from_step: the hardware mass comes from the STEP file's solids",
        ),
    ],
)
def test_part_options_are_checked_as_on_the_command_line(step_folder, extra, message):
    data = tomllib.loads(FIXED.format(geometry='"link.step"', extra=extra))
    with pytest.raises(StudyError, match=re.escape(message)):
        parse_study(data, step_folder)


def test_part_options_need_a_step_geometry():
    data = tomllib.loads('[fixed]\npitch = 101.6\ncam = "modified-sine"\n')
    with pytest.raises(StudyError, match="fixed.pitch: a part option, only for a STEP geometry"):
        parse_study(data)


def test_part_options_go_into_the_fea_identity(step_folder):
    from study.sampling import design_points
    from study.tasks import base_config

    plain = parse_study(tomllib.loads(FIXED.format(geometry='"link.step"', extra="")), step_folder)
    pitched = parse_study(tomllib.loads(FIXED.format(geometry='"link.step"', extra="pitch = 112.5")), step_folder)
    a, b = (design_points(s, base_config(s.settings)) for s in (plain, pitched))
    assert len(a) == len(b) == 4  # 2 speeds x both materials (one mesh for both)
    assert len({p.geometry for p in a}) == len({p.geometry for p in b}) == 1 and a[0].geometry != b[0].geometry
    assert "web_thickness_m" not in a[0].inputs and a[0].inputs["geometry_file"] == "link.step"


# --- the machine: the idler tensioner as study variables -----------------------------------------


def test_tensioner_variables_reach_the_run_config():
    from study.sampling import design_points
    from study.tasks import base_config, point_config

    spec = parse_study(
        tomllib.loads("""
[variables]
tensioner_rate_N_per_m = [2.0e5, 8.0e5]
[fixed]
tensioner_mass_kg = 4.0
tensioner_damping_N_s_per_m = 150.0
cam = "modified-sine"
material = "al6061-t6"
""")
    )
    points = design_points(spec, base_config(spec.settings))
    assert [p.inputs["tensioner_rate_N_per_m"] for p in points] == [2.0e5, 8.0e5]
    cfg = point_config(spec.settings, points[1].inputs)
    assert (cfg.tensioner_rate_N_per_m, cfg.tensioner_mass_kg, cfg.tensioner_damping_N_s_per_m) == (8.0e5, 4.0, 150.0)


def test_builtin_study_without_a_tensioner_has_no_tensioner_columns():
    from study.sampling import design_points
    from study.tasks import base_config

    spec = parse_study(tomllib.loads('[fixed]\ncam = "modified-sine"\nmaterial = "al6061-t6"\n'))
    (point,) = design_points(spec, base_config(spec.settings))
    assert not any(k.startswith("tensioner_") for k in point.inputs)


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "[variables]\ntensioner_rate_N_per_m = {min = 1e5, max = 2e5}",
            "variables.tensioner_rate_N_per_m: the tensioner needs its carriage mass",
        ),
        ("[fixed]\ntensioner_mass_kg = 0.0", r"fixed.tensioner_mass_kg: expected a value > 0, got 0.0"),
        (
            "[fixed]\ntensioner_mass_kg = 2.0\ntensioner_damping_N_s_per_m = -1.0",
            r"fixed.tensioner_damping_N_s_per_m: expected a value >= 0, got -1.0",
        ),
    ],
)
def test_tensioner_checks(text, message):
    with pytest.raises(StudyError, match=message):
        parse_study(tomllib.loads(text))


@pytest.mark.parametrize("example", sorted((ROOT / "examples").glob("*.toml")), ids=lambda p: p.name)
def test_example_studies_load(example):
    """Every example study is valid, its STEP paths resolved against the examples folder."""
    from study.sampling import design_points
    from study.spec import load_study
    from study.tasks import base_config

    spec = load_study(example)
    points = design_points(spec, base_config(spec.settings))
    assert points and all(p.point_id for p in points)
    if "geometry_file" in spec.fixed:
        assert spec.parts[spec.fixed["geometry_file"]].path == (ROOT / "geometry" / "data" / "example_link.step")
