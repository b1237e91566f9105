"""The station RMS metrics the machine kernel takes over every step (dynamics.solvers.machine_verlet,
RMS_METRICS, `step_moments`: the RMS over time, the trapezoid rule on the steps' nodes) against closed
forms: the trapezoid rule on a sinusoid (its error term (h^2 / 12) [f'] over the window), and the
two-mass impact (tests/test_clearance_impacts.py's scene: each mass's acceleration a half-sine pulse of
peak v omega / 2 over pi / omega, zero in free flight; its velocity v / 2 before, -v / 2 after, (v / 2)
cos(omega t) in the contact). The impact's every-step RMS is bounded by the integrator's second-order
error, (omega h)^2 / 24 (velocity Verlet's phase and amplitude error on an oscillator, as
tests/test_station_peaks.py bounds the peaks); the output samples' RMS is first order in the sample
interval (where the pulse falls between samples) and fails that bound.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_clearance_impacts import OMEGA, V, impact_on_the_machine_kernel

from dynamics.solvers import machine_verlet as mv

PEAK_A = V * OMEGA / 2
OUT_EVERY = 4


def _sine_moments(omega: float, length_s: float, n_steps: int, offset_m: float = 0.0):
    """step_moments of one station whose displacement, velocity and acceleration (relative to a cam at
    rest at `offset_m`) are sin(omega t) over n_steps steps of the window."""
    t = np.linspace(0.0, length_s, n_steps + 1)
    y = np.sin(omega * t)
    values = np.stack([y, y, y], axis=1)[:, None, :]
    cam = (np.full(t.size, offset_m), np.zeros(t.size), np.zeros(t.size))
    return mv.step_moments(values, cam, length_s / n_steps, 1)


@pytest.mark.parametrize("n_steps", [16, 64, 256])
def test_the_every_step_integral_of_a_sinusoid_has_the_trapezoid_rules_second_order_error(n_steps):
    """Over 1.3 periods (not a whole number, where the trapezoid rule would be exact) the integral of
    sin^2 exceeds L / 2 - sin(2 omega L) / (4 omega) by (h^2 / 12) omega sin(2 omega L), to O(h^4)."""
    omega, length = 2.0 * math.pi, 1.3
    h = length / n_steps
    m = _sine_moments(omega, length, n_steps).sum(axis=0)[0]
    exact = length / 2 - math.sin(2 * omega * length) / (4 * omega)
    leading = (h * h / 12) * omega * math.sin(2 * omega * length)
    assert m[:, 0] == pytest.approx(length, rel=1e-12)
    np.testing.assert_allclose(m[:, 2] - exact, leading, rtol=(omega * h) ** 2)
    rms = mv.station_rms(m[None])[0]
    np.testing.assert_allclose(rms, math.sqrt(exact / length), rtol=(omega * h) ** 2 / 12)


def test_shifting_the_displacements_frame_is_the_moments_of_the_shifted_displacement():
    """shifted_moments (a later piece's lift frame, the cycle's place in the window) is exact."""
    shifted = mv.shifted_moments(_sine_moments(3.0, 1.1, 50), 0.7)
    direct = _sine_moments(3.0, 1.1, 50, offset_m=0.7)
    np.testing.assert_allclose(shifted, direct, rtol=1e-13, atol=1e-15)
    assert mv.shifted_moments(None, 0.7) is None


def _impact(steps_per_impact: int):
    """(the every-step RMS of link 2's RMS_METRICS, its sampled RMS of |a|, the window's length) of
    the two-mass impact on the ring's topology, outputs every OUT_EVERY steps."""
    run, h, n_steps = impact_on_the_machine_kernel(steps_per_impact, OUT_EVERY)
    moments = run.station_moments
    assert moments.shape == (n_steps // OUT_EVERY, 1, len(mv.RMS_METRICS), 3)
    rms = mv.station_rms(moments.sum(axis=0))[0]
    return rms, math.sqrt(float(np.mean(run.a[:, 2] ** 2))), n_steps * h


@pytest.mark.parametrize("steps_per_impact", [10, 20, 40, 80, 160])
def test_the_every_step_rms_of_an_impact_converges_at_second_order_and_the_sampled_rms_does_not(steps_per_impact):
    omega_h = math.pi / steps_per_impact
    rms, sampled, window_s = _impact(steps_per_impact)
    contact_s = math.pi / OMEGA
    exact_a = math.sqrt(PEAK_A**2 * contact_s / 2 / window_s)
    exact_v = 0.5 * V * math.sqrt((window_s - contact_s / 2) / window_s)
    bound = omega_h**2 / 24
    assert rms[2] == pytest.approx(exact_a, rel=bound)
    assert rms[1] == pytest.approx(exact_v, rel=bound)
    if 20 <= steps_per_impact <= 80:  # sampled every OUT_EVERY steps: first order, over the bound
        assert abs(sampled / exact_a - 1) > 4 * bound


def test_the_machines_every_step_rms_is_the_trapezoid_rule_on_its_outputs_at_one_step_per_sample():
    """simulate_machine's window (two index cycles from rest on the 24-link machine of
    tests/test_station_peaks.py, 1 mm free play, impacts every index) with an output sample at every
    step (a sample interval under the stable step): the every-step RMS (the response's "station_rms")
    is the trapezoid rule's RMS over the output samples, but for the seat change at the cycles'
    boundary inside the window, whose output sample is the state after it and the kernel's node the
    state before: that moves the integral of y^2 by at most h max y^2 / 2 (the RMS by half that
    relative to the integral), the bound here; a cycle counted in the wrong lift frame (a pitch off)
    or an interval missed or counted twice moves it by far more."""
    from test_station_peaks import PITCH_M, _wheels_scene

    from dynamics.cams import CamProgram
    from dynamics.machine_scene import WINDOW_REFINEMENT, machine_model, simulate_machine
    from dynamics.models.chain import ChainModel
    from dynamics.solvers import clearance_verlet as verlet

    model = machine_model(_wheels_scene("global"), ChainModel(24, 2.03, 9.331e7))
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=300)
    pred = verlet.default_predictor(model)
    # the window's steps per sample at the pipeline's 120 samples per cycle here (52 at WINDOW_REFINEMENT 3.5, 38 at 2.5)
    per_cycle = 120 * mv.substeps_for(
        model, cam.cycle_s / 120, verlet.default_safety(model, pred) / WINDOW_REFINEMENT["global"], pred
    )
    t = np.arange(2 * per_cycle + 1) * cam.cycle_s / per_cycle
    r, summary = simulate_machine(model, cam, t, choice="clearance", steady_state=False)
    assert summary.steps_per_output == 1 and summary.peak_sampling == "every step"
    h, window_s = t[1] - t[0], t[-1] - t[0]
    cols = list(model.machine.stations().values())
    rms = r.diagnostics["station_rms"]
    for name, motion in zip(mv.RMS_METRICS, (r.x_m, r.v_m_s, r.a_m_s2)):
        y2 = motion[:, cols] ** 2
        integral = np.trapezoid(y2, dx=h, axis=0)
        stepped = np.array([rms[s][name] for s in model.machine.stations()])
        bound = h * np.max(y2, axis=0) / 2 / integral / 2
        assert np.all(np.abs(np.sqrt(integral / window_s) / stepped - 1) <= bound), name
