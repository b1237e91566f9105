"""The long chain's accuracy settings by the slowest mode's decay per cycle rho (issue #24,
dynamics.machine_scene) and by length (the O(N) damping's tolerance, dynamics.models.machine_damping):
their values at given rho and length, their limits, and that below rho 0.92 (up to 2,000 links on the
default scene) they are the settings the default run had before."""

import numpy as np
import pytest

from dynamics import machine_scene
from dynamics.cams import CamProgram
from dynamics.machine_scene import (
    LONG_SEARCH_SLACK_STATE_ERROR,
    LONG_SEARCH_STATE_ERROR,
    LONG_SEARCH_STATE_ERROR_UP_TO_DECAY,
    LONG_SEARCH_TOL,
    LONG_SEARCH_TOL_FLOOR,
    SETTLE_AT_WINDOW_STEP_ABOVE_DECAY,
    _settle_substeps,
    long_search_tol,
)
from dynamics.models import machine_damping
from dynamics.models.chain import ChainModel
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import MachineLayout
from dynamics.models.machine_damping import (
    DEFAULT_MACHINE_DAMPING_TOLERANCE,
    LONG_MACHINE_DAMPING_ABOVE_LINKS,
    LONG_MACHINE_DAMPING_TOLERANCE,
    default_tolerance,
    of_machine,
)
from dynamics.models.reduction import DENSE_LINK_LIMIT
from dynamics.models.wheels import Wheel
from dynamics.solvers import clearance_verlet as verlet
from dynamics.solvers import machine_shooting
from dynamics.solvers import machine_verlet as mv

PITCH_M = 0.1125
LAYOUT = MachineLayout("wheels", Wheel(12, PITCH_M, 6, 0.688), Wheel(12, PITCH_M, 6, 0.688), None, True)
CAM = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)


@pytest.fixture(scope="module")
def model():
    chain = ChainModel(DENSE_LINK_LIMIT + 20, 2.03, 9.0092e7, damping_ratio=0.13, friction_coefficient=0.35)
    return ClearanceMachine.of(chain, LAYOUT, None, 94e-6)


def _at_decay(monkeypatch, decay: float) -> None:
    """The slowest mode's decay per index cycle every rule reads, set to `decay`."""
    monkeypatch.setattr(machine_shooting, "slowest_decay_per_cycle", lambda model, period_s: decay)


def test_the_rules_thresholds_and_bounds_are_in_range():
    """The thresholds are decays per cycle in (0, 1); the state-error bounds and floors are changes per
    cycle relative to the cycle's largest |q|, |q'| (dimensionless); above the threshold the bound is
    tighter than below it, and the floor below LONG_SEARCH_TOL."""
    for decay in (LONG_SEARCH_STATE_ERROR_UP_TO_DECAY, SETTLE_AT_WINDOW_STEP_ABOVE_DECAY):
        assert 0.0 < decay < 1.0
    assert 0.0 < LONG_SEARCH_SLACK_STATE_ERROR < LONG_SEARCH_STATE_ERROR < 1.0
    assert 0.0 < LONG_SEARCH_TOL_FLOOR < LONG_SEARCH_TOL < 1.0
    assert 0.0 < LONG_MACHINE_DAMPING_TOLERANCE < DEFAULT_MACHINE_DAMPING_TOLERANCE < 1.0


@pytest.mark.parametrize(
    "decay, expected",
    [
        (0.80, 9.0e-4),  # 1,000 links: the state-error bound, as before
        (0.893, 4.815e-4),  # 2,000 links
        (0.99, 1e-4),  # below a threshold moved up: the bound, 4.5e-5, gives way to LONG_SEARCH_TOL
        (0.926, 3.7e-5),  # 3,000 links: the slack side's bound, 5e-4 (1 - rho)
        (0.946, 2.7e-5),  # 4,000 links
        (0.978, 1.1e-5),  # 10,000 links
        (0.9995, 1e-5),  # the Kelvin-Voigt law's nearly undamped mode: the floor
    ],
)
def test_the_search_tolerance_at_given_decays(monkeypatch, model, decay, expected):
    """long_search_tol at given rho: LONG_SEARCH_STATE_ERROR (1 - rho) up to
    LONG_SEARCH_STATE_ERROR_UP_TO_DECAY (never below LONG_SEARCH_TOL), LONG_SEARCH_SLACK_STATE_ERROR
    (1 - rho) above it (never below LONG_SEARCH_TOL_FLOOR); never tighter than the caller's tol."""
    if decay == 0.99:
        # the only row whose rho sits below the threshold by moving it: the floor's branch below
        monkeypatch.setattr(machine_scene, "LONG_SEARCH_STATE_ERROR_UP_TO_DECAY", 0.995)
    _at_decay(monkeypatch, decay)
    np.testing.assert_allclose(long_search_tol(model, CAM, 1e-6), expected, rtol=1e-12)
    assert long_search_tol(model, CAM, 0.5) == 0.5


def test_the_search_tolerance_tightens_with_decay_above_the_threshold(monkeypatch, model):
    """Above the threshold the tolerance falls with 1 - rho down to its floor, and at the threshold it
    steps down from the bound below it (the settle at the window's step needs the tighter one)."""
    decays = np.linspace(LONG_SEARCH_STATE_ERROR_UP_TO_DECAY + 1e-6, 0.9999, 50)
    tols = []
    for decay in decays:
        _at_decay(monkeypatch, decay)
        tols.append(long_search_tol(model, CAM, 1e-6))
    assert np.all(np.diff(tols) <= 0.0)
    assert tols[-1] == LONG_SEARCH_TOL_FLOOR
    _at_decay(monkeypatch, LONG_SEARCH_STATE_ERROR_UP_TO_DECAY)
    assert long_search_tol(model, CAM, 1e-6) > tols[0]


@pytest.mark.parametrize("decay, at_window", [(0.80, False), (0.893, False), (0.92, False), (0.926, True)])
def test_the_settle_is_at_the_window_step_above_the_threshold(monkeypatch, model, decay, at_window):
    """_settle_substeps: the default safety's steps per output sample up to
    SETTLE_AT_WINDOW_STEP_ABOVE_DECAY (as before: 1,000 and 2,000 links), the window's above it."""
    _at_decay(monkeypatch, decay)
    h_out = CAM.cycle_s / 90
    pred = verlet.default_predictor(model)
    safety = verlet.default_safety(model, pred)
    fine = mv.substeps_for(model, h_out, safety / machine_scene.WINDOW_REFINEMENT["global"], pred)
    default = mv.substeps_for(model, h_out, safety, pred)
    assert default < fine
    assert _settle_substeps(model, CAM, h_out, safety, pred, fine) == (fine if at_window else default)


@pytest.mark.parametrize(
    "links, expected",
    [(401, 1e-5), (1000, 1e-5), (2000, 1e-5), (2001, 1e-7), (3000, 1e-7), (10000, 1e-7)],
)
def test_the_damping_tolerance_by_length(links, expected):
    """Each mode's damping ratio to 1e-5 up to LONG_MACHINE_DAMPING_ABOVE_LINKS (2,000) links, as
    before, and to 1e-7 above."""
    assert LONG_MACHINE_DAMPING_ABOVE_LINKS == 2000
    assert default_tolerance(links) == expected


def test_the_damping_form_takes_its_tolerance_by_length(monkeypatch, model):
    """of_machine without a tolerance builds the form at default_tolerance(the machine's links): the
    same nodes as asked for it, and more nodes (the tighter rule) once the machine counts as longer
    than LONG_MACHINE_DAMPING_ABOVE_LINKS."""
    machine = model.machine
    as_before = of_machine(machine, tolerance=DEFAULT_MACHINE_DAMPING_TOLERANCE)
    np.testing.assert_array_equal(of_machine(machine).weights, as_before.weights)
    monkeypatch.setattr(machine_damping, "LONG_MACHINE_DAMPING_ABOVE_LINKS", machine.n_links - 1)
    tight = of_machine(machine, tolerance=LONG_MACHINE_DAMPING_TOLERANCE)
    np.testing.assert_array_equal(of_machine(machine).weights, tight.weights)
    assert tight.weights.size > as_before.weights.size
