"""dynamics.warm_up: the machine's kernels loaded before the dynamics stage leave the stage nothing
to load or compile (every specialisation it calls is there), and change none of its answers."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

# In a fresh process (a test run has loaded the kernels already): the warm-up, then one index cycle's
# first steps of the default run's machine (85 links, the default wheels, aluminium) with its stations,
# counting the kernels' specialisations after each
_AFTER_WARM_UP_THEN_DEFAULT = """
import json
import numpy as np
import pytest
from dynamics import warm_up
from dynamics.solvers import machine_verlet as mv
from dynamics.machine_scene import machine_model, station_dofs
from dynamics.cams import CamProgram
from benchmarks.defaults import DEFAULT_RUN, PITCH_M
from stages.chain import chain_model, chain_scene
from stages.fea import MaterialStiffness

kernels = (mv._run, mv._step_peaks_into)
counts = lambda: [len(k.signatures) for k in kernels]
before = counts()
warm_up.load_machine_kernels()
warm = counts()
fea = MaterialStiffness("al6061-t6", 9.3e7, 0.01, 0.373, 1.4e-4, PITCH_M, 0.0087)
model = machine_model(chain_scene(DEFAULT_RUN, PITCH_M), chain_model(DEFAULT_RUN, fea))
cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=DEFAULT_RUN.rpm)
step = mv.stable_step_s(model, 0.31, "ab2")
zr, zd, zdd = mv.cycle_nodes(cam, step, 20)
rest = np.zeros(model.n_state)
mv.integrate(model, zr, zd, zdd, step, rest, rest, out_every=4, predictor="ab2", stations=station_dofs(model))
print(json.dumps({"before": before, "warm": warm, "default": counts()}))
"""


def test_the_warm_up_loads_every_specialisation_the_default_machine_calls():
    from dynamics.solvers import machine_verlet as mv

    if mv.numba is None:
        pytest.skip("numba not installed: the kernels are plain Python, nothing to load")
    out = subprocess.run(
        [sys.executable, "-c", _AFTER_WARM_UP_THEN_DEFAULT], cwd=ROOT, capture_output=True, text=True, check=True
    )
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    assert counts["before"] == [0, 0]
    assert counts["warm"] == [1, 1]
    assert counts["default"] == [1, 1]  # the default machine's steps loaded nothing more


def test_the_warm_ups_small_machine_steps_from_rest_and_leaves_no_state_behind():
    """Its machine is a chain on two wheels with free play; the kernels' answers afterwards are the
    same to the bit as without it (it touches no cache a run reads: its machine is its own)."""
    from dynamics import warm_up
    from dynamics.solvers import machine_verlet as mv

    model = warm_up.small_machine()
    assert model.machine.drive == "wheels" and model.clearance_m > 0 and not model.reduced_damping
    assert mv.default_damping_precision(model) == "single"

    def cycle_start():
        from dynamics.cams import CamProgram

        cam = CamProgram.indexing("modified-sine", pitch_m=0.1, rpm=180)
        step = mv.stable_step_s(model, 0.31, "ab2")
        zr, zd, zdd = mv.cycle_nodes(cam, step, 200)
        rest = np.zeros(model.n_state)
        return mv.integrate(model, zr, zd, zdd, step, rest, rest, out_every=10, predictor="ab2")

    first = cycle_start()
    warm_up.load_machine_kernels()
    again = cycle_start()
    np.testing.assert_array_equal(again.q, first.q)
    np.testing.assert_array_equal(again.a, first.a)


@pytest.mark.parametrize("drive, loads", [("wheels", True), ("link", False)])
def test_the_run_loads_the_machine_kernels_before_the_stiffness_only_for_a_chain_on_its_wheels(
    monkeypatch, drive, loads
):
    import pipeline
    from dynamics import warm_up
    from reporting import outputs
    from settings import RunConfig

    calls = []
    monkeypatch.setattr(warm_up, "load_machine_kernels", lambda: calls.append("kernels"))
    monkeypatch.setattr(outputs, "prepare_figure_workers", lambda: None)
    pipeline._import_chain_and_outputs(RunConfig(drive=drive))
    assert calls == (["kernels"] if loads else [])
