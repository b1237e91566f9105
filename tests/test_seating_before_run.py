"""Rigid seating's verdict decided before the run (issue #22; stages.machine.rigid_seating_before_run):
from the layout and the cam alone it is the verdict the rigid run records (but for the snap, which
needs that run), so a scenario that switches to the tooth model (--tooth-stiffness auto) is simulated
once, and the default run (tooth phase 0, rigid seating holds) is simulated as before."""

from dataclasses import replace

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.scene import simulate_scene
from settings import RunConfig
from stages.chain import chain_scene, output_times_s, simulate_scenario
from stages.machine import rigid_seating_before_run, scene_machine, seating_that_runs

P = 0.1125
CHAIN = ChainModel(30, 2.03, 9.3e7, preload_N=RunConfig().preload_N, damping_ratio=RunConfig().damping)


@pytest.mark.parametrize("phase", [0.0, 0.25, 0.75])
@pytest.mark.parametrize("cam_id", ["modified-sine", "cycloidal"])
def test_the_verdict_before_the_run_is_the_rigid_runs(phase, cam_id):
    """The cam's speed and acceleration fractions at the seat change as the rigid run records them
    (dynamics.solvers.machine_verlet.index_cycle locates the instant by the same brentq on the cam's
    law; the bracket's end differs by round-off: 1e-9), the same validity and reason; snap_J None."""
    cfg = RunConfig(links=30, tooth_phase=phase, cams=(cam_id,), tooth_stiffness_N_per_m=np.inf)
    ran = simulate_scenario(cfg, CHAIN, "al", cam_id, P, 2).machine.seating_validity
    t = output_times_s(cfg.rpm, 2)
    cam = CamProgram.indexing(cam_id, pitch_m=P, rpm=cfg.rpm)
    before = rigid_seating_before_run(scene_machine(chain_scene(cfg, P), CHAIN), cam, t)
    assert before.snap_J is None and ran.snap_J is not None
    assert before.cam_speed_fraction == pytest.approx(ran.cam_speed_fraction, rel=1e-9, abs=1e-15)
    assert before.cam_acceleration_fraction == pytest.approx(ran.cam_acceleration_fraction, rel=1e-9, abs=1e-15)
    assert replace(before, cam_speed_fraction=0.0, cam_acceleration_fraction=0.0) == replace(
        ran, snap_J=None, cam_speed_fraction=0.0, cam_acceleration_fraction=0.0
    )
    assert before.valid == (phase == 0.0)


@pytest.mark.parametrize("phase, layouts", [(0.25, [9.5025e8]), (0.0, [np.inf])])
def test_a_scenario_is_simulated_once_with_the_seating_that_runs(monkeypatch, phase, layouts):
    """Tooth phase 0.25 (rigid seating flagged): one simulation, with the teeth; phase 0 (the default,
    rigid seating holds): one, rigid, as before."""
    seen = []

    def counted(scene, *args, **kwargs):
        seen.append(scene.layout.tooth_stiffness_N_per_m)
        return simulate_scene(scene, *args, **kwargs)

    monkeypatch.setattr("dynamics.scene.simulate_scene", counted)
    cfg = RunConfig(links=30, tooth_phase=phase, cams=("modified-sine",), samples_per_degree=2)
    simulate_scenario(cfg, CHAIN, "al", "modified-sine", P, 2)
    assert seen == pytest.approx(layouts, rel=1e-4)


def test_a_set_seating_is_not_decided():
    """--tooth-stiffness rigid or N/m, and the link drive: the scene runs as given, no verdict made."""
    t = output_times_s(180.0, 2)
    cam = CamProgram.indexing("modified-sine", pitch_m=P, rpm=180.0)
    for cfg in (
        RunConfig(links=30, tooth_phase=0.25, tooth_stiffness_N_per_m=np.inf),
        RunConfig(links=30, tooth_phase=0.25, tooth_stiffness_N_per_m=2e9),
        RunConfig(links=30, drive="link"),
    ):
        scene = chain_scene(cfg, P)
        assert seating_that_runs(cfg, scene, CHAIN, cam, t) == (scene, None)
