import math

import numpy as np
import pytest

from dynamics.errors import DynamicsError
from dynamics.response.metrics import (
    RANKABLE,
    link_metrics,
    matlab_round,
    rank_cams,
    residual_vibration,
    rms,
    settling_times,
    station_links,
    station_metrics,
    tension_extremes,
)


def test_matlab_round_is_half_away_from_zero():
    assert matlab_round([0.5, 1.5, 2.5, -0.5, -2.5, 63.75, 42.5]).tolist() == [1, 2, 3, -1, -3, 64, 43]


def test_station_links():
    assert station_links(85) == {"drive-end": 1, "tight-side": 64, "idler-end": 43, "slack-side": 21}
    # N = 10: 7.5 -> 8 and 2.5 -> 3 (Python's round would give 8 and 2).
    assert station_links(10) == {"drive-end": 1, "tight-side": 8, "idler-end": 5, "slack-side": 3}
    assert station_links(1) == {"drive-end": 1, "tight-side": 1, "idler-end": 1, "slack-side": 1}
    with pytest.raises(DynamicsError, match="n_links"):
        station_links(0)


def test_rms_of_a_sine_over_whole_periods():
    # Sampling whole periods evenly, the discrete mean of sin^2 is exactly 1/2 (aliasing-free for
    # more than 2 samples per period), so RMS = A / sqrt(2) to rounding.
    t = np.arange(1000) / 1000
    assert rms(3.0 * np.sin(2 * np.pi * 5 * t)) == pytest.approx(3.0 / math.sqrt(2), rel=1e-14)


def _history(n_t=201, n_links=4):
    t = np.linspace(0.0, 1.0, n_t)
    z = t.copy()
    zdot = np.ones_like(t)
    zddot = np.zeros_like(t)
    amp = np.arange(1, n_links + 1) * 1e-3
    x = z[:, None] + amp * np.sin(2 * np.pi * 10 * t)[:, None]
    v = zdot[:, None] + amp * 2 * np.pi * 10 * np.cos(2 * np.pi * 10 * t)[:, None]
    a = -amp * (2 * np.pi * 10) ** 2 * np.sin(2 * np.pi * 10 * t)[:, None]
    dwell = t >= 0.5
    return t, x, v, a, z, zdot, zddot, dwell, amp


def test_link_metrics_on_known_signals():
    t, x, v, a, z, zdot, zddot, dwell, amp = _history()
    m = link_metrics(x, v, a, z, zdot, zddot, dwell)
    # Samples at 200 per second hit the sine's crests (10 Hz, 20 samples per period): the maxima
    # are the amplitudes to rounding.
    assert np.allclose(m.max_deviation_m, amp, rtol=1e-12)
    assert np.allclose(m.residual_vibration_m, amp, rtol=1e-12)
    assert np.allclose(m.max_velocity_deviation_m_s, amp * 2 * np.pi * 10, rtol=1e-12)
    assert np.allclose(m.max_abs_acceleration_m_s2, amp * (2 * np.pi * 10) ** 2, rtol=1e-12)
    assert np.allclose(m.max_acceleration_deviation_m_s2, m.max_abs_acceleration_m_s2)
    assert np.allclose(m.rms_acceleration_m_s2, rms(a))
    st = station_metrics(m)
    assert st["tight-side"].link == 3 and st["tight-side"].max_deviation_m == pytest.approx(amp[2])
    assert st["drive-end"].rms_velocity_m_s == pytest.approx(m.rms_velocity_m_s[0])


def test_residual_vibration_sees_only_the_dwell():
    t = np.linspace(0.0, 1.0, 101)
    x = np.where(t < 0.5, 1.0, 0.01)[:, None]
    assert residual_vibration(x, np.zeros_like(t), t >= 0.5)[0] == pytest.approx(0.01)
    with pytest.raises(DynamicsError, match="dwell"):
        residual_vibration(x, np.zeros_like(t), np.zeros_like(t, dtype=bool))


def test_settling_time_of_a_decaying_exponential():
    # Deviation 1e-3 exp(-(t - t0)/tau) in each of two dwells: it enters a band b at
    # t0 + tau ln(1e-3/b). Linear interpolation of a convex exponential between samples 1 ms
    # apart errs by < dt^2/(8 tau) = 1.25e-5 s here.
    tau, band = 0.01, 1e-5
    t = np.arange(0.0, 0.4, 1e-3)
    dwell = ((t >= 0.1) & (t < 0.2)) | (t >= 0.3)
    start = np.where(t >= 0.3, 0.3, 0.1)
    dev = np.where(dwell, 1e-3 * np.exp(-(t - start) / tau), 5e-3)
    x = np.stack([dev, 0.1 * dev, 1e-9 * np.ones_like(t)], axis=1)
    s = settling_times(t, x, np.zeros_like(t), dwell, band)
    assert np.allclose(s.dwell_start_s, [0.1, 0.3])
    exact = tau * math.log(1e-3 / band)
    assert np.allclose(s.settling_time_s[:, 0], exact, atol=1.3e-5)
    assert np.allclose(s.settling_time_s[:, 1], tau * math.log(1e-4 / band), atol=1.3e-5)
    assert np.all(s.settling_time_s[:, 2] == 0.0)  # inside the band from the start
    never = settling_times(t, x, np.zeros_like(t), dwell, 1e-12)
    assert np.all(np.isnan(never.settling_time_s[:, :2]))


def test_tension_extremes():
    tension = np.array([[10.0, 5.0, 3.0], [12.0, -2.0, 4.0]])
    e = tension_extremes(tension)
    assert (e.peak_N, e.peak_link, e.min_N, e.min_link, e.slack) == (12.0, 1, -2.0, 2, True)
    assert not tension_extremes(np.abs(tension)).slack


def test_rank_cams():
    t, x, v, a, z, zdot, zddot, dwell, amp = _history()
    by_cam = {
        "big": station_metrics(link_metrics(x, v, a, z, zdot, zddot, dwell)),
        "small": station_metrics(link_metrics(z[:, None] + 0.5 * (x - z[:, None]), v, a, z, zdot, zddot, dwell)),
    }
    r = rank_cams(by_cam, "residual_vibration_m")
    assert r.best == "small" and [c for c, _ in r.order] == ["small", "big"]
    assert r.order[0][1] == pytest.approx(0.5 * amp[2])
    assert "max_abs_acceleration_m_s2" in RANKABLE
    with pytest.raises(DynamicsError, match="metric"):
        rank_cams(by_cam, "loudness")
    with pytest.raises(DynamicsError, match="station"):
        rank_cams(by_cam, "residual_vibration_m", station="middle")


def test_bad_shapes():
    t, x, v, a, z, zdot, zddot, dwell, _ = _history()
    with pytest.raises(DynamicsError, match="v: got shape"):
        link_metrics(x, v[:, :2], a, z, zdot, zddot, dwell)
    with pytest.raises(DynamicsError, match="zdot"):
        link_metrics(x, v, a, z, zdot[:-1], zddot, dwell)
    with pytest.raises(DynamicsError, match="band_m"):
        settling_times(t, x, z, dwell, 0.0)
