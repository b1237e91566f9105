import numpy as np
import pytest

from dynamics.cams import CamProgram, MotionLaw, Segment, get_law, laws, mqp2012_program
from dynamics.errors import DynamicsError

RPM = 180.0
DEG_S = 1.0 / (6 * RPM)  # seconds per cam degree


def _ramp_svaj(x):
    x = np.asarray(x, dtype=float)
    return x, np.ones_like(x), np.zeros_like(x), np.zeros_like(x)


def _short_svaj(x):
    x = np.asarray(x, dtype=float)
    s, v, a, j = get_law("cycloidal").svaj(x)
    return 0.9 * s, 0.9 * v, 0.9 * a, 0.9 * j


@pytest.fixture
def odd_laws(monkeypatch):
    """Two laws that must not join a dwell, registered for one test only."""
    monkeypatch.setitem(laws._REGISTRY, "test-ramp", MotionLaw("test-ramp", "constant velocity", _ramp_svaj, True))
    monkeypatch.setitem(laws._REGISTRY, "test-short", MotionLaw("test-short", "lift 0.9", _short_svaj, True))


def test_rise_scales_the_law_by_lift_and_duration():
    p = CamProgram.indexing("cycloidal", pitch_m=0.1, index_deg=60.0, dwell_deg=30.0, rpm=RPM)
    T = 60.0 * DEG_S
    x = np.linspace(0.0, 0.95, 11)  # x = 1 belongs to the dwell that follows
    S, V, A, J = get_law("cycloidal").svaj(x)
    s, v, a, j = p.svaj(x * T)
    assert np.allclose(s, 0.1 * S, rtol=0, atol=1e-15)
    assert np.allclose(v, 0.1 * V / T, rtol=1e-13)
    assert np.allclose(a, 0.1 * A / T**2, rtol=1e-13, atol=1e-10)
    assert np.allclose(j, 0.1 * J / T**3, rtol=1e-13)


def test_periodic_indexing_advances_one_pitch_per_period():
    p = CamProgram.indexing("modified-sine")
    assert p.period_s == pytest.approx(90.0 * DEG_S, rel=1e-15)
    assert p.advance_m == pytest.approx(0.1125)
    t = np.linspace(0.0, p.period_s, 97)
    s0, v0, a0, j0 = p.svaj(t)
    for n in (1, 5, -2):
        s, v, a, j = p.svaj(t + n * p.period_s)
        # n periods add n*advance; time shifts by n*period round by a few ulps of t.
        assert np.allclose(s, s0 + n * p.advance_m, rtol=0, atol=1e-12)
        assert np.allclose(v, v0, rtol=0, atol=1e-8)
        assert np.allclose(a, a0, rtol=0, atol=1e-5)


def test_program_velocity_and_acceleration_are_time_derivatives():
    p = mqp2012_program("modified-trapezoid")
    t = np.linspace(0.0005, 0.16, 300)
    joints_s = np.array([0.0, 45.0, 90.0, 135.0]) * DEG_S  # jerk jumps at rise starts and ends
    t = t[np.min(np.abs(t[:, None] - joints_s[None, :]), axis=1) > 1e-5]
    h = 1e-6
    s_p, v_p, _, _ = p.svaj(t + h)
    s_m, v_m, _, _ = p.svaj(t - h)
    _, v, a, _ = p.svaj(t)
    # Second-order central differences: truncation h^2/6 |f'''| (<= 1e-12/6 * 1.5e6 for s -> v,
    # <= 1e-12/6 * 3e7 for v -> a), rounding ~eps |f| / h (1e-11 and 1e-9): bounds 1e-6 and 1e-4.
    assert np.max(np.abs((s_p - s_m) / (2 * h) - v)) < 1e-6
    assert np.max(np.abs((v_p - v_m) / (2 * h) - a)) < 1e-4


def test_mqp2012_program_positions_and_dwells():
    p = mqp2012_program("poly-345")
    deg = np.array([0.0, 45.0, 60.0, 90.0, 135.0, 150.0, 180.0, 400.0])
    s, v, a, _ = p.svaj(deg * DEG_S)
    assert np.allclose(s, [0, 0.1125, 0.1125, 0.1125, 0.225, 0.225, 0.225, 0.225], atol=1e-15)
    assert np.allclose(v[[1, 2, 4, 5, 6, 7]], 0.0, atol=1e-12)
    assert p.period_s is None and p.advance_m is None
    assert p.duration_s == pytest.approx(180.0 * DEG_S)
    mask = p.dwell_mask(np.array([10.0, 50.0, 89.0, 100.0, 140.0, 200.0]) * DEG_S)
    assert mask.tolist() == [False, True, True, False, True, True]
    (a0, a1), (b0, b1) = p.dwell_intervals_s
    assert (a0, a1) == pytest.approx((45 * DEG_S, 90 * DEG_S))
    assert b0 == pytest.approx(135 * DEG_S) and b1 == np.inf


def test_mqp2012_full_cycle_returns_to_start():
    p = mqp2012_program("cycloidal", full_cycle=True)
    assert p.period_s == pytest.approx(360.0 * DEG_S)
    assert p.advance_m == 0.0
    s, v, _, _ = p.svaj(np.array([180.0, 225.0, 270.0, 360.0]) * DEG_S)
    assert np.allclose(s, [0.225, 0.1125, 0.0, 0.0], atol=1e-15)
    assert np.allclose(v[[0, 2, 3]], 0.0, atol=1e-12)
    assert v[1] == pytest.approx(-0.225 * 2.0 / (90.0 * DEG_S))  # mid-return: cycloid's Cv = 2


def test_velocity_jump_at_a_joint_is_refused(odd_laws):
    with pytest.raises(DynamicsError, match="velocity jumps"):
        CamProgram([Segment("rise", 45.0, 0.1, "test-ramp"), Segment("dwell", 45.0)], RPM, periodic=False)


def test_displacement_jump_at_a_joint_is_refused(odd_laws):
    with pytest.raises(DynamicsError, match="displacement jumps"):
        CamProgram([Segment("rise", 45.0, 0.1, "test-short"), Segment("dwell", 45.0)], RPM, periodic=False)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(kind="lift", angle_deg=45.0, lift_m=0.1, law_id="cycloidal"), "kind"),
        (dict(kind="rise", angle_deg=0.0, lift_m=0.1, law_id="cycloidal"), "angle_deg"),
        (dict(kind="rise", angle_deg=45.0, lift_m=-0.1, law_id="cycloidal"), "lift_m"),
        (dict(kind="dwell", angle_deg=45.0, lift_m=0.1), "dwell lift_m"),
        (dict(kind="rise", angle_deg=45.0, lift_m=0.1), "law_id"),
        (dict(kind="rise", angle_deg=45.0, lift_m=0.1, law_id="nope"), "nope"),
    ],
)
def test_bad_segments(kwargs, match):
    with pytest.raises(DynamicsError, match=match):
        Segment(**kwargs)


def test_bad_program_inputs():
    with pytest.raises(DynamicsError, match="rpm"):
        CamProgram.indexing("cycloidal", rpm=0.0)
    with pytest.raises(DynamicsError, match="segments"):
        CamProgram([], RPM, periodic=True)
    with pytest.raises(DynamicsError, match="t >= 0"):
        mqp2012_program("cycloidal").svaj(np.array([-1e-3]))


def test_at_rpm_keeps_the_angle_profile():
    p = CamProgram.indexing("poly-4567")
    q = p.at_rpm(90.0)
    s1, v1, a1, _ = p.svaj(np.array([10.0 * DEG_S]))
    s2, v2, a2, _ = q.svaj(np.array([20.0 * DEG_S]))
    assert s2 == pytest.approx(s1) and v2 == pytest.approx(v1 / 2) and a2 == pytest.approx(a1 / 4)
