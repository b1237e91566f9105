"""The linear machine's search that chooses the model (machine_scene._choice_substeps): under the
default step it runs at SEARCH_SAFETY of the stability limit at every length, and what the choice
takes from it (the linear machine's minimum tension over its steady cycle) is the default step's to
well within CHOICE_TOL; a run given its step (the step control, a converged reference) searches at it."""

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.machine_scene import (
    CHOICE_TOL,
    SEARCH_SAFETY,
    SearchSettings,
    _choice_substeps,
    linear_machine,
    start_state,
)
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.solvers import machine_verlet as mv

PITCH_M = 0.1125
RPM = 180.0


def _default_linear_machine():
    """The default run's linear machine (85 links, the default wheels, aluminium's k and mass)."""
    from benchmarks.defaults import DEFAULT_RUN, MATERIALS
    from dynamics.models.chain import ChainModel
    from stages.machine import machine_layout

    k, mass = MATERIALS["al6061-t6"]
    chain = ChainModel(DEFAULT_RUN.links, mass, k, friction_coefficient=DEFAULT_RUN.friction)
    layout = machine_layout(DEFAULT_RUN, PITCH_M)
    return linear_machine(ClearanceMachine.of(chain, layout, None, DEFAULT_RUN.pin_clearance_m))


def test_the_default_steps_choice_search_is_at_the_search_safety_and_a_given_step_at_its_own():
    linear = _default_linear_machine()
    h_out = 1.0 / (4 * 6 * RPM)
    default = SearchSettings.of(linear)
    window_sub = mv.substeps_for(linear, h_out, default.safety, default.predictor)
    coarse = mv.substeps_for(linear, h_out, SEARCH_SAFETY["global"], default.predictor)
    assert coarse < window_sub
    assert _choice_substeps(linear, h_out, window_sub, default) == coarse
    given = SearchSettings.of(linear, safety=default.safety)
    assert not given.default_step
    assert _choice_substeps(linear, h_out, window_sub, given) == window_sub


def test_the_coarse_choice_search_gives_the_default_steps_minimum_tension_within_choice_tol():
    """Measured 9e-8 of itself on the default machine with the modified sine (over the default run's
    five cams and two materials at most 2.0e-5); the choice needs it to CHOICE_TOL."""
    linear = _default_linear_machine()
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=RPM)
    h_out = 1.0 / (4 * 6 * RPM)
    per_cycle = int(round(cam.period_s / h_out))
    search = SearchSettings.of(linear, tol=CHOICE_TOL)
    rest = (np.zeros(linear.n_state), np.zeros(linear.n_state))
    window_sub = mv.substeps_for(linear, h_out, search.safety, search.predictor)
    tensions = {}
    for sub in (window_sub, _choice_substeps(linear, h_out, window_sub, search)):
        _, ss, last = start_state(linear, cam, h_out, per_cycle, sub, rest, search)
        assert ss.found
        tensions[sub] = last.min_tension_N
    fine, coarse = tensions.values()
    assert fine < 0.0 and coarse < 0.0  # the clearance machine runs: its choice is the same
    assert coarse == pytest.approx(fine, rel=CHOICE_TOL / 10)
