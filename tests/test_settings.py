"""The settings package: each default written once (RunConfig), read by the command line and by
studies; every range check named after its option; a cam law added by one registration reaches
'all', the command line, studies and summary.json."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

import pipeline
from dynamics.cams import MotionLaw, laws, register_law
from settings import (
    LIMITS,
    RunConfig,
    SettingsError,
    cam_ids,
    check_run_config,
    extra_cam_ids,
    known_cam_ids,
    registries,
)
from study.spec import Settings, parse_study
from study.tasks import base_config
from study.variables import RUN, VARIABLES

COARSE = ["--mesh-size", "10", "--drive", "link", "--links", "12", "--samples-per-degree", "2", "--no-images", "-q"]


def test_the_command_line_defaults_are_run_config_defaults():
    assert pipeline.parse_cli([]) == RunConfig()


def test_the_defaults_are_read_from_the_models_that_own_them():
    from dynamics.models.clearance import DEFAULT_PIN_CLEARANCE_M
    from geometry.dimensions import DEFAULT_HARDWARE_MASS_KG, NEST_MASS_KG

    d = RunConfig()
    assert (d.pin_clearance_m, d.hardware_mass_kg, d.nest_mass_kg) == (
        DEFAULT_PIN_CLEARANCE_M,
        DEFAULT_HARDWARE_MASS_KG,
        NEST_MASS_KG,
    )


def test_the_chain_defaults_have_one_home():
    """The damping ratio and the preload are written once (dynamics.options): the run's defaults,
    ChainModel's and the tooth contact's load are that very object, so a literal repeated anywhere,
    even with the same value, fails here."""
    from dataclasses import fields

    from dynamics.models.chain import ChainModel
    from dynamics.models.wheels import DEFAULT_TOOTH_LOAD_N
    from dynamics.options import DEFAULT_DAMPING_RATIO, DEFAULT_PRELOAD_N

    chain = {f.name: f.default for f in fields(ChainModel)}
    d = RunConfig()
    assert d.damping is chain["damping_ratio"] is DEFAULT_DAMPING_RATIO
    assert d.preload_N is chain["preload_N"] is DEFAULT_TOOTH_LOAD_N is DEFAULT_PRELOAD_N


def test_the_memory_budget_reaches_the_fea_settings_and_its_cache_key():
    from fem.budget import DEFAULT_MAX_MEMORY_GB
    from fem.materials import get_material
    from stages.fea import fea_cache_settings, fea_settings

    assert RunConfig().max_memory_gb == DEFAULT_MAX_MEMORY_GB
    cfg = pipeline.parse_cli(["--max-memory", "3"])
    settings = fea_settings(cfg)
    assert cfg.max_memory_gb == settings.max_memory_gb == 3.0
    material = get_material("al6061-t6")
    assert fea_cache_settings(cfg, settings, material, None) != fea_cache_settings(
        RunConfig(), fea_settings(RunConfig()), material, None
    )


def test_help_shows_the_run_config_defaults_in_the_options_units():
    text = pipeline.build_parser().format_help()
    d = RunConfig()
    assert f"(default: {d.pin_clearance_m * 1e3:g}," in text and f"(default: {d.settling_band_m * 1e3:g})" in text


def test_a_study_starts_from_the_run_config_defaults():
    settings = Settings()
    d = RunConfig()
    for name in ("mesh_size_m", "order", "samples_per_degree", "solver", "settling_band_m", "steady_state"):
        assert getattr(settings, name) == getattr(d, name), name
    assert settings.station == d.focus_station
    assert base_config(settings) == replace(d, quiet=True, images=False)


def test_a_study_bounds_its_run_variables_with_the_settings_limits():
    run_variables = [v for v in VARIABLES.values() if v.target == RUN]
    assert run_variables
    for variable in run_variables:
        assert variable.bounds == LIMITS[variable.field].bounds, variable.name


@pytest.mark.parametrize("name", list(LIMITS))
def test_a_value_outside_its_limit_is_one_line_naming_the_option(name):
    limit = LIMITS[name]
    bounds = limit.bounds
    bad = bounds.lower if not bounds.lower_included else bounds.lower - 1
    with pytest.raises(SettingsError) as caught:
        check_run_config(replace(RunConfig(), **{name: bad}))
    message = str(caught.value)
    assert message.startswith(f"{limit.option}: expected ") and "\n" not in message


@pytest.mark.parametrize("name", ["pin_clearance_m", "friction", "damping", "settling_band_m", "preload_N"])
def test_every_default_passes_its_check_and_nan_does_not(name):
    check_run_config(RunConfig())
    with pytest.raises(SettingsError, match=LIMITS[name].option):
        check_run_config(replace(RunConfig(), **{name: math.nan}))


def _poly_345(x):
    """The 3-4-5 polynomial written out here, independently of dynamics.cams.laws."""
    x = np.asarray(x, dtype=float)
    return (
        10 * x**3 - 15 * x**4 + 6 * x**5,
        30 * x**2 - 60 * x**3 + 30 * x**4,
        60 * x - 180 * x**2 + 120 * x**3,
        60 - 360 * x + 360 * x**2,
    )


@pytest.fixture
def test_law(monkeypatch):
    """A cam law registered for this test only (the registry is restored afterwards)."""
    monkeypatch.setattr(laws, "_REGISTRY", dict(laws._REGISTRY))
    register_law(MotionLaw("test-345", "3-4-5 polynomial (test copy)", _poly_345, True))
    return "test-345"


def test_one_registration_puts_a_cam_law_in_all_and_in_studies(test_law):
    assert test_law in cam_ids() and test_law not in extra_cam_ids() and test_law in known_cam_ids()
    assert test_law in RunConfig().cams
    assert "simple-harmonic" in extra_cam_ids()  # a law with a dwell acceleration jump: by name only
    spec = parse_study({"variables": {"rpm": [150.0, 180.0]}, "fixed": {"cam": test_law}})
    assert spec.fixed["cam"] == test_law


def test_a_registered_cam_law_runs_through_the_command_line(test_law, tmp_path):
    out, cache = tmp_path / "out", tmp_path / "cache"
    assert (
        pipeline.main(
            [
                *COARSE,
                "--materials",
                "al6061-t6",
                "--cams",
                f"{test_law},poly-345",
                "--out",
                str(out),
                "--cache-dir",
                str(cache),
            ]
        )
        == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["cams"]) == [test_law, "poly-345"]
    ours = summary["materials"]["al6061-t6"]["cams"][test_law]["stations"]
    built_in = summary["materials"]["al6061-t6"]["cams"]["poly-345"]["stations"]
    # the same law written twice: the same chain response to rounding
    for station, metrics in built_in.items():
        for key, value in metrics.items():
            assert ours[station][key] == pytest.approx(value, rel=1e-9, abs=1e-15), (station, key)


def test_the_registries_name_what_the_stages_accept():
    from dynamics.response.metrics import station_links
    from dynamics.solvers import METHODS

    assert registries.station_names() == tuple(station_links(12))
    assert set(registries.solver_methods()) == set(METHODS)
    assert RunConfig().focus_station == registries.DEFAULT_STATION in registries.station_names()
