"""The speed sweep runs the model the run uses (issue #22): on the wheels the linear machine at each
speed (dynamics.response.sweep.machine_rpm_sweep), on the link drive its modal linear chain as before."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from dynamics.errors import DynamicsError
from dynamics.machine_scene import machine_model
from dynamics.response.seating import RIGID, TOOTH_STIFFNESS_MODEL
from dynamics.response.sweep import LINK_DRIVE_MODEL, MACHINE_MODEL, machine_rpm_sweep, rpm_sweep
from reporting.outputs import _sweep_summary, _sweep_table
from reporting.sections import _sweep_seating_paragraph
from settings.run import RunConfig
from stages import chain as chain_stage
from stages.fea import MaterialStiffness
from stages.machine import scene_machine, tooth_model_scene

PITCH_M = 0.1125
FEA = {"al": MaterialStiffness("al", 9.0092e7, 0.01, 1.2, 4.4e-4, PITCH_M, 0.01)}


def _quiet(*_args, **_kwargs):
    return None


def _cfg(**changes) -> RunConfig:
    return replace(RunConfig(), links=24, friction=0.0, cams=("modified-sine",), **changes)


def test_a_point_of_the_wheels_sweep_is_the_pipelines_linear_machine_run_at_that_speed():
    """The sweep at 200 rpm against the dynamics stage's own scenario at 200 rpm with --model linear
    (same grid, same steady state, same step): the station's residual vibration and peak
    acceleration agree to rounding."""
    cfg = _cfg(rpm_sweep="200:200:1")
    sweep = chain_stage.run_rpm_sweeps(cfg, FEA, _quiet)["al"]
    assert sweep.model == MACHINE_MODEL and sweep.seating_model == ((RIGID,),)  # tooth phase 0: rigid holds
    run = replace(cfg, rpm=200.0, model="linear")
    model = chain_stage.chain_model(run, FEA["al"])
    scenario = chain_stage.simulate_scenario(run, model, "al", "modified-sine", PITCH_M, run.samples_per_degree)
    assert scenario.contact.model == "linear" and scenario.contact.steady_state.found
    station = scenario.stations[cfg.focus_station]
    assert sweep.station_link == station.link
    np.testing.assert_allclose(sweep.residual_vibration_m[0, 0], station.residual_vibration_m, rtol=1e-12)
    np.testing.assert_allclose(sweep.peak_acceleration_m_s2[0, 0], station.max_abs_acceleration_m_s2, rtol=1e-12)


@pytest.mark.parametrize("tooth_stiffness, seating", [(None, TOOTH_STIFFNESS_MODEL), (np.inf, RIGID)])
def test_a_sweep_point_runs_the_seating_the_runs_verdict_gives_at_its_speed(tooth_stiffness, seating):
    """Tooth phase 0.25 (the seats change inside the index, rigid seating does not hold): the sweep at
    200 rpm runs the tooth model, as the dynamics stage's scenario at 200 rpm does (--model linear), and
    agrees with it to rounding; its critical speeds are the tooth machine's. --tooth-stiffness rigid
    keeps rigid seating in both."""
    cfg = _cfg(rpm_sweep="200:200:1", tooth_phase=0.25, tooth_stiffness_N_per_m=tooth_stiffness)
    lines = []
    sweep = chain_stage.run_rpm_sweeps(cfg, FEA, lines.append)["al"]
    assert sweep.seating_model == ((seating,),)
    assert (f"{TOOTH_STIFFNESS_MODEL} at 1 of 1 points" in lines[-1]) == (seating == TOOTH_STIFFNESS_MODEL)
    assert _sweep_summary(sweep)["cams"]["modified-sine"]["seating_model"] == [seating]  # summary.json
    assert [row[-1] for row in _sweep_table({"al": sweep}).rows] == [seating]  # rpm_sweep.csv
    assert f"al: {seating} at" in _sweep_seating_paragraph(
        SimpleNamespace(results=SimpleNamespace(sweeps={"al": sweep}))
    )
    run = replace(cfg, rpm=200.0, model="linear")
    model = chain_stage.chain_model(run, FEA["al"])
    scenario = chain_stage.simulate_scenario(run, model, "al", "modified-sine", PITCH_M, run.samples_per_degree)
    assert scenario.machine.seating_validity.model == seating
    station = scenario.stations[cfg.focus_station]
    np.testing.assert_allclose(sweep.residual_vibration_m[0, 0], station.residual_vibration_m, rtol=1e-12)
    np.testing.assert_allclose(sweep.peak_acceleration_m_s2[0, 0], station.max_abs_acceleration_m_s2, rtol=1e-12)
    ran = chain_stage.scene_that_ran(chain_stage.chain_scene(cfg, PITCH_M), [scenario])
    np.testing.assert_array_equal(sweep.natural_frequencies_Hz, scene_machine(ran, model).modes()[0])
    if seating == TOOTH_STIFFNESS_MODEL:  # the two machines' modes differ: the check tells them apart
        rigid = scene_machine(chain_stage.chain_scene(cfg, PITCH_M), model).modes()[0]
        assert abs(sweep.natural_frequencies_Hz[0] / rigid[0] - 1.0) > 1e-3


def test_each_speed_of_a_sweep_runs_and_reports_its_own_seating():
    """A sweep whose seating switches between its two speeds (`model_at`: rigid at 120 rpm, the tooth
    model at 200 rpm, tooth phase 0.25): each point is that seating's own sweep at that speed, and
    summary.json, rpm_sweep.csv's seating_model column and the report's paragraph say which ran where.
    (The pipeline's verdict compares the cam's state at the seat change with its peaks, the same
    fractions at every speed, so a run's sweep switches between cam laws or tooth phases, not speeds.)"""
    cfg = _cfg(tooth_phase=0.25, tooth_stiffness_N_per_m=np.inf)
    scene = chain_stage.chain_scene(cfg, PITCH_M)
    model = chain_stage.chain_model(cfg, FEA["al"])
    rigid, tooth = machine_model(scene, model), machine_model(tooth_model_scene(scene), model)
    sweep = machine_rpm_sweep(
        rigid,
        "modified-sine",
        [120.0, 200.0],
        pitch_m=PITCH_M,
        model_at=lambda cam, t: rigid if cam.rpm < 150 else tooth,
    )
    assert sweep.seating_model == ((RIGID, TOOTH_STIFFNESS_MODEL),)
    for j, (alone, rpm) in enumerate(((rigid, 120.0), (tooth, 200.0))):
        point = machine_rpm_sweep(alone, "modified-sine", [rpm], pitch_m=PITCH_M)
        assert sweep.residual_vibration_m[0, j] == point.residual_vibration_m[0, 0]
        assert sweep.peak_acceleration_m_s2[0, j] == point.peak_acceleration_m_s2[0, 0]
    np.testing.assert_array_equal(sweep.natural_frequencies_Hz, tooth.machine.modes()[0])  # the tooth model's
    table = _sweep_table({"al": sweep})
    assert table.header[-1] == "seating_model"
    assert [(row[2], row[-1]) for row in table.rows] == [(120.0, RIGID), (200.0, TOOTH_STIFFNESS_MODEL)]
    assert table.to_csv().splitlines()[1].endswith(f",{RIGID}")
    assert _sweep_summary(sweep)["cams"]["modified-sine"]["seating_model"] == [RIGID, TOOTH_STIFFNESS_MODEL]
    paragraph = _sweep_seating_paragraph(SimpleNamespace(results=SimpleNamespace(sweeps={"al": sweep})))
    assert (
        f"al: {TOOTH_STIFFNESS_MODEL} at 1 of 2 points (rigid seating does not hold there), {RIGID} at the others"
        in (paragraph)
    )


def test_the_wheels_sweeps_critical_speeds_come_from_the_machines_frequencies_carriage_included():
    cfg = _cfg(tensioner_rate_N_per_m=2e5, tensioner_mass_kg=15.0)
    scene = chain_stage.chain_scene(cfg, PITCH_M)
    model = chain_stage.chain_model(cfg, FEA["al"])
    frequencies, fraction = scene_machine(scene, model).modes()
    reported = chain_stage.natural_frequencies_Hz(scene, model)
    np.testing.assert_allclose(frequencies[: reported.size], reported, rtol=1e-9)
    assert fraction.sum() == pytest.approx(1.0, rel=1e-9)
    sweep = machine_rpm_sweep(machine_model(scene, model), "modified-sine", [60.0, 300.0], pitch_m=PITCH_M)
    assert sweep.critical_speeds
    for c in sweep.critical_speeds:
        assert c.frequency_Hz == pytest.approx(frequencies[c.mode - 1], rel=1e-12)
        assert fraction[c.mode - 1] >= 0.01
        assert c.rpm == pytest.approx(60.0 * c.frequency_Hz / (c.harmonic * sweep.cycles_per_rev), rel=1e-12)


def test_the_link_drives_sweep_is_the_modal_sweep_as_before():
    cfg = _cfg(drive="link", rpm_sweep="60:300:40")
    sweep = chain_stage.run_rpm_sweeps(cfg, FEA, _quiet)["al"]
    model = chain_stage.chain_model(cfg, FEA["al"])
    before = rpm_sweep(model, cfg.cams, np.arange(60.0, 301.0, 40.0), pitch_m=PITCH_M, station=cfg.focus_station)
    assert sweep.model.startswith(LINK_DRIVE_MODEL) and sweep.seating_model is None  # no seats
    assert _sweep_summary(sweep)["cams"]["modified-sine"]["seating_model"] is None
    assert {row[-1] for row in _sweep_table({"al": sweep}).rows} == {""}  # rpm_sweep.csv: no seats, empty
    assert _sweep_seating_paragraph(SimpleNamespace(results=SimpleNamespace(sweeps={"al": sweep}))) == ""
    assert np.array_equal(sweep.residual_vibration_m, before.residual_vibration_m)
    assert np.array_equal(sweep.peak_acceleration_m_s2, before.peak_acceleration_m_s2)
    assert sweep.critical_speeds == before.critical_speeds


def test_the_wheels_sweep_refuses_friction_and_unknown_stations():
    scene = chain_stage.chain_scene(_cfg(), PITCH_M)
    model = chain_stage.chain_model(_cfg(), FEA["al"])
    with pytest.raises(DynamicsError, match="friction"):
        machine_rpm_sweep(machine_model(scene, replace(model, friction_coefficient=0.3)), "modified-sine", [180.0])
    with pytest.raises(DynamicsError, match="station"):
        machine_rpm_sweep(machine_model(scene, model), "modified-sine", [180.0], station="middle")
