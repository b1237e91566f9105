"""A run resolves its part once (geometry.part): the STEP file is read from disk once and the link
body and its pin bores are chosen once, however many mesh levels the FEA, the stress study and the
cache key need. Each stiffness level loads the body into its own gmsh model from the part's copy
(the STEP bytes kept at resolution, or the parametric link's dimensions), the stress study's
sub-model from the BREP text the measurement wrote: that is counted too, so a level that read the
file again or chose the bores again would fail here.

The runs use an empty private cache, so both the stiffness study and the stress study run.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import gmsh
import pytest

import geometry.assembly
import geometry.measure
import geometry.parametric
import geometry.part
import geometry.step_io
import geometry.symmetry
import pipeline
from fem import cli as fem_cli
from geometry import DEFAULT_LINK, EXAMPLE_STEP, resolve_part

# Coarse on purpose: two FEA levels at 13 and 10 mm, stress levels, a short chain.
FAST = [
    "--mesh-size",
    "10",
    "--drive",
    "link",
    "--links",
    "12",
    "--samples-per-degree",
    "2",
    "-q",
    "--no-images",
    "--materials",
    "al6061-t6",
    "--cams",
    "modified-sine",
    # the counts are taken in this process: --serial keeps the FEA here (by default it runs in a
    # child forked from this process after the part was resolved, stages.beside)
    "--serial",
]


@pytest.fixture
def calls(monkeypatch) -> Counter:
    """Counts of what resolving and meshing a part does: files read, bore choices, gmsh loads."""
    counts: Counter = Counter()

    def counted(module, name, key=None, record=None):
        original = getattr(module, name)

        def wrapper(*args, **kwargs):
            counts[key or name] += 1
            if record is not None:
                counts[record(*args, **kwargs)] += 1
            return original(*args, **kwargs)

        monkeypatch.setattr(module, name, wrapper)

    counted(geometry.step_io, "read_step", record=lambda path: ("read_step", str(Path(path).resolve())))
    counted(geometry.assembly, "select_pin_bores")  # the pin-bore choice (pick_body)
    counted(geometry.assembly, "find_holes")  # hole detection over the solids
    counted(geometry.measure, "symmetry_plane")
    # the parametric link built in gmsh: by the measurement, and by `Part.load_body` (which imports it when called)
    counted(geometry.measure, "add_link")
    counted(geometry.parametric, "add_link")
    counted(gmsh.model.occ, "importShapes", record=lambda path, *a, **k: ("importShapes", str(Path(path).resolve())))
    counted(geometry.part.Part, "load_body")  # one per stiffness level
    counted(geometry.part.Part, "load_body_brep")  # the stress study's sub-model, from the measured body's BREP
    return counts


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def test_a_step_run_reads_the_file_and_chooses_the_bores_once(tmp_path, calls):
    out, cache = tmp_path / "out", tmp_path / "cache"
    assert pipeline.main([*FAST, "--geometry", str(EXAMPLE_STEP), "--out", str(out), "--cache-dir", str(cache)]) == 0
    step = str(Path(EXAMPLE_STEP).resolve())
    assert calls["read_step"] == 1 and calls[("read_step", step)] == 1
    assert calls[("importShapes", step)] == 0  # OpenCASCADE reads the bytes kept at resolution, never the file
    assert calls["select_pin_bores"] == 1 and calls["find_holes"] == 1
    assert calls["symmetry_plane"] == 1
    # both studies ran: 2 stiffness levels and the stress study's sub-model, each loaded into gmsh once
    assert calls["load_body"] >= 2 and calls["load_body_brep"] >= 1
    assert calls["importShapes"] == 1 + calls["load_body"] + calls["load_body_brep"]
    assert calls["add_link"] == 0
    assert _summary(out)["materials"]["al6061-t6"]["stiffness_N_per_m"] > 0


def test_a_parametric_run_builds_the_link_and_chooses_the_bores_once(tmp_path, calls):
    out, cache = tmp_path / "out", tmp_path / "cache"
    assert pipeline.main([*FAST, "--out", str(out), "--cache-dir", str(cache)]) == 0
    assert calls["read_step"] == 0
    assert calls["select_pin_bores"] == 1 and calls["find_holes"] == 1
    assert calls["symmetry_plane"] == 1
    assert calls["load_body"] >= 2 and calls["load_body_brep"] >= 1
    # resolution builds the link once; each stiffness level builds its own copy from the dimensions,
    # the stress study's sub-model loads the measured body's BREP
    assert calls["add_link"] == 1 + calls["load_body"]
    assert calls["importShapes"] == calls["load_body_brep"]
    # the same run again: all of its FEA is in the cache, so the part is never built in gmsh
    calls.clear()
    assert pipeline.main([*FAST, "--out", str(tmp_path / "again"), "--cache-dir", str(cache)]) == 0
    assert calls["add_link"] == 0 and calls["find_holes"] == 0 and calls["load_body"] == 0
    assert calls["load_body_brep"] == 0
    cached, solved = _summary(tmp_path / "again")["materials"]["al6061-t6"], _summary(out)["materials"]["al6061-t6"]
    for key in ("stiffness_N_per_m", "body_mass_kg", "peak_von_mises_converged_Pa_per_N"):
        assert cached[key] == solved[key]


def test_python_m_fem_resolves_the_part_once(tmp_path, calls, capsys):
    assert fem_cli.main([str(EXAMPLE_STEP), "--mesh-size", "10", "--converge-stress", "--json"]) == 0
    step = str(Path(EXAMPLE_STEP).resolve())
    assert calls[("read_step", step)] == 1 and calls[("importShapes", step)] == 0
    assert calls["select_pin_bores"] == 1 and calls["find_holes"] == 1
    assert calls["load_body"] >= 2 and calls["load_body_brep"] >= 1
    assert calls["importShapes"] == 1 + calls["load_body"] + calls["load_body_brep"]
    assert json.loads(capsys.readouterr().out)["stress_converged"] in (True, False)


def test_the_fingerprint_is_the_content_hash_the_fea_cache_was_keyed_by():
    """Cache keys are unchanged: the STEP file's sha256, or that of the default link's repr."""
    assert (
        resolve_part(EXAMPLE_STEP, symmetry=False).fingerprint
        == hashlib.sha256(Path(EXAMPLE_STEP).read_bytes()).hexdigest()
    )
    assert resolve_part(None, symmetry=False).fingerprint == hashlib.sha256(repr(DEFAULT_LINK).encode()).hexdigest()


def test_resolving_the_built_in_link_and_reading_the_part_options_import_no_gmsh():
    """pipeline.py's own process resolves the part and reads the part options but meshes nothing: it
    imports neither gmsh nor the geometry modules that mesh or measure (geometry.measure measures on
    first use of `Part.geometry`, in the FEA's process), as a fresh interpreter shows."""
    probe = (
        "import sys, pipeline\n"
        "from geometry.options import link_source\n"
        "from stages.geometry import resolve_run_part\n"
        "cfg = pipeline.parse_cli([])\n"
        "part = resolve_run_part(cfg)\n"
        "print(json.dumps([part.fingerprint, sorted(m for m in sys.modules if m == 'gmsh' or m.startswith('geometry'))]))\n"
    )
    done = subprocess.run([sys.executable, "-c", "import json\n" + probe], capture_output=True, text=True, check=True)
    fingerprint, modules = json.loads(done.stdout)
    assert fingerprint == resolve_part(None).fingerprint
    assert "gmsh" not in modules and "geometry.measure" not in modules and "geometry.meshing" not in modules
    assert "geometry.part" in modules and "geometry.options" in modules


def test_a_part_meshes_as_its_source_did():
    """A level meshed from the resolved part equals one meshed from the path (same body, same bores)."""
    part = resolve_part(EXAMPLE_STEP)
    from geometry import load_link, mesh_part

    a = mesh_part(part, mesh_size_m=0.012, mirror=True)
    b = load_link(EXAMPLE_STEP, mesh_size_m=0.012, mirror=True)
    assert a.points_m.shape == b.points_m.shape and (a.points_m == b.points_m).all()
    assert a.mirror_plane == b.mirror_plane == part.mirror_plane
    assert a.cad_volume_m3 == part.volume_m3 == part.summary.body_volume_m3


def test_the_stress_study_refines_the_bores_the_user_named(tmp_path, capsys):
    """python -m fem --converge-stress on a part whose pin bores only --bores can name: the stress
    study takes the resolved part (before, it resolved the bare path again and refused it as ambiguous)."""
    from geometry.sample_parts import write_part

    path = tmp_path / "ambiguous.step"
    write_part("ambiguous", path)
    argv = [str(path), "--json", "--mesh-size", "8", "--order", "1", "--bores", "0,-10,6:70,10,6", "--converge-stress"]
    assert fem_cli.main(argv) == 0, capsys.readouterr().err
    result = json.loads(capsys.readouterr().out)
    assert result["part"]["pin_bores"]["rule"] == "given by --bores 0,-10,6:70,10,6"
    assert result["peak_von_mises_converged_Pa_per_N"] > 0
