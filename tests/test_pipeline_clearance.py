"""`python pipeline.py` with the chain-model options of issue #11: which model runs and why, the
contact outputs, `--pin-clearance 0` = the linear chain, bad values refused."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import pipeline

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
    "poly-4567",
]
CONTACT_KEYS = (
    "model",
    "model_reason",
    "contact_lost",
    "free_play_time_fraction",
    "impacts_per_cycle",
    "impact_force_spike_N",
    "impact_closing_speed_max_m_s",
    "impact_energy_per_cycle_J",
    "impact_dissipated_per_cycle_J",
    "preload_for_full_contact_N",
    "peak_tension_N",
    "min_tension_N",
)


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fea-cache")


def _run(tmp_path: Path, cache_dir: Path, *args: str) -> dict:
    out = tmp_path / ("out" + "_".join(a.strip("-") for a in args))
    assert pipeline.main([*FAST, *args, "--out", str(out), "--cache-dir", str(cache_dir)]) == 0
    return {"summary": json.loads((out / "summary.json").read_text()), "out": out}


def _scenario(run: dict) -> dict:
    return run["summary"]["materials"]["al6061-t6"]["cams"]["poly-4567"]


def test_default_runs_the_clearance_model_and_says_why(tmp_path, cache_dir):
    run = _run(tmp_path, cache_dir)
    sc = _scenario(run)
    assert all(k in sc for k in CONTACT_KEYS)
    assert sc["model"] == "clearance" and "leaves pulling contact" in sc["model_reason"]
    assert sc["contact_lost"] and 0 < sc["free_play_time_fraction"] < 1 and sc["impacts_per_cycle"] > 0
    assert sc["preload_for_full_contact_N"] > run["summary"]["inputs"]["preload_N"]
    assert sc["clearance_steady_state"]["found"]
    assert run["summary"]["inputs"]["pin_clearance_m"] == pytest.approx(94e-6)
    page = (run["out"] / "report.html").read_text()
    assert "Model: clearance chain" in page and "lets links push" not in page
    assert (run["out"] / "al6061-t6_tension_map.png").exists()
    assert "impacts per cycle" in (run["out"] / "tension.csv").read_text()


def test_zero_clearance_reproduces_the_linear_chain(tmp_path, cache_dir):
    zero = _scenario(_run(tmp_path, cache_dir, "--pin-clearance", "0"))
    linear = _scenario(_run(tmp_path, cache_dir, "--model", "linear"))
    assert zero["model"] == "linear" and "clearance 0" in zero["model_reason"]
    assert zero["stations"] == linear["stations"]
    assert zero["min_tension_N"] == linear["min_tension_N"] < 0  # the linear chain pushes: contact lost
    assert zero["contact_lost"]


def test_a_chain_that_can_only_pull_and_a_tensioner(tmp_path, cache_dir):
    pull_only = _scenario(_run(tmp_path, cache_dir, "--pin-clearance", "inf"))
    assert pull_only["model"] == "clearance" and pull_only["min_tension_N"] >= 0.0
    assert pull_only["impact_force_spike_N"] > 0 and pull_only["impact_closing_speed_max_m_s"] > 0
    tensioned = _scenario(
        _run(tmp_path, cache_dir, "--tensioner-rate", "2e5", "--tensioner-mass", "5", "--tensioner-damping", "200")
    )
    assert tensioned["model"] == "clearance" and "tensioner" in tensioned["model_reason"]


@pytest.mark.parametrize(
    "args, named",
    [
        (["--pin-clearance", "-0.1"], "--pin-clearance"),
        (["--pin-clearance", "loose"], "--pin-clearance"),
        (["--rayleigh", "3"], "--rayleigh"),
        (["--rayleigh", "a:b"], "--rayleigh"),
        (["--rayleigh=-1:1e-5"], "--rayleigh"),
        (["--rayleigh", "1:1e-5", "--span-damping", "kelvin-voigt"], "--rayleigh"),
        (["--tensioner-mass", "0"], "--tensioner-mass"),
        (["--tensioner-rate", "-5", "--tensioner-mass", "5"], "--tensioner-rate"),
        (["--tensioner-rate", "1e5"], "--tensioner-mass"),
        (["--tensioner-damping", "-1", "--tensioner-mass", "5"], "--tensioner-damping"),
    ],
)
def test_bad_chain_model_values_are_one_line_exit_2(args, named, tmp_path, capsys):
    assert pipeline.main([*args, "--out", str(tmp_path / "never")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and named in lines[0]
    assert not (tmp_path / "never").exists()
