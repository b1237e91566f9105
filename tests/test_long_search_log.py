"""Measuring a long chain's steady-state searches (issue #24): machine_shooting's per-cycle observer
and benchmarks/bench_long_search.py, on a short chain with the long-chain path forced."""

import numpy as np

from benchmarks import bench_long_search
from dynamics.cams import CamProgram
from dynamics.machine_scene import linear_machine
from dynamics.models import clearance_machine
from dynamics.models.chain import ChainModel
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import MachineLayout
from dynamics.models.wheels import Wheel
from dynamics.solvers import machine_shooting
from dynamics.solvers import machine_verlet as mv

PITCH_M = 0.1125
WHEEL = Wheel(12, PITCH_M, 6, 0.688)
LAYOUT = MachineLayout("wheels", WHEEL, WHEEL, None, True)


def test_the_observer_sees_every_cycle_and_changes_nothing():
    """on_cycle is called once per index cycle stepped with the acceptance test's residual and the
    cycle's end state: the last call's are the search's returned residual and state; the search with
    the observer returns what it returns without (the same floating-point operations)."""
    chain = ChainModel(40, 2.03, 9.331e7, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)
    sub = mv.substeps_for(model, cam.cycle_s / 180, 0.31, "ab2")
    zeros = np.zeros(model.topology.n_dof)
    options = dict(tol=1e-6, max_cycles=40, predictor="ab2")
    args = (model, cam, cam.cycle_s / (180 * sub), 180 * sub, zeros, zeros)
    seen = []
    observed = machine_shooting.relabelled_periodic_state(*args, **options, on_cycle=lambda *a: seen.append(a))
    plain = machine_shooting.relabelled_periodic_state(*args, **options)
    q0, v0, cycles, residual, found, run = observed
    assert found and cycles == plain[2] == len(seen) > 1
    np.testing.assert_array_equal(q0, plain[0])
    np.testing.assert_array_equal(v0, plain[1])
    assert residual == plain[3] == seen[-1][0] <= 1e-6 < seen[0][0]
    np.testing.assert_array_equal(seen[-1][1][0], q0)
    np.testing.assert_array_equal(seen[-1][1][1], v0)
    assert seen[-1][2] is run


def test_the_linear_machine_is_the_one_simulate_machine_decides_with():
    chain = ChainModel(40, 2.03, 9.331e7, friction_coefficient=0.35)
    model = ClearanceMachine.of(chain, LAYOUT, None, 94e-6, "kelvin-voigt")
    linear = linear_machine(model)
    assert linear.clearance_m == 0.0 and linear.span_damping == "global" and linear.tensioner is None
    assert linear.machine is model.machine and linear.friction_chain is model.friction_chain


def test_the_search_benchmark_logs_each_search(monkeypatch):
    """40 links, the long-chain path forced: the linear machine's table has a row per cycle with a
    finite positive bound, and the clearance machine's table a row per start, each found."""
    monkeypatch.setattr(clearance_machine, "DENSE_LINK_LIMIT", 0)
    lines = bench_long_search.measure(40, linear_starts=(0, 1), own_starts=(1,))
    cycles = int(lines[0].split(": ")[2].split(" cycles")[0])
    rows = [line for line in lines if line.startswith("| ") and not line.startswith("| cycle")]
    linear_rows, clearance_rows = rows[:cycles], rows[cycles + 1 :]
    assert [int(r.split(" | ")[0][2:]) for r in linear_rows] == list(range(1, cycles + 1))
    assert all(float(r.split(" | ")[3].split()[0]) > 0 for r in linear_rows)
    names = [r.split(" | ")[0][2:] for r in clearance_rows]
    assert names[0] == "rest" and names[1] == "the linear machine after 1 cycles"
    assert names[2].startswith("the linear machine's steady state") and names[3].startswith("afresh from")
    assert all("NOT found" not in r for r in clearance_rows)
    # the minimum tension's stretch column is (T - P) / k of the printed T, to the printed digits
    chain = linear_machine(bench_long_search.scenario(40)[0]).chain
    for row in linear_rows:
        cells = row.split(" | ")
        tension_N, stretch_m = float(cells[2].split()[0]) * 1e3, float(cells[4].split()[0]) * 1e-3
        printed = 0.05e3 + 5e-3 * chain.stiffness_N_per_m * abs(stretch_m)
        assert abs(chain.preload_N + chain.stiffness_N_per_m * stretch_m - tension_N) <= printed
        span, output = (int(x) for x in cells[5].split(" |")[0].split(", "))
        assert span >= 0 and output >= 0
