"""ChainModel: matrices, frequencies against closed forms, damping, tension sign, friction law."""

import numpy as np
import pytest

from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel


def test_field_note_frequencies_with_the_driven_link_held():
    model = ChainModel(85, 2.0, 1e8)
    f = model.natural_frequencies_Hz(driven_link_held=True)
    assert f.size == 84
    assert f[0] == pytest.approx(41.6, abs=0.05)  # field notes: 41.6 Hz
    assert f[-1] == pytest.approx(2250.0, rel=2e-3)  # field notes: about 2250 Hz


@pytest.mark.parametrize("n", [3, 8, 85])
def test_held_frequencies_match_the_closed_form(n):
    k, m = 9.27e7, 2.03
    f = ChainModel(n, m, k).natural_frequencies_Hz(driven_link_held=True)
    j = np.arange(1, n)
    closed = 2 * np.sqrt(k / m) * np.sin(j * np.pi / (2 * n)) / (2 * np.pi)
    np.testing.assert_allclose(f, closed, rtol=1e-10)  # eigensolver rounding only


def test_a_very_stiff_drive_approaches_the_held_chain():
    held = ChainModel(20, 2.0, 1e8).natural_frequencies_Hz(driven_link_held=True)
    stiff = ChainModel(20, 2.0, 1e8, drive_stiffness_N_per_m=1e14).natural_frequencies_Hz()
    # the drive adds one very high mode; the other 19 tend to the held chain's as k/k_d = 1e-6
    np.testing.assert_allclose(stiff[:-1], held, rtol=1e-5)


def test_rigid_translation_loads_only_the_drive_spring():
    model = ChainModel(10, 2.0, 1e8, drive_stiffness_N_per_m=3e7)
    kk = model.stiffness_matrix()
    np.testing.assert_array_equal(kk, kk.T)
    expected = np.zeros(10)
    expected[0] = 3e7
    np.testing.assert_allclose(kk @ np.ones(10), expected)


@pytest.mark.parametrize("zeta", [0.0, 0.02, 0.13])
def test_modal_damping_gives_the_ratio_on_every_mode(zeta):
    model = ChainModel(12, 2.0, 1e8, damping_ratio=zeta)
    omega, phi = model.modes()
    modal = phi.T @ model.damping_matrix() @ phi
    np.testing.assert_allclose(np.diag(modal), 2 * zeta * omega, rtol=1e-9, atol=1e-9 * omega.max())
    off = modal - np.diag(np.diag(modal))
    assert np.max(np.abs(off)) < 1e-8 * max(2 * zeta * omega.max(), 1.0)


def test_rayleigh_damping_replaces_the_modal_ratio():
    model = ChainModel(6, 2.0, 1e8, rayleigh_coefficients=(3.0, 2e-5))
    np.testing.assert_allclose(model.damping_matrix(), 3.0 * model.mass_matrix() + 2e-5 * model.stiffness_matrix())


def test_tension_sign_convention():
    """Pushing link 1 forward stretches the spring behind it (link N -> 1, the tight side) and
    compresses the one ahead (link 1 -> 2)."""
    model = ChainModel(5, 2.0, 1e8, preload_N=2224.0)
    x = np.array([1e-4, 0, 0, 0, 0])
    t = model.tension_N(x)
    assert t[4] == pytest.approx(2224.0 + 1e4)  # spring from link 5 to link 1
    assert t[0] == pytest.approx(2224.0 - 1e4)  # spring from link 1 to link 2
    np.testing.assert_allclose(t[1:4], 2224.0)
    np.testing.assert_allclose(model.tension_N(np.full((3, 5), 0.7)), 2224.0)  # rigid motion: preload
    assert model.drive_force_N(np.array([1e-4]), np.array([3e-4]))[0] == pytest.approx(1e8 * 2e-4)


def test_friction_is_coulomb_in_newtons_with_a_stated_smoothing():
    model = ChainModel(4, 2.0, 1e8, friction_coefficient=0.35, friction_velocity_scale_m_s=5e-3)
    coulomb = 0.35 * 2.0 * 9.80665
    f = model.friction_force_N(np.array([1.0, -1.0, 0.0, 1e-5]))
    assert f[0] == pytest.approx(-coulomb, rel=1e-12)  # 200 v_s: saturated
    assert f[1] == pytest.approx(coulomb, rel=1e-12)
    assert f[2] == 0.0
    assert f[3] == pytest.approx(-coulomb * 1e-5 / 5e-3, rel=1e-5)  # linear branch, slope mu m g / v_s
    assert model.friction_slope_per_s() == pytest.approx(0.35 * 9.80665 / 5e-3)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"n_links": 1}, "n_links"),
        ({"n_links": 8.5}, "n_links"),
        ({"link_mass_kg": 0.0}, "link_mass_kg"),
        ({"stiffness_N_per_m": -1.0}, "stiffness_N_per_m"),
        ({"drive_stiffness_N_per_m": 0.0}, "drive_stiffness_N_per_m"),
        ({"damping_ratio": 1.0}, "damping_ratio"),
        ({"rayleigh_coefficients": (1.0,)}, "rayleigh_coefficients"),
        ({"preload_N": -1.0}, "preload_N"),
        ({"friction_coefficient": 1.5}, "friction_coefficient"),
        ({"friction_velocity_scale_m_s": 0.0}, "friction_velocity_scale_m_s"),
    ],
)
def test_bad_model_inputs_raise(kwargs, name):
    base = {"n_links": 8, "link_mass_kg": 2.0, "stiffness_N_per_m": 1e8}
    base.update(kwargs)
    with pytest.raises(DynamicsError, match=name):
        ChainModel(**base)


def test_base_excitation_is_minus_mass_times_cam_acceleration():
    class Cam:
        def svaj(self, t):
            return t**3, 3 * t**2, 6 * t, 6 + 0 * t

    model = ChainModel(4, 2.5, 1e8)
    t = np.linspace(0, 1, 5)
    f = model.base_excitation(Cam(), t)
    np.testing.assert_allclose(f.values, -2.5 * np.outer(6 * t, np.ones(4)))
    np.testing.assert_array_equal(f.t_s, t)
