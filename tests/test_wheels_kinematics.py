"""dynamics.models.wheels: pitch radius and the chordal action against an independent planar construction
and the closed form for a steadily turning wheel."""

import numpy as np
import pytest

from dynamics.errors import DynamicsError
from dynamics.models.wheels import Wheel, pitch_radius_m, steel_disc_inertia_kg_m2

P = 0.1125


@pytest.mark.parametrize("z", [6, 12, 17, 40])
def test_the_pitch_radius_makes_each_link_a_chord_of_one_tooth(z):
    r = pitch_radius_m(P, z)
    pins = r * np.exp(2j * np.pi * np.arange(z) / z)
    np.testing.assert_allclose(np.abs(np.diff(pins)), P, rtol=1e-14)


def test_the_default_sprocket_has_the_issues_radius():
    assert pitch_radius_m(P, 12) == pytest.approx(0.2173, abs=5e-5)  # issue #22: R = 217 mm


def _strand_end_by_construction(z: int, angle: np.ndarray) -> np.ndarray:
    """Planar construction: pins on the pitch circle at r e^(i alpha), alpha measured from the
    strand's tangent point (alpha = 0 on the real axis, the strand along the imaginary axis); the
    pulling pin is the one with alpha in [-pi/z, pi/z), its along-strand coordinate the imaginary
    part of its position; each seat change adds one pitch (the strand's pins are p apart)."""
    r = pitch_radius_m(P, z)
    tooth = 2 * np.pi / z
    out = np.empty_like(angle)
    for i, a in enumerate(angle):
        pins = a - np.pi / z - tooth * np.arange(-2 * z, 2 * z)  # pin angles from the tangent point
        j = np.flatnonzero((pins >= -np.pi / z - 1e-15) & (pins < np.pi / z - 1e-15))[0]
        seats = np.round((a - np.pi / z - pins[j]) / tooth)  # teeth passed since the dwell
        out[i] = (r * np.exp(1j * pins[j])).imag + seats * P
    return out - (r * np.exp(-1j * np.pi / z)).imag


@pytest.mark.parametrize("z", [6, 12, 21])
def test_strand_end_equals_the_planar_construction(z):
    wheel = Wheel(z, P, 1)
    angle = np.linspace(-1.3, 2.7, 997) * 2 * np.pi / z * 3
    np.testing.assert_allclose(wheel.strand_end_m(angle), _strand_end_by_construction(z, angle), atol=1e-15)


@pytest.mark.parametrize("z", [6, 12, 21, 60])
def test_steady_turning_gives_the_chordal_speed_law(z):
    """omega constant: speed omega R cos(gamma), between omega R cos(pi/z) and omega R, mean omega R_m;
    position continuous through each seat change."""
    wheel = Wheel(z, P, 1)
    omega = 18.0  # rad/s
    t = np.linspace(0.0, 3 * wheel.tooth_angle_rad / omega, 30001)
    x = wheel.strand_end_m(omega * t)
    v = np.gradient(x, t)
    closed = omega * wheel.pitch_radius_m * wheel.strand_end_speed_ratio(omega * t)
    jumps = np.abs(np.diff(np.floor(omega * t / wheel.tooth_angle_rad)))
    smooth = np.ones_like(t, dtype=bool)
    smooth[np.flatnonzero(jumps) + 1] = smooth[np.flatnonzero(jumps)] = False  # one-sided gradient at a kink
    smooth[[0, -1]] = False
    np.testing.assert_allclose(v[smooth], closed[smooth], rtol=2e-7)  # central difference O(dt^2)
    ratio = closed / (omega * wheel.pitch_radius_m)
    assert ratio.min() == pytest.approx(np.cos(np.pi / z), abs=1e-9)
    assert ratio.max() == pytest.approx(1.0, abs=1e-9)
    assert np.max(np.abs(np.diff(x))) < 1.01 * omega * wheel.pitch_radius_m * (t[1] - t[0])  # no jump
    assert x[-1] == pytest.approx(3 * P, rel=1e-12)  # one pitch per tooth: mean speed omega R_m


def test_the_feed_departure_vanishes_as_z_grows():
    """max |s(a) - R_m a| over a tooth -> pi^2 / (18 sqrt 3) p / z^2 (expansion of R sin(g) - R_m g)."""
    scaled = []
    for z in (50, 100, 200, 400):
        wheel = Wheel(z, P, 1)
        a = np.linspace(0.0, wheel.tooth_angle_rad, 20001)
        dep = np.max(np.abs(wheel.strand_end_m(a) - wheel.feed_radius_m * a))
        np.testing.assert_allclose(
            wheel.feed_departure_m(a), wheel.strand_end_m(a) - wheel.feed_radius_m * a, atol=1e-15
        )
        scaled.append(dep * z**2 / P)
    limit = np.pi**2 / (18 * np.sqrt(3))
    assert abs(scaled[-1] - limit) < 0.25 * abs(scaled[0] - limit) + 1e-12  # O(z^-2) approach
    assert scaled[-1] == pytest.approx(limit, rel=1e-4)


def test_feed_departure_slope_is_its_derivative():
    wheel = Wheel(12, P, 6)
    a = np.linspace(-0.1, 0.6, 50)
    h = 1e-6
    fd = (wheel.feed_departure_m(a + h) - wheel.feed_departure_m(a - h)) / (2 * h)
    np.testing.assert_allclose(wheel.feed_departure_slope(a), fd, atol=1e-10)


def test_steel_disc_inertia():
    assert steel_disc_inertia_kg_m2(0.2, 0.025) == pytest.approx(0.5 * 7850 * np.pi * 0.2**2 * 0.025 * 0.2**2)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(teeth=2, pitch_m=P, wrap_links=1), "teeth"),
        (dict(teeth=12, pitch_m=-1.0, wrap_links=1), "pitch_m"),
        (dict(teeth=12, pitch_m=P, wrap_links=12), "wrap_links"),
        (dict(teeth=12, pitch_m=P, wrap_links=6, tooth_phase=1.0), "tooth_phase"),
    ],
)
def test_bad_wheels_are_refused(kwargs, match):
    with pytest.raises(DynamicsError, match=match):
        Wheel(**kwargs)
