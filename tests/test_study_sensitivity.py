"""Sensitivity of a study's metrics to its inputs (study.sensitivity): the estimator against the
exact first-order indices of the Ishigami function and of an additive model with a list variable,
the mapping of a study's points onto samples and list combinations, and the adequacy verdict."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from scipy.stats import qmc

from study.sensitivity import MIN_SAMPLES, first_order_indices, study_sensitivity
from study.spec import parse_study

# Ishigami (a = 7, b = 0.1): exact first-order indices (Saltelli et al. 2008, Global Sensitivity
# Analysis: The Primer, section 4.5): V = a^2/8 + b pi^4/5 + b^2 pi^8/18 + 1/2,
# S1 = (1/2)(1 + b pi^4/5)^2 / V, S2 = (a^2/8) / V, S3 = 0.
A, B = 7.0, 0.1
V = A**2 / 8 + B * math.pi**4 / 5 + B**2 * math.pi**8 / 18 + 0.5
ISHIGAMI = {"x1": 0.5 * (1 + B * math.pi**4 / 5) ** 2 / V, "x2": A**2 / 8 / V, "x3": 0.0}


def ishigami(x: np.ndarray) -> np.ndarray:
    return np.sin(x[:, 0]) + A * np.sin(x[:, 1]) ** 2 + B * x[:, 2] ** 4 * np.sin(x[:, 0])


def _sample(method: str, n: int, seed: int) -> np.ndarray:
    engine = qmc.LatinHypercube(d=3, seed=seed) if method == "lhs" else qmc.Sobol(d=3, scramble=True, seed=seed)
    return qmc.scale(engine.random(n), [-math.pi] * 3, [math.pi] * 3)


def test_exact_ishigami_values():
    assert [round(ISHIGAMI[k], 4) for k in ("x1", "x2", "x3")] == [0.3139, 0.4424, 0.0]


@pytest.mark.parametrize("method", ["lhs", "sobol"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_ishigami_indices_within_their_intervals(method, seed):
    X = _sample(method, 256, seed)
    indices = first_order_indices(X, ["x1", "x2", "x3"], ishigami(X)[:, None], {}, seed)
    assert [i.input for i in indices] == ["x2", "x1", "x3"]
    for i in indices:
        assert i.kind == "range" and 0 < i.half_width < 0.2
        assert abs(i.first_order - ISHIGAMI[i.input]) <= i.half_width, i


def test_one_list_combination_is_salib_rbd_fast():
    """With no list variable the range indices are SALib's RBD-FAST indices unchanged."""
    from SALib.analyze import rbd_fast

    X = _sample("lhs", 128, 7)
    Y = ishigami(X)
    ours = {i.input: i for i in first_order_indices(X, ["x1", "x2", "x3"], Y[:, None], {}, 7)}
    problem = {"num_vars": 3, "names": ["x1", "x2", "x3"], "bounds": [[-math.pi, math.pi]] * 3}
    salib = rbd_fast.analyze(problem, X, Y, M=4, seed=7)
    for k, name in enumerate(("x1", "x2", "x3")):
        assert ours[name].first_order == pytest.approx(salib["S1"][k], rel=1e-12)
        assert ours[name].half_width == pytest.approx(salib["S1_conf"][k], rel=1e-12)


def test_additive_model_with_a_list_variable():
    """Y = 4 x + c with x uniform on [0, 1] (variance 16/12) and c in {0, 1, 2} equally often (variance
    2/3), crossed in full: S_x = (4/3) / 2 = 2/3, S_c = 1/3 exactly; nothing is left to interaction."""
    x = qmc.LatinHypercube(d=1, seed=3).random(128)
    labels = ["a", "b", "c"]
    Y = 4 * x + np.array([0.0, 1.0, 2.0])[None, :]
    indices = {i.input: i for i in first_order_indices(x, ["x"], Y, {"c": labels}, 3)}
    assert indices["x"].kind == "range" and indices["c"].kind == "list"
    for name, exact in (("x", 2 / 3), ("c", 1 / 3)):
        assert abs(indices[name].first_order - exact) <= indices[name].half_width, indices[name]
    assert indices["c"].first_order == pytest.approx(1 / 3, abs=0.02)  # list effect: exact up to sampling of x


def test_constant_metric_has_zero_indices():
    X = _sample("lhs", 64, 0)
    assert all(
        i.first_order == 0 for i in first_order_indices(X, ["x1", "x2", "x3"], np.ones((64, 2)), {"c": [1, 2]}, 0)
    )


STUDY = """
[variables]
rpm = {min = 100.0, max = 200.0}
preload_N = {min = 1000.0, max = 4000.0}
cam = ["modified-sine", "poly-345"]
[fixed]
material = "al6061-t6"
[sampling]
method = "lhs"
points = POINTS
[objectives]
minimise = ["residual_vibration_m"]
"""


def _rows(points: int, missing: set[int] = frozenset()) -> tuple:
    """Rows as the study table has them: range samples outermost, then the cam list; the metric
    depends on rpm and the cam, not the preload."""
    spec = parse_study(tomllib.loads(STUDY.replace("POINTS", str(points))))
    from study.sampling import range_samples

    rows = []
    for s, sample in enumerate(range_samples(spec)):
        for c, cam in enumerate(("modified-sine", "poly-345")):
            point = 2 * s + c
            value = math.nan if s in missing else sample["rpm"] / 100 + (0.5 if cam == "poly-345" else 0.0)
            rows.append({"point": point, **sample, "cam": cam, "residual_vibration_m": value})
    return spec, rows


def test_study_points_map_onto_samples_and_lists():
    spec, rows = _rows(128, missing={5, 9})
    (found,) = study_sensitivity(spec, rows, ["residual_vibration_m"])
    assert found.samples == 126 and found.dropped == 2
    assert found.ranking() == ["rpm", "cam", "preload_N"]
    by_name = {i.input: i for i in found.indices}
    # rpm/100 uniform on [1, 2] (variance 1/12) + 0.5 x cam (variance 1/16): S_rpm = 4/7, S_cam = 3/7
    assert abs(by_name["rpm"].first_order - 4 / 7) <= by_name["rpm"].half_width
    assert by_name["cam"].first_order == pytest.approx(3 / 7, abs=0.02)
    assert abs(by_name["preload_N"].first_order) <= by_name["preload_N"].half_width
    assert found.adequate, found.adequacy


def test_too_few_points_is_said():
    spec, rows = _rows(32)
    (found,) = study_sensitivity(spec, rows, ["residual_vibration_m"])
    assert not found.adequate and found.adequacy.startswith("too few points") and f"{MIN_SAMPLES}" in found.adequacy
    assert found.indices  # still estimated, shown with the warning
    spec, rows = _rows(8)
    (found,) = study_sensitivity(spec, rows, ["residual_vibration_m"])
    assert not found.adequate and found.indices == () and "too few points" in found.adequacy


def test_grid_study_has_no_sensitivity():
    spec = parse_study(tomllib.loads(STUDY.replace('method = "lhs"\npoints = POINTS', 'method = "grid"')))
    assert study_sensitivity(spec, [], ["residual_vibration_m"]) is None


# A small real study: the built-in link at the coarse FEA of the other study tests (one geometry,
# so one FEA), the drive's speed, preload and damping over 64 Latin-hypercube points.
REAL_STUDY = """
[study]
name = "which drive input matters"
report_best = 0

[variables]
rpm = {{min = 60.0, max = 180.0}}
preload_N = {{min = 1000.0, max = 5000.0}}
damping = {{min = 0.01, max = 0.2}}
{coarse}
method = "lhs"
points = 64
seed = {seed}

[objectives]
minimise = ["residual_vibration_m", "peak_tension_N"]
"""


def _inputs_that_matter(found: dict) -> list[str]:
    """The inputs whose interval lies above zero, largest index first: the part of the ranking the
    estimator vouches for (inputs whose intervals include 0 are not told apart)."""
    return [i["input"] for i in found["indices"] if i["first_order"] - i["half_width"] > 0]


@pytest.fixture(scope="module")
def real_studies(tmp_path_factory):
    import subprocess

    from study_cluster import COARSE, ROOT, env, study_command

    folder = tmp_path_factory.mktemp("sensitivity")
    outs = []
    for seed in (1, 2):
        study = folder / f"seed{seed}.toml"
        coarse = COARSE.replace("[fixed]\n", '[fixed]\ncam = "modified-sine"\n').replace('method = "grid"', "")
        study.write_text(REAL_STUDY.format(coarse=coarse, seed=seed))
        out = folder / f"out{seed}"
        result = subprocess.run(
            study_command(study, out, "--workers", "2"),
            cwd=ROOT,
            env=env(folder / "cache"),
            capture_output=True,
            text=True,
            timeout=900,
        )
        assert result.returncode == 0, result.stderr
        outs.append(out)
    return outs


def test_real_study_ranking_is_stable_across_seeds(real_studies):
    import json

    found = [
        {m["metric"]: m for m in json.loads((out / "sensitivity.json").read_text())["metrics"]} for out in real_studies
    ]
    for metric in ("residual_vibration_m", "peak_tension_N"):
        first, second = found[0][metric], found[1][metric]
        assert first["samples"] == second["samples"] == 64 and first["dropped"] == 0
        ranked = _inputs_that_matter(first)
        assert ranked and ranked == _inputs_that_matter(second), (first, second)
        # the cam speed drives both: the dwell's residual vibration and the inertial tension grow with it
        assert ranked[0] == "rpm"
    csv_lines = (real_studies[0] / "sensitivity.csv").read_text().splitlines()
    assert csv_lines[0].startswith("metric,input,kind,first_order,half_width") and len(csv_lines) == 1 + 2 * 3


def test_page_shows_a_sensitivity_chart_per_objective(real_studies):
    from browser import page_in_browser

    out = real_studies[0]
    for metric in ("residual_vibration_m", "peak_tension_N"):
        assert (out / f"sensitivity_{metric}.png").stat().st_size > 1000
    seen = page_in_browser(out / "index.html")
    assert "Which inputs matter: residual_vibration_m" in seen.sections
    assert "Which inputs matter: peak_tension_N" in seen.sections
    assert seen.images == seen.images_drawn >= 4  # Pareto, metrics vs variables, parallel, 2 sensitivity charts
