"""1- and 2-DOF follower models (report Appendices A, B) against closed forms."""

import numpy as np
import pytest

from dynamics.errors import DynamicsError
from verification.small_models import one_dof_follower, two_dof_follower


class RampCam:
    """s = V t: constant velocity, an exact closed-form steady state for the follower."""

    period_s = None
    advance_m = None

    def __init__(self, speed_m_s):
        self.speed = speed_m_s

    def svaj(self, t):
        t = np.asarray(t, dtype=float)
        return self.speed * t, np.full_like(t, self.speed), np.zeros_like(t), np.zeros_like(t)


def test_one_dof_follower_lags_a_ramp_by_the_closed_form():
    """m x'' + (c1 + c2) x' + k1 x = k1 V t + c1 V has the particular solution x = V t - c2 V / k1:
    started on it, the follower stays on it (exact method: rounding only)."""
    m, k1, c2, speed = 1.1, 1.09e6, 40.0, 0.5  # Appendix A's mass and stiffness
    model = one_dof_follower(m, k1, damping_ratio=0.05, ground_damping_N_s_per_m=c2)
    assert model.drive_damping_N_s_per_m == pytest.approx(2 * 0.05 * np.sqrt(k1 * m))
    t = np.linspace(0, 0.1, 101)
    lag = c2 * speed / k1
    r = model.simulate(RampCam(speed), t, x0=[-lag], v0=[speed])
    np.testing.assert_allclose(r.x[:, 0], speed * t - lag, atol=1e-12)
    np.testing.assert_allclose(r.a[:, 0], 0.0, atol=1e-6)


def test_one_dof_follower_from_rest_settles_onto_the_ramp():
    m, k1, speed = 1.1, 1.09e6, 0.5
    model = one_dof_follower(m, k1)
    t = np.linspace(0, 0.2, 401)  # zeta w t = 0.05 * 995 * 0.2 ~ 10: transient e^-10
    r = model.simulate(RampCam(speed), t)
    assert abs(r.x[-1, 0] - speed * t[-1]) < 1e-4 * speed / np.sqrt(k1 / m)


def test_two_dof_frequencies_match_the_closed_form():
    """Equal masses and springs: w^2 = (k/m)(3 -+ sqrt 5)/2."""
    m, k = 1.1, 1.09e6
    model = two_dof_follower((m, m), (k, k))
    lam = np.linalg.eigvals(np.linalg.solve(model.system.mass, model.system.stiffness))
    np.testing.assert_allclose(np.sort(lam.real), k / m * np.array([(3 - np.sqrt(5)) / 2, (3 + np.sqrt(5)) / 2]))
    c = 2 * 0.05 * np.sqrt(k * m)
    np.testing.assert_allclose(model.system.damping, [[2 * c, -c], [-c, c]])


def test_two_dof_with_a_rigid_second_spring_acts_as_one_mass():
    """k2 -> infinity locks the masses: the pair moves as one follower of mass m1 + m2 (the stiff
    mode is far above the forcing; difference of order k1 / k2)."""
    cam = RampCam(0.5)
    t = np.linspace(0, 0.05, 201)
    pair = two_dof_follower((1.1, 0.9), (1.09e6, 1.09e12), dampings_N_s_per_m=(30.0, 0.0)).simulate(cam, t)
    single = one_dof_follower(2.0, 1.09e6, drive_damping_N_s_per_m=30.0).simulate(cam, t)
    np.testing.assert_allclose(pair.x[:, 0], single.x[:, 0], atol=1e-5 * np.abs(single.x).max())
    np.testing.assert_allclose(pair.x[:, 1], single.x[:, 0], atol=1e-5 * np.abs(single.x).max())


def test_small_models_run_with_other_solvers():
    model = two_dof_follower((1.1, 1.1), (1.09e6, 1.09e6))
    t = np.linspace(0, 0.05, 101)
    ref = model.simulate(RampCam(0.5), t)
    rk = model.simulate(RampCam(0.5), t, method="report-rk45")
    assert np.max(np.abs(rk.x - ref.x)) < 1e-6 * np.max(np.abs(ref.x))  # tolerance-bounded


def test_bad_small_model_inputs():
    with pytest.raises(DynamicsError, match="mass_kg"):
        one_dof_follower(0.0, 1e6)
    with pytest.raises(DynamicsError, match="damping_ratio"):
        one_dof_follower(1.0, 1e6, damping_ratio=1.5)
    with pytest.raises(DynamicsError, match="stiffnesses_N_per_m"):
        two_dof_follower((1.0, 1.0), (1e6, -1.0))
