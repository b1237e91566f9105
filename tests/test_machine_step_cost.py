"""The machine's compiled step made cheaper (issue #22, Speed: one 85-link window to 1e-3): the global
law's dense damping product in single precision on the wheels (double for the link drive, which
replicates the ring's kernel, and on request), and one sine per wheel in the polygonal feed. Each
change against the arithmetic it replaces: the product's rounding is 1e-7 of C q', four orders below
the step's 1e-3 (benchmarks/bench_machine.py, docs/performance.md, The clearance chain on wheels)."""

import math

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import DEFAULT_PIN_CLEARANCE_M
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import LINK_DRIVE, MachineLayout
from dynamics.models.wheels import Wheel, pitch_radius_m, steel_disc_inertia_kg_m2
from dynamics.solvers import machine_verlet as mv

PITCH_M = 0.1125


def _wheels(n_links=41):
    wheel = Wheel(12, PITCH_M, 6, steel_disc_inertia_kg_m2(pitch_radius_m(PITCH_M, 12), 0.025))
    chain = ChainModel(n_links=n_links, link_mass_kg=2.03, stiffness_N_per_m=9.0092e7)
    return ClearanceMachine.of(chain, MachineLayout("wheels", wheel, wheel, None, True), None, DEFAULT_PIN_CLEARANCE_M)


def _cycle(model, **options):
    """One index cycle from rest at the default step (ab2 at 0.31 of its limit), 4 samples per degree."""
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)
    h_out = 1.0 / (4 * 6 * 180)
    sub = mv.substeps_for(model, h_out, 0.31, "ab2")
    zr, zd, zdd = mv.cycle_nodes(cam, h_out / sub, 360 * sub)
    zeros = np.zeros(model.topology.n_dof)
    return mv.integrate(model, zr, zd, zdd, h_out / sub, zeros, zeros, out_every=sub, predictor="ab2", **options)


def _apart(new, old) -> float:
    return float(np.max(np.abs(np.asarray(new) - old)) / np.max(np.abs(old)))


def test_the_single_precision_product_is_the_double_to_its_rounding():
    """On the wheels through the impacts of one index cycle from rest: positions within 1e-6 of their
    largest, accelerations and tensions within 1e-4 of theirs, the impact statistics to 1e-5 (measured
    on 41 links: 3.6e-8, 2.0e-6, 2.4e-7, 1.2e-7; 117 impacts); the same number of impacts."""
    model = _wheels()
    assert mv.default_damping_precision(model) == "single"
    single, double = _cycle(model), _cycle(model, damping_precision="double")
    assert single.impacts == double.impacts > 0
    assert 0 < _apart(single.q, double.q) < 1e-6  # it runs the single product (not bit for bit the double)
    assert _apart(single.a, double.a) < 1e-4
    assert _apart(single.tension_N, double.tension_N) < 1e-4
    for name in ("impact_max_speed_m_s", "impact_kinetic_energy_J", "impact_force_spike_N"):
        assert getattr(single, name) == pytest.approx(getattr(double, name), rel=1e-5), name


def test_the_link_drive_keeps_the_double_product_and_a_bad_precision_is_refused():
    chain = ChainModel(n_links=24, link_mass_kg=2.03, stiffness_N_per_m=9.0092e7)
    model = ClearanceMachine.of(chain, LINK_DRIVE, None, DEFAULT_PIN_CLEARANCE_M)
    assert mv.default_damping_precision(model) == "double"
    default, double = _cycle(model), _cycle(model, damping_precision="double")
    assert np.array_equal(default.q, double.q)
    with pytest.raises(DynamicsError, match="damping_precision"):
        _cycle(model, damping_precision="half")


@pytest.mark.parametrize("gamma0", [-math.pi / 12, 0.9, 1.4, -2.0])
def test_one_sine_per_wheel_gives_the_feed_of_both_calls(gamma0):
    """`_wheels_into` (the cosine from the sine within 1 rad of the tangent, its own call beyond)
    against sin and cos of the pin's angle, over angles either side of 1 rad, to 1e-15 m and 1e-14."""
    r, rm = 0.21733331, 0.21485917
    wheels = mv._step_wheels(np.array([[r, rm, gamma0, -1.0]]))
    wd, wsl, wdt = np.zeros(1), np.zeros(1), np.zeros(1)
    for z_rel in np.linspace(0.0, 0.12, 25):
        mv._wheels_into(np.zeros(1), np.zeros(1), z_rel, 1.5, wheels, wd, wsl, wdt)
        ang = z_rel / rm
        slope = (r * math.cos(gamma0 + ang) - rm) / rm
        assert wd[0] == pytest.approx(r * (math.sin(gamma0 + ang) - math.sin(gamma0)) - rm * ang, abs=1e-15)
        assert wsl[0] == pytest.approx(slope, abs=1e-14)
        assert wdt[0] == pytest.approx(1.5 * slope, abs=1e-14)
        four = np.zeros(1), np.zeros(1), np.zeros(1)  # MachineArrays' own four columns: the same feed
        mv._wheels_into(np.zeros(1), np.zeros(1), z_rel, 1.5, wheels[:, :4].copy(), *four)
        assert (four[0][0], four[1][0], four[2][0]) == (wd[0], wsl[0], wdt[0])


def test_the_steps_branch_free_tanh_is_the_librarys_to_the_last_bit_of_one_and_saturates_exactly():
    """`_tanh_branch_free` (the exponential written out so that the friction's loop vectorises) within
    2.3e-16 of the library's tanh (one ulp of 1), exactly +-1 from
    |x| = TANH_IS_ONE on, compiled and as Python."""
    x = np.concatenate(
        [
            np.linspace(-40, 40, 80001),
            np.geomspace(1e-300, 1e-3, 50),
            -np.geomspace(1e-300, 1e-3, 50),
            [0.0, mv.TANH_IS_ONE, np.nextafter(mv.TANH_IS_ONE, 0), 800.0, np.inf, -np.inf],
        ]
    )
    kernels = [mv._tanh_branch_free] + ([mv._tanh_branch_free.py_func] if mv.numba is not None else [])
    for tanh in kernels:
        got = np.array([tanh(float(v)) for v in x])
        assert np.max(np.abs(got - np.tanh(x))) <= 2.3e-16
        saturated = np.abs(x) >= mv.TANH_IS_ONE
        assert np.all(got[saturated] == np.sign(x[saturated]))


@pytest.mark.parametrize("law", ["global", "kelvin-voigt"])
def test_the_steps_friction_is_the_tanh_law_in_and_out_of_saturation(law):
    """The step's friction on a 40-link machine with free play, wheels with tooth springs and friction
    0.1 (`_accel_into`'s accelerations with friction minus those without) against the law
    -F_c w tanh((z' + q') / v_s) / m with the library's tanh, to 1e-14 of the largest acceleration
    (the other forces' rounding in the difference), its power to 1e-14: in a dwell (every link off saturation), in motion (every link on it,
    the sign alone) and between (some of each)."""
    wheel = Wheel(12, PITCH_M, 6, 0.688, 0.25)
    chain = ChainModel(40, 2.03, 9.331e7, damping_ratio=0.13, friction_coefficient=0.1)
    layout = MachineLayout("wheels", wheel, wheel, None, True, 9.5e8)
    model = ClearanceMachine.of(chain, layout, None, DEFAULT_PIN_CLEARANCE_M, span_damping=law)
    arr = model.arrays
    assert arr.par[8] > 0.0 and np.count_nonzero(arr.dof_float[:, 4]) > 20  # tooth springs, friction
    n, ns = arr.dof_float.shape[0], arr.span_int.shape[0]
    dof_float, wheels = np.asfortranarray(arr.dof_float), mv._step_wheels(arr.wheel_float)
    cmat, red = mv.kernel_damping(arr, "single")
    rng = np.random.default_rng(5)
    q, v = 1e-5 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n)
    fc, inv_vs = arr.par[5], arr.par[6]

    def accelerations(par, zd):
        work = mv._accel_work(n, wheels, cmat)
        spans = [np.zeros(ns), np.zeros(ns), np.zeros(ns, dtype=np.bool_), np.zeros(ns)]
        a = np.zeros(n)
        args = (q, v, 0.01, zd, 3.0, arr.span_int, arr.span_float, dof_float, wheels, par, cmat, red)
        mv._accel_into(*args, work, *spans, a)
        return a, work[6][2]

    frictionless = arr.par.copy()
    frictionless[5] = 0.0
    rubbing = arr.dof_float[:, 4] > 0.0
    for zd, off_saturation in ((0.0, "all"), (2.0, "none"), (0.0955, "some")):
        x = (zd + v) * inv_vs
        unsaturated = np.count_nonzero(rubbing & (np.abs(x) < mv.TANH_IS_ONE))
        assert {"all": np.count_nonzero(rubbing), "none": 0}.get(off_saturation, unsaturated) == unsaturated
        assert 0 < unsaturated < np.count_nonzero(rubbing) or off_saturation != "some"
        law = -fc * arr.dof_float[:, 4] * np.tanh(x)
        (with_friction, power), (without, _) = accelerations(arr.par, zd), accelerations(frictionless, zd)
        scale = np.max(np.abs(without))  # the other forces' rounding in the difference
        np.testing.assert_allclose(with_friction - without, law * arr.dof_float[:, 0], rtol=0, atol=1e-14 * scale)
        assert power == pytest.approx(-np.sum(law * (v + arr.dof_float[:, 1] * zd)), rel=1e-14)
