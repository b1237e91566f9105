"""The machine's step on request locates the elastic span force's kinks within the step (issue #24,
dynamics.solvers.machine_verlet.integrate(kinks=True), `_kink_terms`): Stormer's truncation over a
kink, checked on one impact with a closed form; no kink, no change. And the default predictor's
stability limit on the wheels, on both sides."""

import math

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.errors import SolverDivergedError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import MachineLayout
from dynamics.models.wheels import Wheel
from dynamics.solvers import machine_verlet as mv

PITCH_M = 0.1125
WHEEL = Wheel(12, PITCH_M, 6, 0.688)
LAYOUT = MachineLayout("wheels", WHEEL, WHEEL, None, True)
# one mass against a one-sided spring (k = m = 1, omega 1): free flight at v0 to the contact at x_c,
# half a period in contact, free flight back; the state at T_END in closed form
X_C, V0, T_END = 0.3, 1.0, 5.0


def _bounce_exact(t):
    t_c = X_C / V0
    if t < t_c + math.pi:
        return (X_C + V0 * math.sin(t - t_c), V0 * math.cos(t - t_c)) if t > t_c else (V0 * t, V0)
    return X_C - V0 * (t - t_c - math.pi), -V0


def _bounce_error(h, kinks):
    """Velocity Verlet on the bounce, with the kink terms applied as machine_verlet does (the shift
    tau_n, the impulse (tau_n + tau_n+1) / h); the state's error at T_END."""
    x, v = 0.0, V0
    a = -max(x - X_C, 0.0)
    for _ in range(int(round(T_END / h))):
        x_old, v_old = x, v
        half = v + 0.5 * h * a
        x += h * half
        a = -max(x - X_C, 0.0)
        v = half + 0.5 * h * a
        if kinks:  # the span's stretch is x - X_C, its force T = max(k e, 0), on the mass -T
            now, nxt = mv._kink_terms(h, x_old - X_C, x - X_C, v_old, v, 1.0, math.inf)
            x -= now
            v -= (now + nxt) / h
            a = -max(x - X_C, 0.0)
    xe, ve = _bounce_exact(T_END)
    return max(abs(x - xe), abs(v - ve))


def test_the_located_kink_leaves_the_bounce_only_the_schemes_smooth_error():
    """Without the kink terms the error after one impact depends on where the contact falls in the
    step (orders 2.4, 1.7, 2.0 over three halvings: the trapezoid's f (1 - f) term); with them it is
    the contact oscillation's own phase error, h^2 pi / 24 (orders 2.00), and smaller at every step."""
    steps = (0.1, 0.05, 0.025, 0.0125)
    plain = np.array([_bounce_error(h, False) for h in steps])
    located = np.array([_bounce_error(h, True) for h in steps])
    orders = np.log2(located[:-1] / located[1:])
    assert np.all(np.abs(orders - 2.0) < 0.02)
    assert np.all(located < 0.6 * plain)
    # the smooth part: Verlet's frequency error (omega h)^2 / 24 over the contact's half period pi
    assert located[-1] == pytest.approx(V0 * math.pi * steps[-1] ** 2 / 24, rel=0.05)


def test_without_free_play_there_is_no_kink_and_the_step_is_unchanged():
    """Free play 0: every span is always in contact, so locating kinks changes nothing, bitwise."""
    model = ClearanceMachine.of(ChainModel(24, 2.03, 9.331e7), LAYOUT, None, 0.0)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=300)
    h = mv.stable_step_s(model, 0.31, "ab2")
    n = int(cam.cycle_s / h)
    zr, zd, zdd = mv.cycle_nodes(cam, cam.cycle_s / n, n)
    zeros = np.zeros(model.topology.n_dof)
    runs = [
        mv.integrate(model, zr, zd, zdd, cam.cycle_s / n, zeros, zeros, out_every=n, predictor="ab2", kinks=k)
        for k in (False, True)
    ]
    assert np.array_equal(runs[0].q, runs[1].q) and np.array_equal(runs[0].v, runs[1].v)


@pytest.mark.parametrize("fraction", [0.99, 1.03, 1.05])
def test_the_default_predictor_on_the_wheels_both_sides_of_its_limit(fraction):
    """ab2 (the global law's default) on the linear machine (free play 0, every span in contact: the
    step's amplification is clearance_verlet.spectral_radius per mode) over an index from a perturbed
    state: at 0.99 of stable_step_s's limit the response stays the cam's (max |q| 3.7 mm measured);
    above it the top mode grows (measured: 1.01 and 1.02 too slowly to show within one index, 10.7 m
    at 1.03, refused as diverged at 1.05)."""
    model = ClearanceMachine.of(ChainModel(24, 2.03, 9.331e7), LAYOUT, None, 0.0)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=300)
    n = int(cam.cycle_s / mv.stable_step_s(model, fraction, "ab2"))
    h = cam.cycle_s / n
    zr, zd, zdd = mv.cycle_nodes(cam, h, n)
    q0 = 1e-6 * np.random.default_rng(1).standard_normal(model.topology.n_dof)
    v0 = np.zeros_like(q0)
    if fraction < 1.0:
        run = mv.integrate(model, zr, zd, zdd, h, q0, v0, predictor="ab2")
        assert np.max(np.abs(run.q)) < 1e-2
    elif fraction < 1.04:
        run = mv.integrate(model, zr, zd, zdd, h, q0, v0, predictor="ab2")
        assert np.max(np.abs(run.q)) > 1.0
    else:
        with pytest.raises(SolverDivergedError, match="reduce the step"):
            mv.integrate(model, zr, zd, zdd, h, q0, v0, predictor="ab2")
