"""The chain stage's seams: the reported natural frequencies are the one cached eigensolve's that gave
lowest_mode (dynamics.solvers.machine_modes), and a steady state's cycle count is the cycles its search
actually stepped, the step control's levels summed, on both drives (dynamics.scene.SteadyState.cycles)."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.machine_scene import machine_lowest_mode, machine_model, simulate_machine_to_accuracy
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain
from dynamics.models.machine import MachineOnWheels
from dynamics.options import DENSE_LINK_LIMIT
from dynamics.scene import DEFAULT_TOL, simulate_chain
from dynamics.solvers import cache, machine_modes
from dynamics.solvers import clearance_verlet as verlet
from dynamics.solvers import machine_verlet as mv
from geometry.dimensions import LinkDimensions
from settings import RunConfig
from stages import chain as chain_stage
from stages.fea import MaterialStiffness
from stages.machine import scene_machine

PITCH_M = LinkDimensions().pitch_m
K_AL, M_AL = 9.325e7, 2.03  # the default aluminium link's FEA k (N/m) and lumped mass (kg)
RPM = 180.0


def _count_solves(monkeypatch) -> list[int]:
    """The counts of every machine eigensolve from here on (the solver cache emptied first)."""
    solves: list[int] = []
    solve = MachineOnWheels.lowest_natural_frequencies_Hz

    def counted(self, count):
        solves.append(count)
        return solve(self, count)

    monkeypatch.setattr(MachineOnWheels, "lowest_natural_frequencies_Hz", counted)
    cache.clear()
    return solves


def test_the_stage_reports_lowest_modes_frequency_from_its_one_eigensolve(monkeypatch):
    """The default run's scene (85 links on the wheels, one cam law): the reported f1 is the scenario's
    lowest_mode frequency to the bit, the reported modes are the first REPORTED_MODES of the modes the
    nearest resonance was picked from, and the stage solved the machine's modes once."""
    cfg = RunConfig(cams=("modified-sine",))
    stiffness = MaterialStiffness("al", K_AL, 1e-3, M_AL - cfg.hardware_mass_kg - cfg.nest_mass_kg, 1e-4, PITCH_M, 0.01)
    solves = _count_solves(monkeypatch)
    chains, scenarios = chain_stage.run_dynamics(cfg, {"al": stiffness}, lambda line: None)
    reported = chains["al"].natural_frequencies_Hz
    contact = scenarios["al", "modified-sine"].contact
    assert contact.model == "clearance"
    assert solves == [machine_modes.SOLVED_MODES]
    assert reported.size == machine_modes.REPORTED_MODES
    assert reported[0] == contact.lowest_mode.frequency_Hz
    modes = machine_modes.lowest_frequencies_Hz(
        scene_machine(chain_stage.chain_scene(cfg, PITCH_M), chains["al"].model)
    )
    assert np.array_equal(reported, modes[: reported.size]) and contact.nearest_resonance.searched_up_to_Hz == modes[-1]
    assert solves == [machine_modes.SOLVED_MODES]


def test_a_long_machines_reported_modes_are_the_shift_invert_solve_of_lowest_mode(monkeypatch):
    """Above DENSE_LINK_LIMIT links (the shift-invert solve): natural_frequencies_Hz after lowest_mode
    solves nothing more and its f1 is lowest_mode's to the bit."""
    cfg = RunConfig()
    chain = ChainModel(DENSE_LINK_LIMIT + 50, M_AL, K_AL, damping_ratio=0.13)
    scene = chain_stage.chain_scene(cfg, PITCH_M)
    solves = _count_solves(monkeypatch)
    lowest = machine_lowest_mode(machine_model(scene, chain), 1 / 12)
    reported = chain_stage.natural_frequencies_Hz(scene, chain)
    assert solves == [machine_modes.SOLVED_MODES]
    assert reported.size == machine_modes.REPORTED_MODES and reported[0] == lowest.frequency_Hz
    with pytest.raises(ValueError, match="SOLVED_MODES"):
        machine_modes.lowest_frequencies_Hz(scene_machine(scene, chain), machine_modes.SOLVED_MODES + 1)


def _cycles_counted(monkeypatch, module, name, is_search_cycle) -> list[int]:
    """A list that grows by one for each call of module.name that `is_search_cycle(args, kwargs)` says
    steps one cycle of a steady state's search."""
    calls: list[int] = []
    original = getattr(module, name)

    def counted(*args, **kwargs):
        if is_search_cycle(args, kwargs):
            calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)
    return calls


def test_the_link_drives_step_control_counts_every_levels_search_cycles(monkeypatch):
    """simulate_chain(accuracy=) on 15 links with 1 mm free play at 300 rpm: SteadyState.cycles is the
    number of one-period integrations of all its levels' searches (counted at the compiled step's
    entry: a call stepping exactly one cam period), over at least two levels, and its statement says it."""
    rpm = 300.0
    cam = CamProgram.indexing("modified-sine", pitch_m=0.1125, rpm=rpm)
    model = ClearanceChain(ChainModel(15, M_AL, 9.0092e7), 1e-3)
    t = np.arange(361) / 2 / (6 * rpm)

    def one_period(args, kwargs):
        zd, h = args[1], args[3]
        return abs((zd.size - 1) * h - cam.period_s) < 1e-9 * cam.period_s

    calls = _cycles_counted(monkeypatch, verlet, "integrate", one_period)
    _, contact = simulate_chain(model, cam, t, accuracy=1e-4)
    first = verlet.substeps_for(model, float(t[1] - t[0]), verlet.default_safety(model, "ab2"), "ab2")
    assert contact.model == "clearance" and contact.steady_state.found
    assert contact.steps_per_output >= 2 * first  # two levels or more
    assert contact.steady_state.cycles == len(calls) > 0
    assert f"after {len(calls)} cam cycles" in contact.steady_state.statement


def test_the_machines_step_control_counts_every_levels_search_cycles(monkeypatch):
    """simulate_machine_to_accuracy on the default wheels (40 links, default free play): SteadyState.cycles
    is the number of index cycles its levels' searches stepped on the clearance machine (each a
    relabelled map without the window's stations), over its two levels or more (the step control always
    halves the step once), as the link drive counts them; the linear machine's cycles that chose the
    model are not counted."""
    chain = ChainModel(40, M_AL, K_AL, damping_ratio=0.13)
    model = machine_model(chain_stage.chain_scene(RunConfig(), PITCH_M), chain)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=RPM)
    t = np.arange(181) / 2 / (6 * RPM)

    def clearance_search(args, kwargs):
        return args[0].clearance_m > 0 and kwargs.get("stations") is None

    calls = _cycles_counted(monkeypatch, mv, "next_index_start", clearance_search)
    _, contact = simulate_machine_to_accuracy(model, cam, t, accuracy=0.3)
    assert contact.model == "clearance" and contact.steady_state.found
    assert contact.steady_state.cycles == len(calls) > 0
    assert f"after {len(calls)} index cycles" in contact.steady_state.statement
    assert contact.steady_state.statement.endswith(f"<= {DEFAULT_TOL:g})")  # the tolerance its levels searched to


def _exact_rayleigh_quotient(topology, shape) -> float:
    """The oracle: y^T K y / y^T M y of `shape` in long double, summed term by term (the spans'
    stretches, the ground springs, the couplings): its rounding is about 1e-19 of each term."""
    y = np.asarray(shape, dtype=np.longdouble)
    b = topology.incidence().tocoo()
    e = np.zeros(b.shape[0], dtype=np.longdouble)
    np.add.at(e, b.row, b.data.astype(np.longdouble) * y[b.col])
    elastic = np.longdouble(topology.span_stiffness_N_per_m) * np.sum(e * e)
    elastic += np.sum(topology.ground_vector().astype(np.longdouble) * y * y)
    for a, c, k in topology.couplings:
        elastic += np.longdouble(k) * (y[a] - y[c]) ** 2
    return elastic / np.sum(np.asarray(topology.masses_kg, dtype=np.longdouble) * y * y)


@pytest.mark.skipif(np.finfo(np.longdouble).eps > 1e-18, reason="the oracle needs an extended long double")
def test_a_long_machines_mode_1_is_the_exact_eigenvalue_to_rounding():
    """Above DENSE_LINK_LIMIT links mode 1 is the Rayleigh quotient of the shift-invert mode shape: within
    1e-14 (about 50 ulp) of the exact eigenvalue in omega^2, the Rayleigh quotient of numpy's dense
    mode-1 shape in long double (its error quadratic in the shape's, far below 1e-18 here). The
    shift-invert eigenvalue itself is 2.8e-12 off on this machine (the factorisation's rounding), so the
    test fails without the refinement; modes 2 to 12 stay the shift-invert solve's (the dense
    eigensolve's to its own rounding, eps x lambda_max / lambda_1)."""
    chain = ChainModel(DENSE_LINK_LIMIT + 50, M_AL, K_AL, damping_ratio=0.13)
    machine = scene_machine(chain_stage.chain_scene(RunConfig(), PITCH_M), chain)
    topo = machine.topology
    r = 1 / np.sqrt(np.asarray(topo.masses_kg, dtype=float))
    lam, shapes = np.linalg.eigh(r[:, None] * topo.stiffness_matrix_sparse().toarray() * r[None, :])
    exact = _exact_rayleigh_quotient(topo, r * shapes[:, 0])
    frequencies = machine.lowest_natural_frequencies_Hz(machine_modes.SOLVED_MODES)
    omega2 = (2 * np.pi * frequencies) ** 2
    assert abs(float(omega2[0] / exact - 1)) < 1e-14
    assert omega2[1:] == pytest.approx(lam[1 : machine_modes.SOLVED_MODES], rel=1e-9)


def _trapezoid_moments(values, nodes, step_s, out_every):
    """The oracle: the trapezoid rule's integrals of 1, y and y^2 per output interval, written out
    (y the values plus the cam's nodes), each interval's steps summed in order."""
    y = values + np.stack(nodes, axis=1)[:, None, :]
    powers = np.stack([np.ones_like(y), y, y * y], axis=-1)
    steps = 0.5 * step_s * (powers[1:] + powers[:-1])
    return steps.reshape(-1, out_every, *steps.shape[1:]).sum(axis=1)


def test_the_step_moments_are_the_trapezoid_rules_to_the_bit():
    """machine_verlet.step_moments (the RMS metrics over every step) is the written-out trapezoid rule to
    the last bit, at several samplings, station counts and scales (the default run's numbers stay)."""
    rng = np.random.default_rng(7)
    for out_every, intervals, stations, scale in (
        (1, 5, 1, 1.0),
        (21, 360, 4, 1e-3),
        (9, 40, 2, 1e2),
        (37, 3, 3, 1e-6),
    ):
        n = out_every * intervals + 1
        values = scale * rng.normal(size=(n, stations, 3))
        nodes = tuple(scale * rng.normal(size=n) for _ in range(3))
        step_s = float(rng.uniform(1e-6, 1e-3))
        got = mv.step_moments(values, nodes, step_s, out_every)
        assert np.array_equal(got, _trapezoid_moments(values, nodes, step_s, out_every))
