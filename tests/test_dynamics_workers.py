"""A long chain's scenarios in forked worker processes (stages.chain._scenarios_in_workers, above
SCENARIO_WORKERS_ABOVE_LINKS links): the same scenarios as one after the other in one process, to the
bit, in the same order; a progress line as each ends (one after the other too); --serial runs them
here; a worker that dies is one DynamicsError naming --serial."""

from __future__ import annotations

import os
from dataclasses import fields

import numpy as np
import pytest

import stages.chain as chain_stage
from dynamics.errors import DynamicsError
from processes import usable_cores
from settings import RunConfig
from stages.fea import MaterialStiffness

LINKS = chain_stage.SCENARIO_WORKERS_ABOVE_LINKS + 20
CAMS = ("modified-sine", "cycloidal")
# a link's FEA figures, given (k about the default aluminium link's): the dynamics stage needs no FEA here
FEA = {"al6061-t6": MaterialStiffness("al6061-t6", 9.325e7, 0.005, 0.60, 2.2e-4, 0.1, 0.0127)}

needs_two_cores = pytest.mark.skipif(usable_cores() < 2, reason="the workers run only where there are two cores")


class Lines:
    def __init__(self):
        self.lines = []

    def __call__(self, message: str) -> None:
        self.lines.append(message)


def _run(**settings):
    lines = Lines()
    cfg = RunConfig(links=LINKS, cams=CAMS, materials=tuple(FEA), samples_per_degree=1, **settings)
    chains, scenarios = chain_stage.run_dynamics(cfg, FEA, lines)
    return chains, scenarios, lines.lines


def _arrays(scenario) -> list[np.ndarray]:
    h = scenario.history
    return [h.x_m, h.v_m_s, h.a_m_s2, scenario.settling_time_s, np.asarray(scenario.tension.peak_N)]


@needs_two_cores
def test_the_workers_give_the_serial_scenarios_to_the_bit_in_order():
    chains, scenarios, lines = _run()
    serial_chains, serial, serial_lines = _run(scenario_workers=False)
    assert list(scenarios) == list(serial) == [("al6061-t6", cam) for cam in CAMS]
    for key in serial:
        for got, want in zip(_arrays(scenarios[key]), _arrays(serial[key]), strict=True):
            np.testing.assert_array_equal(got, want)
        for field in fields(serial[key].metrics):
            np.testing.assert_array_equal(
                getattr(scenarios[key].metrics, field.name), getattr(serial[key].metrics, field.name)
            )
        assert scenarios[key].contact.steady_state == serial[key].contact.steady_state
    np.testing.assert_array_equal(
        chains["al6061-t6"].natural_frequencies_Hz, serial_chains["al6061-t6"].natural_frequencies_Hz
    )
    # one line as each ends, in the order they end (one after the other: the tasks' order)
    for said in (lines, serial_lines):
        done = [line for line in said if "scenarios)" in line]
        assert [line.rsplit("(", 1)[1] for line in done] == ["1 of 2 scenarios)", "2 of 2 scenarios)"]
        assert sorted(line.split(" / ")[1].split(":")[0] for line in done) == sorted(CAMS)
    assert [line.split(" / ")[1].split(":")[0] for line in serial_lines if "scenarios)" in line] == list(CAMS)


def test_short_chains_and_one_scenario_run_here():
    assert not chain_stage._in_workers(RunConfig(links=chain_stage.SCENARIO_WORKERS_ABOVE_LINKS), 10)
    assert not chain_stage._in_workers(RunConfig(links=LINKS), 1)
    assert not chain_stage._in_workers(RunConfig(links=LINKS, scenario_workers=False), 10)
    assert chain_stage._in_workers(RunConfig(links=LINKS), 2) == (usable_cores() > 1)


def _dies(*args):
    os._exit(3)


@needs_two_cores
def test_a_worker_that_dies_is_one_error_naming_serial(monkeypatch):
    monkeypatch.setattr(chain_stage, "_scenario", _dies)  # forked: the workers see it
    with pytest.raises(DynamicsError, match=r"a scenario's worker process ended early .*--serial"):
        _run()
