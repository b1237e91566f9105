"""A long chain's steady-state search says how it goes (dynamics.search_progress): at most a line every
PROGRESS_EVERY_S seconds, none before, each search's index cycles counted on across its steps; heard
from the machine's searches and the single-link drive's without changing them (the same state to the
bit); and in the pipeline, from the scenarios' worker processes, named by the scenario."""

from __future__ import annotations

import re

import numpy as np
import pytest

import dynamics.search_progress as search_progress
from dynamics.cams import CamProgram
from dynamics.machine_scene import machine_model, simulate_machine
from dynamics.search_progress import SearchProgress
from processes import usable_cores
from settings import RunConfig
from stages.chain import SCENARIO_WORKERS_ABOVE_LINKS, chain_model, chain_scene, output_times_s, run_dynamics
from stages.fea import MaterialStiffness
from stages.progress import Progress

LINKS = SCENARIO_WORKERS_ABOVE_LINKS + 20  # the scenarios in workers, the accelerated search
CAMS = ("modified-sine", "cycloidal")
# a link's FEA figures, given (k about the default aluminium link's): the dynamics need no FEA here
FEA = {"al6061-t6": MaterialStiffness("al6061-t6", 9.325e7, 0.005, 0.60, 2.2e-4, 0.1, 0.0127)}


class Clock:
    def __init__(self):
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s


def test_a_line_at_most_every_interval_and_none_before_the_first():
    clock, lines = Clock(), []
    said = SearchProgress(lines.append, every_s=10.0, clock=clock)
    linear = said.observer("of the linear machine", 1e-3)
    for change in (0.5, 0.2, 0.1):  # 3 s a cycle: nothing until 10 s have passed
        clock.now_s += 3.0
        linear(change)
    assert lines == []
    clock.now_s += 3.0
    linear(0.05)  # 12 s
    clock.now_s += 3.0
    linear(0.02)  # 15 s: 3 s after the last line
    assert lines == [
        "steady-state search of the linear machine: 4 index cycles so far, change per cycle 5.0e-02 (accepted at 1.0e-03)"
    ]


def test_a_search_continued_at_another_step_counts_on_and_another_counts_apart():
    clock, lines = Clock(), []
    said = SearchProgress(lines.append, every_s=0.0, clock=clock)
    said.observer("of the linear machine", 1e-3)(0.1)
    coarse = said.observer("with free play", 1e-5)
    coarse(0.2)
    coarse(0.1)
    said.observer("with free play", 1e-5)(2e-6)  # the settle at another step: the same search
    counts = [
        (line.split(":")[0].removeprefix("steady-state search "), int(line.split(": ")[1].split()[0])) for line in lines
    ]
    assert counts == [("of the linear machine", 1), ("with free play", 1), ("with free play", 2), ("with free play", 3)]


def _long_machine_run(progress):
    cfg = RunConfig(links=LINKS, materials=tuple(FEA), samples_per_degree=1)
    fea = FEA["al6061-t6"]
    cam = CamProgram.indexing("modified-sine", pitch_m=fea.pitch_m, rpm=cfg.rpm)
    model = machine_model(chain_scene(cfg, fea.pitch_m), chain_model(cfg, fea))
    return simulate_machine(model, cam, output_times_s(cfg.rpm, 1), progress=progress)


def test_the_machines_searches_are_heard_and_not_changed():
    lines = []
    heard, heard_summary = _long_machine_run(SearchProgress(lines.append, every_s=0.0))
    quiet, quiet_summary = _long_machine_run(None)
    for name in ("x_m", "v_m_s", "a_m_s2", "tension_N"):
        np.testing.assert_array_equal(getattr(heard, name), getattr(quiet, name))
    assert heard_summary.steady_state == quiet_summary.steady_state
    pattern = re.compile(
        r"steady-state search (of the linear machine|with free play): (\d+) index cycles? so far, "
        r"change per cycle (\S+) \(accepted at (\S+)\)"
    )
    said = [pattern.fullmatch(line).groups() for line in lines]
    names = [name for name, *_ in said]
    # the linear machine decides the model first, then the machine with free play is searched
    first_free_play = names.index("with free play")
    assert set(names[:first_free_play]) == {"of the linear machine"} and first_free_play > 0
    assert set(names[first_free_play:]) == {"with free play"}
    for name in set(names):
        counts = [int(n) for who, n, *_ in said if who == name]
        assert counts == list(range(1, len(counts) + 1))
    # every cycle the steady state counts is heard, the last the one that accepts the state: its change
    # within the tolerance it names
    assert names.count("with free play") == quiet_summary.steady_state.cycles
    *_, change, tol = said[-1]
    assert quiet_summary.steady_state.found and float(change) <= float(tol)


@pytest.mark.skipif(usable_cores() < 2, reason="the workers run only where there are two cores")
def test_the_pipelines_scenario_workers_say_it_named_by_the_scenario(monkeypatch, capfd):
    monkeypatch.setattr(search_progress, "PROGRESS_EVERY_S", 0.0)
    cfg = RunConfig(links=LINKS, cams=CAMS, materials=tuple(FEA), samples_per_degree=1)
    run_dynamics(cfg, FEA, Progress(quiet=False))
    err = capfd.readouterr().err
    for cam in CAMS:
        assert re.search(rf"dynamics al6061-t6 / {cam}: steady-state search with free play: 1 index cycle so far", err)


def test_a_quiet_run_says_nothing(monkeypatch, capfd):
    monkeypatch.setattr(search_progress, "PROGRESS_EVERY_S", 0.0)
    cfg = RunConfig(links=LINKS, cams=CAMS[:1], materials=tuple(FEA), samples_per_degree=1)
    run_dynamics(cfg, FEA, Progress(quiet=True))
    assert capfd.readouterr().err == ""


def test_every_period_of_a_defect_corrected_search_is_heard_with_what_it_accepts_by():
    """shooting's searches call on_period once per period stepped (not for the period handed in as
    `first`), with the residual each search accepts by: the coarse search's, the fine map's, and the
    corrected map's (coarse + defect) between them, not the coarse map's plain change (the offset)."""
    from dynamics.solvers import shooting

    target_coarse, target_fine = np.array([1.0, -2.0, 0.5]), np.array([1.1, -2.1, 0.6])

    def contraction(target):
        return lambda x: (target + 0.3 * (x - target), np.ones(3))

    heard = []
    found = shooting.accelerated_fixed_point(
        contraction(target_coarse), np.zeros(3), tol=1e-6, max_periods=30, on_period=heard.append
    )
    assert found.converged and len(heard) == found.periods and heard[-1] <= 1e-6
    heard.clear()
    settled = shooting.defect_corrected_fixed_point(
        contraction(target_coarse), contraction(target_fine), found, tol=1e-8, max_periods=30, on_period=heard.append
    )
    assert settled.search.converged
    assert len(heard) == settled.coarse_periods + settled.fine_periods
    assert heard[0] == pytest.approx(0.7 * 0.1)  # the first fine period at the coarse fixed point: its offset
    assert max(heard[1:]) < heard[0] and heard[-1] <= 1e-8


def test_the_link_drives_search_is_heard_and_not_changed():
    from stages.chain import simulate_scenario

    cfg = RunConfig(links=40, drive="link", materials=tuple(FEA), samples_per_degree=1)
    fea = FEA["al6061-t6"]
    lines = []

    def scenario(progress):
        return simulate_scenario(cfg, chain_model(cfg, fea), "al6061-t6", "modified-sine", fea.pitch_m, 1, progress)

    heard, quiet = scenario(SearchProgress(lines.append, every_s=0.0)), scenario(None)
    np.testing.assert_array_equal(heard.history.a_m_s2, quiet.history.a_m_s2)
    assert heard.contact.steady_state == quiet.contact.steady_state and quiet.contact.steady_state.found
    said = [
        re.fullmatch(
            r"steady-state search with free play: (\d+) index cycles? so far, change per cycle (\S+) \(accepted at (\S+)\)",
            line,
        ).groups()
        for line in lines
    ]
    assert said and [int(n) for n, *_ in said] == list(range(1, len(said) + 1))
    assert len(said) == quiet.contact.steady_state.cycles  # every cam cycle the search stepped
    assert float(said[-1][1]) <= float(said[-1][2])  # the last one accepted the state
