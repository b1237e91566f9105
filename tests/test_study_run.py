"""`python -m study` end to end on a real Dask cluster: a LocalCluster, and a `dask scheduler` with
two `dask worker` processes started here; the table, infeasible reasons, the Pareto front against
a brute-force check, the page, the full report of the best design, and the same table both ways."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pyarrow.parquet as pq
import pytest
from study_cluster import ROOT, ExternalCluster, env, study_command, write_study

POINTS = 2 * 2 * 2 * 2  # web levels x bores x cams x speeds
INFEASIBLE = POINTS // 2  # the 17 mm bore is larger than the 16 mm lug


def _run(command: list[str], cache) -> subprocess.CompletedProcess:
    return subprocess.run(command, cwd=ROOT, env=env(cache), capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("local")
    study = write_study(folder, report_best=1)
    result = _run(study_command(study, folder / "out", "--workers", "2"), folder / "cache")
    assert result.returncode == 0, result.stderr
    return study, folder / "out"


def _table(out) -> list[dict]:
    return pq.read_table(out / "results.parquet").to_pylist()


def _dominates(a, b) -> bool:
    return all(x <= y for x, y in zip(a, b)) and any(x < y for x, y in zip(a, b))


def _same_rows(a: list[dict], b: list[dict]) -> bool:
    """Equal value for value (NaN equal to NaN: a point not computed is NaN in both)."""

    def same(x, y):
        return x == y or (isinstance(x, float) and isinstance(y, float) and np.isnan(x) and np.isnan(y))

    return len(a) == len(b) and all(
        ra.keys() == rb.keys() and all(same(ra[k], rb[k]) for k in ra) for ra, rb in zip(a, b)
    )


def test_every_point_once_with_inputs_and_metrics(local_run):
    _, out = local_run
    rows = _table(out)
    assert [r["point"] for r in rows] == list(range(POINTS))
    assert len({r["point_id"] for r in rows}) == POINTS
    ok = [r for r in rows if r["status"] == "ok"]
    assert len(ok) == POINTS - INFEASIBLE
    for r in ok:
        assert r["material"] == "al6061-t6" and r["links"] == 12
        assert r["stiffness_N_per_m"] > 1e7 and 0 < r["body_mass_kg"] < 1
        assert r["residual_vibration_m"] >= 0 and r["yield_safety_factor"] > 0
    # a thicker web is a heavier and stiffer link
    by_web = {r["web_thickness_m"]: r for r in ok}
    assert by_web[0.009]["body_mass_kg"] > by_web[0.004]["body_mass_kg"]
    assert by_web[0.009]["stiffness_N_per_m"] > by_web[0.004]["stiffness_N_per_m"]
    csv_lines = (out / "results.csv").read_text().splitlines()
    assert len(csv_lines) == POINTS + 1 and csv_lines[0].split(",")[:3] == ["point", "point_id", "geometry"]


def test_infeasible_points_carry_their_reason(local_run):
    _, out = local_run
    for r in _table(out):
        if r["bore_radius_m"] == 0.017:
            assert r["status"] == "infeasible" and not r["feasible"]
            assert "bore_radius_m < lug_radius_m" in r["reason"] and r["reason"] == r["infeasible_reason"]
            assert np.isnan(r["stiffness_N_per_m"])
        else:
            assert r["status"] == "ok" and r["reason"] == ""
            broken = r["yield_safety_factor"] < 2.5
            assert r["feasible"] == (not broken)
            assert ("yield_safety_factor" in r["infeasible_reason"]) == broken


def test_pareto_front_matches_brute_force(local_run):
    _, out = local_run
    rows = _table(out)
    feasible = [r for r in rows if r["feasible"]]
    assert feasible, "the study should leave feasible designs"
    costs = [(r["body_mass_kg"], r["residual_vibration_m"]) for r in feasible]
    expected = [not any(_dominates(c, d) for c in costs) for d in costs]
    assert [r["pareto"] for r in feasible] == expected
    assert not any(r["pareto"] for r in rows if not r["feasible"])
    pareto_csv = (out / "pareto.csv").read_text().splitlines()
    assert len(pareto_csv) == 1 + sum(expected)


def test_page_and_best_report(local_run):
    _, out = local_run
    page = (out / "index.html").read_text()
    for png in ("pareto.png", "metrics_vs_variables.png", "parallel_coordinates.png"):
        assert (out / png).stat().st_size > 1000
    assert page.count("data:image/png;base64,") == 3 and "Pareto front" in page
    reports = list((out / "best").glob("point-*/report.html"))
    assert len(reports) == 1 and f'href="best/{reports[0].parent.name}/report.html"' in page
    assert (reports[0].parent / "al6061-t6_deformed.png").stat().st_size > 1000
    summary = json.loads((reports[0].parent / "summary.json").read_text())
    point = int(reports[0].parent.name.split("-")[1])
    row = next(r for r in _table(out) if r["point"] == point)
    assert row["pareto"]
    assert summary["materials"]["al6061-t6"]["stiffness_N_per_m"] == pytest.approx(row["stiffness_N_per_m"], rel=1e-12)


def test_external_scheduler_gives_the_same_table(local_run, tmp_path):
    _, local_out = local_run
    study = write_study(tmp_path, report_best=0)  # the same points; the best report is tested above
    cluster = ExternalCluster(workers=2, cache=tmp_path / "cache")
    try:
        result = _run(study_command(study, tmp_path / "out", "--scheduler", cluster.address), tmp_path / "cache")
    finally:
        cluster.close()
    assert result.returncode == 0, result.stderr
    external, local = (pq.read_table(o / "results.parquet") for o in (tmp_path / "out", local_out))
    assert external.schema == local.schema
    assert _same_rows(external.to_pylist(), local.to_pylist())
    assert (tmp_path / "out" / "results.csv").read_text() == (local_out / "results.csv").read_text()
