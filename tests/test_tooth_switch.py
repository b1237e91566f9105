"""The run's seating model (issue #22): `--tooth-stiffness` (N/m, rigid or auto) and the switch from rigid
seating to the tooth contact stiffness where rigid seating does not hold for the run (auto, the
default), said in summary.json's seating_model, the report and the progress line. The default run
(tooth phase 0, rigid seating holds) is unchanged: no switch, no new summary keys."""

import json
from dataclasses import replace

import numpy as np
import pytest

import pipeline
from dynamics.models.chain import ChainModel
from dynamics.models.wheels import DEFAULT_TOOTH_STIFFNESS_N_PER_M, line_contact_stiffness_N_per_m
from dynamics.solvers.machine_verlet import Seating
from settings import RunConfig, SettingsError
from stages.chain import chain_scene, simulate_scenario
from stages.machine import machine_cycle, switches_to_tooth_model, tooth_model_scene

P = 0.1125


@pytest.mark.parametrize("text, value", [("rigid", np.inf), ("inf", np.inf), ("auto", None), ("9e8", 9e8)])
def test_the_option_maps_onto_its_one_setting(text, value):
    assert pipeline.parse_cli(["--tooth-stiffness", text]).tooth_stiffness_N_per_m == value
    assert pipeline.parse_cli([]).tooth_stiffness_N_per_m is None  # auto


@pytest.mark.parametrize(
    "argv, word",
    [
        (["--tooth-stiffness", "stiff"], "--tooth-stiffness: expected a stiffness in N/m, rigid or auto"),
        (["--tooth-stiffness", "-1"], "--tooth-stiffness"),
        (["--tooth-stiffness", "1e9", "--idler-inertia", "0"], "--idler-inertia"),
    ],
)
def test_a_bad_tooth_stiffness_is_one_line_naming_the_option(argv, word):
    with pytest.raises(SettingsError, match=word):
        pipeline.parse_cli(argv)


def test_the_default_k_t_is_the_pins_line_contact_at_the_preload():
    """Palmgren's delta = 3.84e-5 Q^0.9 / l^0.8 (mm, N): dQ/d delta at 2224 N over 30 mm, 9.50e8 N/m;
    the secant Q / delta is 0.9 of it (the law's exponent)."""
    assert DEFAULT_TOOTH_STIFFNESS_N_PER_M == pytest.approx(9.5025e8, rel=1e-4)
    delta_mm = 3.84e-5 * 2224.0**0.9 / 30.0**0.8
    assert 2224.0 / delta_mm * 1e3 == pytest.approx(0.9 * DEFAULT_TOOTH_STIFFNESS_N_PER_M, rel=1e-12)
    assert line_contact_stiffness_N_per_m(2 * 2224.0, 0.030) == pytest.approx(2**0.1 * DEFAULT_TOOTH_STIFFNESS_N_PER_M)


def _flagged() -> object:
    return machine_cycle(Seating((0.07, 0.05), (4e-3, 1e-3), 9.4, 3.0, -300.0), True, 5.0, 600.0).seating_validity


def _holds() -> object:
    return machine_cycle(Seating((0.01, 0.01), (1e-5, 1e-5), 0.3), True, 5.0, 600.0).seating_validity


def test_the_switch_is_auto_only_and_where_rigid_seating_does_not_hold():
    scene = chain_scene(RunConfig(tooth_phase=0.25), P)
    assert switches_to_tooth_model(RunConfig(tooth_phase=0.25), scene, _flagged())
    assert not switches_to_tooth_model(RunConfig(tooth_phase=0.25), scene, _holds())
    assert not switches_to_tooth_model(RunConfig(tooth_phase=0.25, tooth_stiffness_N_per_m=np.inf), scene, _flagged())
    tensioned = RunConfig(tooth_phase=0.25, tensioner_rate_N_per_m=2e5, tensioner_mass_kg=20.0)
    assert switches_to_tooth_model(tensioned, chain_scene(tensioned, P), _flagged())  # the teeth ride the carriage
    long = RunConfig(tooth_phase=0.25, links=401)
    assert switches_to_tooth_model(long, chain_scene(long, P), _flagged())  # at any length (the O(N) damping)
    assert pipeline.parse_cli(["--tooth-stiffness", "1e9", "--links", "401"]).links == 401
    assert tooth_model_scene(scene).layout.tooth_stiffness_N_per_m == DEFAULT_TOOTH_STIFFNESS_N_PER_M
    assert chain_scene(RunConfig(), P).layout.tooth_stiffness_N_per_m == np.inf  # auto starts rigid
    assert chain_scene(RunConfig(), P).layout.rigid_seating and not tooth_model_scene(scene).layout.rigid_seating


def test_rigid_seatings_record_is_as_it_was():
    """The default run's seating_model: the same keys as before the tooth model ran in the pipeline."""
    from reporting.outputs import seating_validity_summary

    keys = set(seating_validity_summary(_holds()))
    assert keys == {
        "model",
        "valid",
        "reason",
        "snap_J",
        "cam_speed_fraction_at_seat_change",
        "cam_acceleration_fraction_at_seat_change",
        "at_rest_threshold",
        "instead",
    }
    from reporting.outputs import _machine_inputs

    assert "tooth_stiffness" not in _machine_inputs(RunConfig())
    assert _machine_inputs(RunConfig(tooth_stiffness_N_per_m=np.inf))["tooth_stiffness"] == "rigid"


def test_a_run_inside_the_index_switches_and_says_so():
    """30 links, tooth phase 0.25 (the seats change with the cam at 0.86 of its peak speed): the
    scenario runs the tooth model with the default k_t, its verdict keeps rigid seating's, and
    summary.json and the report say so; --tooth-stiffness rigid keeps rigid seating and its warning."""
    from reporting.outputs import machine_cycle_summary
    from reporting.sections import _seating_paragraphs

    cfg = RunConfig(links=30, tooth_phase=0.25, cams=("modified-sine",), samples_per_degree=2)
    chain = ChainModel(30, 2.03, 9.3e7, preload_N=cfg.preload_N, damping_ratio=cfg.damping)
    switched = simulate_scenario(cfg, chain, "al", "modified-sine", P, 2).machine
    kept = simulate_scenario(
        replace(cfg, tooth_stiffness_N_per_m=np.inf), chain, "al", "modified-sine", P, 2
    ).machine.seating_validity
    verdict = switched.seating_validity
    assert verdict.valid and verdict.tooth_stiffness_N_per_m == DEFAULT_TOOTH_STIFFNESS_N_PER_M
    # decided before the run (stages.machine.rigid_seating_before_run): rigid seating's verdict but its snap,
    # which only a rigid run would give
    assert verdict.switched_from == replace(kept, snap_J=None) and not kept.valid
    assert switched.seating["sprocket"].impact_energy_J == 0.0  # the tooth takes the link, no plastic impact
    assert abs(verdict.snap_J) < 0.1 * abs(kept.snap_J)
    summary = json.loads(json.dumps(machine_cycle_summary(switched), allow_nan=False))["seating_model"]
    assert summary["model"] == "seating through a tooth contact stiffness" and summary["instead"] is None
    assert summary["switched_from"]["model"] == "rigid seating" and summary["switched_from"]["valid"] is False
    assert summary["switched_from"]["snap_J"] is None
    html = _seating_paragraphs({"materials": {"al": {"cams": {"a": {"machine": {"seating_model": summary}}}}}})
    assert "k_t = 9.5e+08 N/m" in html and "switched to it from rigid seating" in html and "warn" not in html


@pytest.mark.parametrize("phase, switched", [(0.25, True), (0.0, False)])
def test_the_reported_modes_are_the_model_that_ran(phase, switched):
    """The material's natural frequencies (summary.json, the report, the progress line) are those of
    the machine its scenarios ran: the tooth model's where the run switched to it (its frequencies
    differ from rigid seating's: the wheels are bodies of their own, the tooth springs in), rigid
    seating's as before at phase 0."""
    from stages.chain import natural_frequencies_Hz, run_dynamics
    from stages.fea import MaterialStiffness

    cfg = RunConfig(links=24, tooth_phase=phase, cams=("modified-sine",), samples_per_degree=2)
    fea = {"al": MaterialStiffness("al", 9.0092e7, 0.01, 1.2, 4.4e-4, P, 0.01)}
    chains, scenarios = run_dynamics(cfg, fea, lambda *_: None)
    assert (scenarios["al", "modified-sine"].machine.seating_validity.switched_from is not None) == switched
    scene, model = chain_scene(cfg, P), chains["al"].model
    rigid = natural_frequencies_Hz(scene, model)
    teeth = natural_frequencies_Hz(tooth_model_scene(scene), model)
    assert np.max(np.abs(teeth / rigid - 1.0)) > 1e-3
    np.testing.assert_array_equal(chains["al"].natural_frequencies_Hz, teeth if switched else rigid)
