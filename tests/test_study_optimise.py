"""--optimise: differential evolution on the Dask client over a range variable, constraints by
penalty, convergence history written and shown on the page."""

from __future__ import annotations

import csv
import subprocess

import pytest
from study_cluster import COARSE, ROOT, env, study_command

from study.optimise import INFEASIBLE_OFFSET, penalised
from study.spec import parse_study

STUDY_TEMPLATE = """
[study]
name = "lightest web"
report_best = 0

[variables]
web_thickness_m = {min = 0.004, max = 0.012}

cam = ["modified-sine"]
{coarse}
levels = 2

[[constraints]]
metric = "yield_safety_factor"
min = 1.0

[objectives]
minimise = ["body_mass_kg"]

[optimise]
popsize = 5
maxiter = 2
seed = 1
"""
STUDY = STUDY_TEMPLATE.replace("{coarse}", COARSE)


def test_penalty_orders_feasible_before_infeasible():
    import tomllib

    spec = parse_study(tomllib.loads(STUDY))
    ok = {"status": "ok", "reason": "", "body_mass_kg": 0.4, "yield_safety_factor": 3.0}
    slightly = {**ok, "yield_safety_factor": 0.9}
    badly = {**ok, "yield_safety_factor": 0.2}
    unbuilt = {"status": "infeasible", "reason": "geometry: ...", "body_mass_kg": float("nan")}
    values = [penalised(r, spec) for r in (ok, slightly, badly, unbuilt)]
    assert values[0] == 0.4 and values == sorted(values) and values[1] > INFEASIBLE_OFFSET


@pytest.mark.slow
def test_optimiser_finds_the_thin_web(tmp_path):
    study = tmp_path / "opt.toml"
    study.write_text(STUDY)
    out = tmp_path / "out"
    result = subprocess.run(
        study_command(study, out, "--workers", "2", "--optimise"),
        cwd=ROOT,
        env=env(tmp_path / "cache"),
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert result.returncode == 0, result.stderr
    history = list(csv.DictReader((out / "optimisation_history.csv").open()))
    best = [float(h["best_objective"]) for h in history]
    assert len(history) >= 1 and best == sorted(best, reverse=True)  # never worse from one generation to the next
    assert all(h["best_feasible"] == "True" for h in history)
    # the lightest link has the thinnest web: the optimiser moves into the lower part of the range
    assert float(history[-1]["best_web_thickness_m"]) < 0.004 + 0.4 * (0.012 - 0.004)
    evaluated = list(csv.DictReader((out / "optimisation_points.csv").open()))
    assert int(history[-1]["evaluations"]) == len(evaluated)
    assert "Optimisation" in (out / "index.html").read_text()
