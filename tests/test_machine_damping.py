"""The machine on its wheels' global damping in the O(N) form (dynamics.models.machine_damping, issue
#24) against the dense MachineOnWheels.damping_matrix, and a 2,000-link machine stepped with it."""

import numpy as np
import pytest
from scipy.linalg import eigh

from dynamics.cams import CamProgram
from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import Tensioner
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import MachineLayout
from dynamics.models.machine_damping import DEFAULT_MACHINE_DAMPING_TOLERANCE, of_machine
from dynamics.models.wheels import Wheel
from dynamics.options import DEFAULT_DAMPING_RATIO, DEFAULT_PIN_CLEARANCE_M
from dynamics.solvers import machine_verlet as mv

PITCH_M = 0.1125
WHEEL = Wheel(12, PITCH_M, 6, 0.688)
TENSIONER = Tensioner(1e5, 5.0, 100.0)


def _reduced_matrix(machine, factor_precision=None) -> np.ndarray:
    """The O(N) form's C as a matrix: its chain block column by column, the carriage's c_t."""
    red = of_machine(machine, factor_precision=factor_precision)
    c = np.zeros((machine.topology.n_dof,) * 2)
    c[np.ix_(red.dofs, red.dofs)] = np.column_stack([red.times(e) for e in np.eye(red.dofs.size)])
    if machine.tensioner is not None:
        c[-1, -1] = machine.tensioner.damping_N_s_per_m
    return c


@pytest.mark.parametrize("n_links", [85, pytest.param(400, marks=pytest.mark.slow)])
@pytest.mark.parametrize("idler", [True, False])
@pytest.mark.parametrize("factor_precision", ["double", "single"])
def test_the_reduced_form_is_the_dense_modal_damping_to_its_tolerance(n_links, idler, factor_precision):
    """Every mode of (K, M) on the chain's DOFs (carriage held) keeps zeta to the rule's tolerance
    (DEFAULT_MACHINE_DAMPING_TOLERANCE: the rule's relative error is a function of the eigenvalue, the
    same bound for every mode), the modes stay uncoupled to that level, the carriage's c_t is kept
    exactly, and the products agree with the dense C; with the factors in either precision (single:
    what chains above SINGLE_PRECISION_FACTORS_ABOVE_LINKS take)."""
    chain = ChainModel(n_links, 2.03, 9.331e7, damping_ratio=DEFAULT_DAMPING_RATIO)
    layout = MachineLayout("wheels", WHEEL, WHEEL if idler else None, None if idler else 2e6, True)
    machine = layout.machine(chain, TENSIONER)
    dense, reduced = machine.damping_matrix(), _reduced_matrix(machine, factor_precision)
    assert reduced[-1, -1] == dense[-1, -1] == TENSIONER.damping_N_s_per_m
    dofs = of_machine(machine).dofs
    _assert_keeps_zeta(machine, dense, reduced, dofs)


@pytest.mark.parametrize("n_links", [85, pytest.param(400, marks=pytest.mark.slow)])
@pytest.mark.parametrize(
    "idler, drive", [(True, None), (True, np.inf), (False, 2e6)], ids=["two-wheels", "held-sprocket", "no-idler"]
)
def test_the_reduced_form_carries_the_tooth_models_wheels(n_links, idler, drive):
    """The tooth model (each seated link held to its wheel by k_t, each free wheel a DOF of its own)
    borders the links' cyclic tridiagonal S with the wheels' rows: every mode of (K, M) on the links
    and wheels (carriage held) keeps zeta to the rule's tolerance as in the rigid case, the modes stay
    uncoupled to that level, and the products agree with the dense C, with two free wheels, one (the
    sprocket held to the cam: its seated links grounded through k_t) and without the idler wheel.
    Before the border the wheels were left out and the lowest mode was damped at 1.65 instead of 0.13."""
    chain = ChainModel(n_links, 2.03, 9.331e7, damping_ratio=DEFAULT_DAMPING_RATIO)
    wheel = Wheel(12, PITCH_M, 6, 0.688, 0.25)
    layout = MachineLayout("wheels", wheel, wheel if idler else None, drive, True, 9.5e8)
    machine = layout.machine(chain, TENSIONER)
    red = of_machine(machine)
    assert red.border.shape[0] == len(machine.topology.wheel_dofs) == (1 if drive == np.inf or not idler else 2)
    dense, reduced = machine.damping_matrix(), _reduced_matrix(machine)
    dofs = red.dofs
    assert set(dofs.tolist()) == set(np.flatnonzero(machine.topology.moves_with_cam()).tolist())
    _assert_keeps_zeta(machine, dense, reduced, dofs)


def test_the_tooth_models_rayleigh_damping_is_exact_on_the_wheels():
    """Rayleigh damping (no nodes) on the tooth model: alpha M + beta K on the links and the wheels, the
    border's rows included, to round-off."""
    chain = ChainModel(30, 2.03, 9.331e7, rayleigh_coefficients=(3.0, 2e-5))
    wheel = Wheel(12, PITCH_M, 6, 0.688, 0.25)
    machine = MachineLayout("wheels", wheel, wheel, None, True, 9.5e8).machine(chain, TENSIONER)
    dense, reduced = machine.damping_matrix(), _reduced_matrix(machine)
    np.testing.assert_allclose(reduced, dense, rtol=0, atol=1e-12 * np.max(np.abs(dense)))


@pytest.mark.slow
def test_a_2000_link_machine_steps_on_the_reduced_damping():
    """No refusal above 400 links: the clearance machine of 2,000 links (tensioned idler wheel,
    polygonal feed) takes the O(N) form (no dense C, the sparse incidence) and steps 200 steps of an
    index cycle from a disturbed state, finite, the damping's dissipation positive."""
    chain = ChainModel(2000, 2.03, 9.331e7, damping_ratio=DEFAULT_DAMPING_RATIO, friction_coefficient=0.1)
    model = ClearanceMachine.of(
        chain, MachineLayout("wheels", WHEEL, WHEEL, None, True), TENSIONER, DEFAULT_PIN_CLEARANCE_M
    )
    assert model.reduced_damping and model.arrays.cmat.size < 100
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)
    h = mv.stable_step_s(model, 0.25, "euler")
    zr, zd, zdd = mv.cycle_nodes(cam, h, 200)
    n = model.arrays.dof_float.shape[0]
    rng = np.random.default_rng(2)
    run = mv.integrate(
        model,
        zr,
        zd,
        zdd,
        h,
        1e-5 * rng.standard_normal(n),
        1e-3 * rng.standard_normal(n),
        out_every=200,
        track_energy=True,
    )
    assert np.all(np.isfinite(run.q)) and run.dissipated_damping_J > 0.0


@pytest.mark.parametrize("kappa", [1e2, 4e5, 4e7, 1e9])
@pytest.mark.parametrize("tolerance", [1e-4, 1e-5, 1e-7])
def test_zolotarevs_rule_is_sqrt_to_its_tolerance_with_fewer_nodes(kappa, tolerance):
    """reduced_damping.zolotarev_nodes_for: a + b x + x sum c_j / (x + tau_j) is sqrt(x) to `tolerance`
    relative everywhere in [x_min, x_max] (checked on 10x the rule's own check points; kappa 1e2 is a
    short chain, 4e5 and 4e7 are 1,000 and 10,000 links), with fewer nodes than the trapezoidal rule
    (reduced_damping.nodes_for) for the same tolerance, and positive poles."""
    from dynamics.models.reduced_damping import nodes_for, zolotarev_nodes_for

    x_min = 7.3
    taus, weights, a, b = zolotarev_nodes_for(tolerance, x_min, kappa * x_min)
    x = np.geomspace(x_min, kappa * x_min, 200_000)
    fitted = a + b * x + x * np.sum(weights[None, :] / (x[:, None] + taus[None, :]), axis=1)
    assert np.max(np.abs(fitted / np.sqrt(x) - 1.0)) <= tolerance
    assert np.all(taus > 0.0)
    assert taus.size < nodes_for(tolerance, x_min, kappa * x_min)[0].size


def test_zolotarevs_rule_leaves_tight_tolerances_to_the_trapezoidal_rule():
    """Below the fit's round-off (FIT_TOLERANCE_FLOOR) the rule is the trapezoidal one, exactly."""
    from dynamics.models.reduced_damping import FIT_TOLERANCE_FLOOR, nodes_for, zolotarev_nodes_for

    tight = FIT_TOLERANCE_FLOOR / 10
    for got, want in zip(zolotarev_nodes_for(tight, 2.0, 2e6), nodes_for(tight, 2.0, 2e6)):
        np.testing.assert_array_equal(got, want)


def test_long_chains_take_single_precision_factors_with_the_same_products():
    """Above SINGLE_PRECISION_FACTORS_ABOVE_LINKS links the factors are stored in single precision
    (the recurrences in double): the products agree with the double factors' to well inside the
    rule's tolerance; up to it the factors stay in double (the dense form's check runs there)."""
    from dynamics.models.machine_damping import SINGLE_PRECISION_FACTORS_ABOVE_LINKS

    def machine(n_links):
        chain = ChainModel(n_links, 2.03, 9.331e7, damping_ratio=DEFAULT_DAMPING_RATIO)
        return MachineLayout("wheels", WHEEL, WHEEL, None, True).machine(chain, TENSIONER)

    assert of_machine(machine(SINGLE_PRECISION_FACTORS_ABOVE_LINKS)).factors.dtype == np.float64
    long_machine = machine(SINGLE_PRECISION_FACTORS_ABOVE_LINKS + 1)
    single, double = of_machine(long_machine), of_machine(long_machine, factor_precision="double")
    assert single.factors.dtype == np.float32
    v = np.random.default_rng(5).standard_normal(single.dofs.size)
    want = double.times(v)
    tolerance = DEFAULT_MACHINE_DAMPING_TOLERANCE
    np.testing.assert_allclose(single.times(v), want, rtol=0, atol=0.1 * tolerance * np.max(np.abs(want)))
    with pytest.raises(DynamicsError, match="factor_precision"):
        of_machine(long_machine, factor_precision="half")


@pytest.mark.slow
def test_a_10000_link_machine_steps_the_same_on_single_precision_factors(monkeypatch):
    """The 10,000-link machine (tensioned idler wheel, polygonal feed) takes single-precision factors
    by default; 400 steps of an index cycle from a disturbed state end where the same steps on the
    double factors end, to the damping's tolerance of the largest |q| and |q'| (measured 2.4e-6 and
    4.2e-6; the rule's own error, 1e-5 against 1e-7, moves them by 2.4e-7 and 7.3e-7). Without free
    play and friction: with them an impact or a stick-slip switch a step earlier or later amplifies
    any difference (the rule's own error moves v by 2.6e-6 there, the rounding by 5e-4 after 400
    steps, 1.6e-4 after a cycle); their effect on the station metrics is bench_long_wheels' check."""
    from dynamics.models import machine_damping

    chain = ChainModel(10_000, 2.03, 9.331e7, damping_ratio=DEFAULT_DAMPING_RATIO)
    layout = MachineLayout("wheels", WHEEL, WHEEL, None, True)
    single = ClearanceMachine.of(chain, layout, TENSIONER, 0.0)
    assert single.arrays.reduced[3].dtype == np.float32
    monkeypatch.setattr(machine_damping, "SINGLE_PRECISION_FACTORS_ABOVE_LINKS", 20_000)
    double = ClearanceMachine.of(chain, layout, TENSIONER, 0.0)
    assert double.arrays.reduced[3].dtype == np.float64
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)
    h = mv.stable_step_s(single, 0.9, "ab2")
    zr, zd, zdd = mv.cycle_nodes(cam, h, 400)
    rng = np.random.default_rng(2)
    n = single.arrays.dof_float.shape[0]
    q0, v0 = 1e-5 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n)
    runs = [mv.integrate(m, zr, zd, zdd, h, q0, v0, out_every=400, predictor="ab2") for m in (single, double)]
    tolerance = DEFAULT_MACHINE_DAMPING_TOLERANCE
    for got, want in ((runs[0].q[-1], runs[1].q[-1]), (runs[0].v[-1], runs[1].v[-1])):
        np.testing.assert_allclose(got, want, rtol=0, atol=tolerance * np.max(np.abs(want)))


def _assert_keeps_zeta(machine, dense, reduced, dofs):
    """Every mode of (K, M) on `dofs` damped at DEFAULT_DAMPING_RATIO by `reduced` to the rule's
    tolerance, the modes uncoupled to that level, and reduced's products those of the dense C."""
    k, m = machine.stiffness_matrix()[np.ix_(dofs, dofs)], machine.mass_matrix()[np.ix_(dofs, dofs)]
    lam, phi = eigh(k, m)
    modal = phi.T @ reduced[np.ix_(dofs, dofs)] @ phi
    ratios = np.diag(modal) / (2.0 * np.sqrt(lam))
    tolerance = DEFAULT_MACHINE_DAMPING_TOLERANCE
    np.testing.assert_allclose(ratios, DEFAULT_DAMPING_RATIO, rtol=tolerance)
    off = modal - np.diag(np.diag(modal))
    assert np.max(np.abs(off)) < tolerance * np.max(np.abs(np.diag(modal)))
    v = np.random.default_rng(3).standard_normal(dense.shape[0])
    np.testing.assert_allclose(reduced @ v, dense @ v, rtol=0, atol=tolerance * np.max(np.abs(dense @ v)))
