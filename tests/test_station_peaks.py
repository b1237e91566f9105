"""The station peaks the machine kernel tracks at every step (dynamics.solvers.machine_verlet,
PEAK_METRICS; docs/physics.md, Station peaks) against the two-mass impact's closed form
(tests/test_clearance_impacts.py's scene: two masses m closing at v onto a spring k, m_eff = m / 2,
omega = sqrt(k / m_eff); each mass's acceleration is a half-sine pulse of peak k (v / omega) / m =
v omega / 2), and the peaks' definition on the machine on its wheels (stations as places).

The tolerances are the methods' known errors at omega h: the largest node lies within half a step of
a smooth peak, at most 1 - cos(omega h / 2) ~ (omega h)^2 / 8 below it, and the parabola through the
three nodes around it removes that term, leaving the integrator's own second-order error, of order
(omega h)^2 / 24 (velocity Verlet's phase and amplitude error on an oscillator). A first-order error
would leave these bounds over the 16x range of steps below.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_clearance_impacts import GAP, OMEGA, N, V, _ring, impact_on_the_machine_kernel

from dynamics.cams import CamProgram
from dynamics.machine_scene import _station_values, machine_model, simulate_machine, station_dofs
from dynamics.models.chain import ChainModel
from dynamics.models.layout import MachineLayout
from dynamics.models.wheels import Wheel
from dynamics.scene import Scene, station_values
from dynamics.solvers import machine_verlet as mv
from dynamics.solvers import ring_on_topology

PEAK_A = V * OMEGA / 2  # each mass's peak acceleration in the contact
OUT_EVERY = 4
PITCH_M = 0.1125


def _impact_peaks(steps_per_impact: int, interpolate: bool):
    """(the station peaks of link 2, the largest output sample of its |a|) of the two-mass impact on
    the ring's topology, outputs every OUT_EVERY steps."""
    run, _, _ = impact_on_the_machine_kernel(steps_per_impact, OUT_EVERY, interpolate_peaks=interpolate)
    return run.station_peaks[0], float(np.max(np.abs(run.a[:, 2])))


@pytest.mark.parametrize("steps_per_impact", [10, 20, 40, 80, 160])
def test_the_step_peak_of_an_impact_converges_at_second_order_and_the_sampled_peak_does_not(steps_per_impact):
    omega_h = math.pi / steps_per_impact
    parabola, sampled = _impact_peaks(steps_per_impact, True)
    largest, _ = _impact_peaks(steps_per_impact, False)
    a = mv.PEAK_METRICS.index("max_abs_acceleration_m_s2")
    assert parabola[a] == pytest.approx(PEAK_A, rel=omega_h**2 / 24)
    assert largest[a] == pytest.approx(PEAK_A, rel=omega_h**2 / 8)
    # no cam: the deviation is the acceleration itself
    assert parabola[mv.PEAK_METRICS.index("max_acceleration_deviation_m_s2")] == parabola[a]
    # the largest output sample of every fourth step misses the peak by more than the step's error
    assert abs(sampled / PEAK_A - 1) > omega_h**2 / 8
    if steps_per_impact == 10:  # 2.5 samples per pulse: more than 10 % low
        assert sampled < 0.9 * PEAK_A


def _wheels_scene(span_damping: str) -> Scene:
    wheel = Wheel(12, PITCH_M, 6, 0.688)
    layout = MachineLayout("wheels", wheel, wheel, None, True)
    return Scene(1e-3, span_damping, None, "clearance", False, "exact", layout, None)


@pytest.mark.parametrize("span_damping", ["global", "kelvin-voigt"])
def test_the_largest_node_at_every_output_node_is_the_largest_output_sample(span_damping):
    """With an output at every step and no parabola, the tracked peaks are the largest outputs at the
    stations' DOFs exactly (the deviations relative to the cam, |a| with the cam's acceleration, the
    residual vibration over the dwell's nodes), and the parabola only raises them."""
    model = machine_model(_wheels_scene(span_damping), ChainModel(24, 2.03, 9.331e7))
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=300)
    n_steps = 600
    h = cam.period_s / n_steps
    zr, zd, zdd = mv.cycle_nodes(cam, h, n_steps)
    t = h * np.arange(n_steps + 1)
    dwell = cam.dwell_mask(t)
    flags = mv.IN_WINDOW | np.where(dwell, mv.IN_DWELL, 0)
    dofs = station_dofs(model)
    n = model.n_state
    options = {"out_every": 1, "predictor": "euler", "stations": dofs, "node_flags": flags}
    run = mv.integrate(model, zr, zd, zdd, h, np.zeros(n), np.zeros(n), interpolate_peaks=False, **options)
    q, v, a = (np.where(dofs >= 0, x[:, np.maximum(dofs, 0)], 0.0) for x in (run.q, run.v, run.a))
    expected = np.column_stack(
        [
            np.max(np.abs(a + zdd[:, None]), axis=0),
            np.max(np.abs(q), axis=0),
            np.max(np.abs(v), axis=0),
            np.max(np.abs(a), axis=0),
            np.max(np.abs(q[dwell]), axis=0),
        ]
    )
    np.testing.assert_array_equal(run.station_peaks, expected)
    parabola = mv.integrate(model, zr, zd, zdd, h, np.zeros(n), np.zeros(n), interpolate_peaks=True, **options)
    assert np.all(parabola.station_peaks >= run.station_peaks)


def test_the_machines_station_peaks_are_its_stations_places_every_step_and_above_the_samples():
    """simulate_machine's stations are places (Machine.stations(): the link at each place during the
    index): its per-step peaks, in the response's diagnostics and in the station values the step
    control compares, are at those columns, at or above the largest output sample there, and the
    summary says how they were taken; the rms metrics are the kernel's over every step too."""
    model = machine_model(_wheels_scene("global"), ChainModel(24, 2.03, 9.331e7))
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=300)
    t = np.arange(241) * cam.cycle_s / 120
    r, summary = simulate_machine(model, cam, t, choice="clearance", steady_state=False)
    assert summary.peak_sampling == "every step"
    peaks = r.diagnostics["station_peaks"]
    assert list(peaks) == list(model.machine.stations())
    cols = list(model.machine.stations().values())
    sampled = station_values(cam, t, r.x_m, r.v_m_s, r.a_m_s2, cols).reshape(8, 4)
    stepped = _station_values(model, cam, t, r).reshape(8, 4)
    rms = r.diagnostics["station_rms"]
    assert stepped[:3].tolist() == [[rms[s][name] for s in model.machine.stations()] for name in mv.RMS_METRICS]
    for i, name in zip(range(3, 8), mv.PEAK_METRICS[:4] + (None,)):
        # max |a|, the three deviations and the residual vibration (LinkMetrics' order)
        assert np.all(stepped[i] >= sampled[i] * (1 - 1e-12))
        if name is not None:
            assert stepped[i].tolist() == [peaks[s][name] for s in model.machine.stations()]
    # from rest, 1 mm free play: impacts every index, and their spikes fall between the samples
    assert np.max(stepped[3] / sampled[3]) > 1.01


def test_the_link_drive_on_the_machine_kernel_gets_the_same_step_peaks():
    """ring_on_topology (the link drive on the machine kernel) hands on the kernel's station peaks."""
    model = _ring()
    h = math.pi / OMEGA / 20
    n_steps = 400
    j = np.arange(N)
    y0 = np.where(j <= model.idler_span, -0.5 * GAP * j, 0.5 * GAP * (N - j))
    w0 = np.zeros(N)
    w0[2], w0[3] = 0.5 * V, -0.5 * V
    zero = np.zeros(n_steps + 1)
    ring = ring_on_topology.integrate(model, zero, zero, h, y0, w0, u0=-0.25 * N * GAP, out_every=4, stations=[2, 3])
    machine = mv.integrate(
        ring_on_topology.machine_of(model),
        zero,
        zero,
        zero,
        h,
        np.r_[y0, -0.25 * N * GAP],
        np.r_[w0, 0.0],
        out_every=4,
        stations=[2, 3],
    )
    np.testing.assert_array_equal(ring.station_peaks, machine.station_peaks)
    assert ring.station_peaks[0, 0] == pytest.approx(PEAK_A, rel=(math.pi / 20) ** 2 / 24)
