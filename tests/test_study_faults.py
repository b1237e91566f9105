"""Faults on a real cluster (`dask scheduler` + `dask worker` processes started here): a worker
killed in the middle of an FEA task, and the client killed mid-study then rerun with --resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pyarrow.parquet as pq
import pytest
from study_cluster import ROOT, ExternalCluster, study_command, write_study

LEVELS = 4  # 4 web thicknesses x 2 bores (one infeasible) x 2 cams x 2 speeds
POINTS = LEVELS * 2 * 2 * 2
INFEASIBLE = POINTS // 2

pytestmark = pytest.mark.slow  # each runs a study of four FEA tasks on a two-worker cluster


@pytest.fixture
def cluster(tmp_path):
    c = ExternalCluster(workers=2, cache=tmp_path / "cache")
    yield c
    c.close()


def _start_study(cluster, study, out) -> subprocess.Popen:
    return subprocess.Popen(
        study_command(study, out, "--scheduler", cluster.address),
        cwd=ROOT,
        env=cluster.env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def _wait(condition, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError(what)
        time.sleep(0.1)


def _rows(out) -> list[dict]:
    return pq.read_table(out / "results.parquet").to_pylist()


def _check_complete(out) -> None:
    rows = _rows(out)
    assert [r["point"] for r in rows] == list(range(POINTS))
    assert len({r["point_id"] for r in rows}) == POINTS
    assert len(list((out / "points").glob("*.json"))) == POINTS
    assert sum(r["status"] == "ok" for r in rows) == POINTS - INFEASIBLE


def test_worker_killed_mid_task(cluster, tmp_path):
    study = write_study(tmp_path, levels=LEVELS)
    out = tmp_path / "out"
    client = cluster.client()
    proc = _start_study(cluster, study, out)
    victim = {}

    def fea_running():
        for address, keys in client.processing().items():
            fea = [k for k in keys if str(k).startswith("fea-")]
            if fea:
                victim.update(address=address, key=str(fea[0]))
                return True
        return False

    try:
        _wait(fea_running, 120, "no FEA task started")
        time.sleep(1.0)  # well inside the task (each takes seconds)
        pid = client.run(os.getpid, workers=[victim["address"]])[victim["address"]]
        assert victim["key"] in map(str, client.processing()[victim["address"]])
        os.kill(pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=600)
    finally:
        client.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    _check_complete(out)
    timings = [json.loads(line) for line in (out / "timings.jsonl").read_text().splitlines()]
    rerun = [t for t in timings if t["task"] == victim["key"]]
    assert len(rerun) == 1 and not rerun[0]["worker"].endswith(f":{pid}")  # finished once, elsewhere


def test_client_killed_then_resumed(cluster, tmp_path):
    study = write_study(tmp_path, levels=LEVELS)
    out = tmp_path / "out"
    proc = _start_study(cluster, study, out)
    points = out / "points"
    try:
        # the infeasible points are written first; wait for the first chain results too
        _wait(lambda: points.is_dir() and len(list(points.glob("*.json"))) > INFEASIBLE, 300, "no chain result")
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    before = {p.name: p.read_bytes() for p in points.glob("*.json")}
    assert INFEASIBLE < len(before) < POINTS, "the client should die mid-study"
    result = subprocess.run(
        study_command(study, out, "--scheduler", cluster.address, "--resume"),
        cwd=ROOT,
        env=cluster.env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    _check_complete(out)
    assert {p.name: p.read_bytes() for p in points.glob("*.json") if p.name in before} == before
    missing = POINTS - len(before)
    assert json.loads((out / "last_run.json").read_text())["ran"] == missing
    runs = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert runs == [{"run": 1, "points_to_run": POINTS}, {"run": 2, "points_to_run": missing}]
    stored_runs = [json.loads(p.read_text())["run"] for p in points.glob("*.json")]
    assert stored_runs.count(2) == missing
