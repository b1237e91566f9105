"""Real-world-shaped STEP files through `python -m fem` and `pipeline.py`: the part options
(--bores, --pitch, --bore-radius, --body, --hardware-material, --hardware-from-step), what is
printed about the choice, and one-line refusals (exit 2) that name the option to use."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import pipeline as pipeline_module
from fem.cli import main as fem_main
from geometry.sample_parts import write_part

ROOT = Path(__file__).resolve().parents[1]
STEEL_DENSITY = 7870.0  # steel-1018 in fem/data/materials.toml


@pytest.fixture(scope="module")
def parts(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli-parts")
    names = ("nest_holes", "chain_plate", "assembly", "ambiguous", "half_bore")
    return {name: (d / f"{name}.step", *write_part(name, d / f"{name}.step")) for name in names}


def fem(*args):
    return subprocess.run(
        [sys.executable, "-m", "fem", *map(str, args)], cwd=ROOT, capture_output=True, text=True, timeout=600
    )


def pipeline(*args):
    return subprocess.run(
        [sys.executable, str(ROOT / "pipeline.py"), *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.mark.slow
def test_fem_on_a_link_with_nest_screw_holes_prints_the_pair_and_the_ignored_holes(parts):
    # default sizes: the 3 mm grease hole sets them (2 x its radius: 3 mm finest, 4 mm coarse, both
    # mesh; 4.4 mm did not); P1 keeps the run short.
    r = fem(parts["nest_holes"][0], "--order", "1")
    assert r.returncode == 0, r.stderr
    assert "mesh            finest 3 mm" in r.stdout
    lines = r.stdout.splitlines()
    assert lines[0].startswith("pin bores       fixed at (0.00, 0.00, 8.00) mm, loaded at (101.60, 0.00, 8.00) mm")
    assert sum("ignored hole" in line for line in lines) == 7
    assert "pitch           101.600 mm" in r.stdout and "stiffness k" in r.stdout


def test_fem_json_on_an_assembly_reports_the_body_alone_and_the_hardware_masses(parts):
    path, spec, volumes = parts["assembly"]
    r = fem(path, "--json", "--mesh-size", "8", "--order", "1", "--hardware-material", "steel-1018")
    assert r.returncode == 0, r.stderr
    result = json.loads(r.stdout)
    assert result["volume_m3"] == pytest.approx(volumes[0], rel=1e-9)  # the body's CAD volume, not the assembly's
    part = result["part"]
    assert part["solids"] == 5 and part["body_solid"] == 1
    assert part["pin_bores"]["pitch_m"] == pytest.approx(spec.pitch_m, rel=1e-9)
    assert [h["mass_kg"] for h in part["hardware"]] == pytest.approx([v * STEEL_DENSITY for v in volumes[1:]], rel=1e-9)
    assert part["hardware_mass_kg"] == pytest.approx(sum(volumes[1:]) * STEEL_DENSITY, rel=1e-9)


def test_fem_bores_option_runs_an_ambiguous_part(parts):
    r = fem(parts["ambiguous"][0], "--json", "--mesh-size", "8", "--order", "1", "--bores", "0,-10,6:70,10,6")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["part"]["pin_bores"]["rule"] == "given by --bores 0,-10,6:70,10,6"


@pytest.mark.parametrize(
    "part, args, named",
    [
        ("ambiguous", [], "--bores"),
        ("half_bore", [], "--bores"),
        ("half_bore", ["--bores", "0,0,0:80,0,0"], "--bores"),
        ("nest_holes", ["--bores", "0,0:101.6,0,0"], "--bores"),
        ("nest_holes", ["--bores", "0,30,0:101.6,0,0"], "--bores"),
        ("nest_holes", ["--pitch", "abc"], "--pitch"),
        ("nest_holes", ["--pitch", "50"], "--pitch 50"),
        ("nest_holes", ["--bore-radius", "-1"], "--bore-radius"),
        ("assembly", ["--body", "9"], "--body"),
        ("assembly", ["--body", "two"], "--body"),
        ("assembly", ["--hardware-material", "steel-1018,ss304"], "--hardware-material"),
        ("assembly", ["--hardware-material", "unobtainium"], "--hardware-material"),
        (None, ["--pitch", "10"], "--pitch"),
        (None, ["--hardware-material", "steel-1018"], "--hardware-material"),
    ],
)
def test_fem_refusals_are_one_line_exit_2_and_name_the_option(parts, capsys, part, args, named):
    # In process (fem.cli.main is what `python -m fem` runs) to spare an interpreter start per case.
    assert fem_main([*([] if part is None else [str(parts[part][0])]), *args, "--json"]) == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and named in lines[0] and "Traceback" not in err, err
    assert "BoreOverride" not in err and out == ""


def test_fem_refusal_from_the_shell(parts):
    r = fem(parts["ambiguous"][0])
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--bores" in r.stderr, r.stderr


def test_pipeline_takes_the_hardware_mass_from_an_assembly(parts, tmp_path):
    path, _, volumes = parts["assembly"]
    out = tmp_path / "out"
    r = pipeline(
        "--geometry",
        path,
        "--hardware-material",
        "steel-1018",
        "--hardware-from-step",
        "--mesh-size",
        "8",
        "--order",
        "1",
        "--drive",
        "link",
        "--links",
        "12",
        "--samples-per-degree",
        "2",
        "--materials",
        "al6061-t6",
        "--cams",
        "modified-sine",
        "--no-images",
        "--out",
        out,
        "--cache-dir",
        tmp_path / "cache",
    )
    assert r.returncode == 0, r.stderr
    assert "pin bores" in r.stderr and "hardware in the STEP file: 4 solids" in r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["inputs"]["hardware_mass_kg"] == pytest.approx(sum(volumes[1:]) * STEEL_DENSITY, rel=1e-9)


@pytest.mark.parametrize(
    "part, args, named",
    [
        ("ambiguous", [], "--bores"),
        ("nest_holes", ["--bores", "1,2,3"], "--bores"),
        ("assembly", ["--hardware-from-step"], "--hardware-material"),
        (None, ["--bores", "0,0,0:1,0,0"], "--bores"),
    ],
)
def test_pipeline_refusals_are_one_line_exit_2_and_leave_out_untouched(parts, tmp_path, capsys, part, args, named):
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}')
    geometry = [] if part is None else ["--geometry", str(parts[part][0])]
    assert (
        pipeline_module.main([*geometry, *args, "--out", str(out), "--cache-dir", str(tmp_path / "cache"), "-q"]) == 2
    )
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and named in lines[0] and "Traceback" not in err, err
    assert sorted(p.name for p in out.iterdir()) == ["summary.json"]


@pytest.mark.slow
def test_pipeline_runs_the_link_with_nest_screw_holes(parts, tmp_path):
    out = tmp_path / "out"
    r = pipeline(
        "--geometry",
        parts["nest_holes"][0],
        "--drive",
        "link",
        "--links",
        "12",
        "--samples-per-degree",
        "2",
        "--materials",
        "al6061-t6",
        "--cams",
        "modified-sine",
        "--no-images",
        "--out",
        out,
        "--cache-dir",
        tmp_path / "cache",
    )
    assert r.returncode == 0, r.stderr
    assert "pitch 101.600 mm" in r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["geometry"]["pitch_m"] == pytest.approx(0.1016, rel=1e-9)
