"""The study file: bad files give one line naming the key, exit status 2 and write nothing; good
files give the same points (and ids) every time; the Pareto filter against brute force."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from study_cluster import ROOT, small_study

from study.cli import main
from study.pareto import pareto_mask
from study.sampling import design_points
from study.spec import StudyError, parse_study
from study.tasks import base_config

GOOD = small_study()

BAD = {
    "unknown variable": (GOOD.replace("rpm = [150.0, 180.0]", "wing_span_m = [1.0, 2.0]"), "variables.wing_span_m"),
    "empty range": (
        GOOD.replace("min = 0.004, max = 0.009", "min = 0.009, max = 0.004"),
        "variables.web_thickness_m: empty range",
    ),
    "empty list": (GOOD.replace("rpm = [150.0, 180.0]", "rpm = []"), "variables.rpm: empty list"),
    "bad sampling": (GOOD.replace('method = "grid"', 'method = "random"'), "sampling.method"),
    "sobol not a power of 2": (
        GOOD.replace('method = "grid"\nlevels = 2', 'method = "sobol"\npoints = 6'),
        "sampling.points",
    ),
    "unknown material": (
        GOOD.replace('material = "al6061-t6"', 'material = "unobtainium"'),
        "fixed.material: unknown material 'unobtainium'",
    ),
    "unknown cam": (GOOD.replace('"poly-345"', '"square-wave"'), "variables.cam[1]: unknown cam law 'square-wave'"),
    "unknown metric": (GOOD.replace('metric = "yield_safety_factor"', 'metric = "happiness"'), "constraints[0].metric"),
    "negative speed": (GOOD.replace("rpm = [150.0, 180.0]", "rpm = [-150.0]"), "variables.rpm[0]"),
    "not TOML": ("[variables\n", "not a valid TOML file"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_study_file(case, tmp_path, capsys):
    text, expected = BAD[case]
    study = tmp_path / "bad.toml"
    study.write_text(text)
    out = tmp_path / "out"
    assert main([str(study), "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("python -m study: error: ") and expected in err, err
    assert "Traceback" not in err
    assert not out.exists()


def test_bad_file_through_the_command_line(tmp_path):
    study = tmp_path / "bad.toml"
    study.write_text(BAD["unknown variable"][0])
    result = subprocess.run(
        [sys.executable, "-m", "study", str(study), "--out", str(tmp_path / "out")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "variables.wing_span_m: unknown variable" in result.stderr
    assert not (tmp_path / "out").exists()


def test_existing_study_needs_resume(tmp_path, capsys):
    study = tmp_path / "s.toml"
    study.write_text(GOOD)
    (tmp_path / "out" / "points").mkdir(parents=True)
    (tmp_path / "out" / "points" / "0123.json").write_text("{}")
    assert main([str(study), "--out", str(tmp_path / "out"), "-q"]) == 2
    assert "--resume" in capsys.readouterr().err


@pytest.mark.parametrize("method", ["lhs", "sobol"])
def test_same_file_and_seed_same_points(method):
    import tomllib

    text = GOOD.replace('method = "grid"\nlevels = 2', f'method = "{method}"\npoints = 8\nseed = 3')
    spec = parse_study(tomllib.loads(text))
    base = base_config(spec.settings)
    first, again = design_points(spec, base), design_points(spec, base)
    assert [(p.point_id, p.inputs) for p in first] == [(p.point_id, p.inputs) for p in again]
    webs = sorted({p.inputs["web_thickness_m"] for p in first})
    assert len(webs) == 8 and 0.004 <= webs[0] and webs[-1] <= 0.009
    other = parse_study(tomllib.loads(text.replace("seed = 3", "seed = 4")))
    assert {p.point_id for p in design_points(other, base)}.isdisjoint({p.point_id for p in first})


def test_grid_crosses_ranges_and_lists():
    import tomllib

    spec = parse_study(tomllib.loads(GOOD))
    points = design_points(spec, base_config(spec.settings))
    assert len(points) == 16 and len({p.point_id for p in points}) == 16
    assert len({p.geometry for p in points}) == 4  # 2 webs x 2 bores; cams and speeds share the FEA
    assert sum(p.infeasible is not None for p in points) == 8


def test_rail_width_sets_the_recess():
    import tomllib

    spec = parse_study(tomllib.loads(GOOD.replace("bore_radius_m = [0.009525, 0.017]", "rail_width_m = [0.003]")))
    p = design_points(spec, base_config(spec.settings))[0]
    assert p.inputs["recess_width_m"] == pytest.approx(0.080 - 2 * 0.003)
    assert p.inputs["rail_width_m"] == pytest.approx(0.003)


def test_web_thicker_than_body_is_infeasible():
    import tomllib

    spec = parse_study(tomllib.loads(GOOD.replace("min = 0.004, max = 0.009", "min = 0.02, max = 0.04")))
    reasons = {p.infeasible for p in design_points(spec, base_config(spec.settings)) if p.infeasible}
    assert any("web_thickness_m < body_height_m" in r for r in reasons)


def _brute_force(costs: np.ndarray) -> np.ndarray:
    n = len(costs)
    return np.array(
        [
            not any(np.all(costs[j] <= costs[i]) and np.any(costs[j] < costs[i]) for j in range(n) if j != i)
            for i in range(n)
        ]
    )


@pytest.mark.parametrize("seed", range(5))
def test_pareto_mask_against_brute_force(seed):
    rng = np.random.default_rng(seed)
    costs = rng.integers(0, 6, size=(60, 1 + seed % 3)).astype(float)  # small integers: many ties
    assert np.array_equal(pareto_mask(costs), _brute_force(costs))


def test_unknown_key_in_a_table():
    with pytest.raises(StudyError, match=r"settings\.mesh_sise_m: unknown key"):
        parse_study({"settings": {"mesh_sise_m": 0.01}})


def test_fea_of_a_link_variant_is_cached_under_its_dimensions(tmp_path):
    """run_fea on two LinkDimensions sharing one cache: each solved (not the other's cached
    result), each found again on a second call."""
    from dataclasses import replace

    from geometry import LinkDimensions
    from stages.fea import run_fea
    from stages.progress import Progress
    from study.spec import Settings

    settings = Settings(mesh_size_m=0.014, order=1)
    base = replace(base_config(settings, tmp_path), materials=("al6061-t6",))
    thin, thick = (replace(base, link=LinkDimensions(web_thickness_m=w)) for w in (0.004, 0.009))
    first = {c.link.web_thickness_m: run_fea(c, Progress(True))["al6061-t6"] for c in (thin, thick)}
    assert not any(r.cached for r in first.values())
    assert first[0.009].body_mass_kg > first[0.004].body_mass_kg
    again = run_fea(thin, Progress(True))["al6061-t6"]
    assert again.cached and again.stiffness_N_per_m == first[0.004].stiffness_N_per_m


def test_out_that_is_a_file_is_refused_in_one_line(tmp_path, capsys):
    study = tmp_path / "s.toml"
    study.write_text(GOOD)
    blocker = tmp_path / "out"
    blocker.write_text("not a folder")
    assert main([str(study), "--out", str(blocker), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err and "is not a folder" in err
    assert blocker.read_text() == "not a folder"
