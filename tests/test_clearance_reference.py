"""The clearance chain's slow reference (verification.clearance_reference) against exact answers.

Tolerances: the reference runs DOP853 at rtol 1e-10 with every contact change located; measured on
the 20-link chain below against the exact linear solver its global error is about 1 rtol in y,
50 rtol in y' and 800 rtol in y'' (relative to each one's peak; y'' carries the highest modes, whose
error is amplified by omega^2), and it shrinks with rtol (checked below), so it is the reference's
own error. The bounds are 10x those figures.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dynamics.cams import CamProgram, Segment
from dynamics.errors import DynamicsError, SolverFailedError
from dynamics.models.chain import ChainModel
from dynamics.solvers.simulate import SlackChainWarning, simulate
from verification.clearance_reference import HeldCam, idler_span_index, reference_response

K = 9.27e7  # N/m, the default link's axial stiffness (order of)
MASS = 2.03  # kg per link
PRELOAD = 2224.0
GAP = 1e-4  # m, total free play of a span's two pin joints
T_WINDOW = np.arange(181) / (6.0 * 180.0)  # 0..180 cam degrees at 180 rpm, one-degree outputs
CAM = CamProgram.indexing("modified-sine")
RESTING = CamProgram((Segment("dwell", 360.0),), 180.0, periodic=True, name="at rest")


def chain(n=20, **overrides):
    args = dict(
        n_links=n,
        link_mass_kg=MASS,
        stiffness_N_per_m=K,
        drive_stiffness_N_per_m=K,
        preload_N=PRELOAD,
        clearance_m=GAP,
        cam=CAM,
        t_eval_s=T_WINDOW,
    )
    args.update(overrides)
    return reference_response(**args)


def relative(lin):
    """Motion of a dynamics.solvers.simulate response relative to the cam."""
    return (lin.x_m - lin.z_m[:, None], lin.v_m_s - lin.zdot_m_s[:, None], lin.a_m_s2 - lin.zddot_m_s2[:, None])


def linear(model):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SlackChainWarning)
        return simulate(model, CAM, T_WINDOW, steady_state=False)


def rel_errors(ref, lin):
    return [
        float(np.abs(a - b).max() / np.abs(b).max())
        for a, b in zip((ref.y_m, ref.ydot_m_s, ref.yddot_m_s2), relative(lin))
    ]


# (i) no free play: today's linear chain ------------------------------------------------------------


def test_no_clearance_is_the_exact_linear_solver_to_the_tolerance():
    model = ChainModel(20, MASS, K, preload_N=PRELOAD)
    lin = linear(model)
    assert lin.min_tension_N < 0  # the linear chain pushes here: the case is not trivially in contact
    errs = {
        rtol: rel_errors(chain(clearance_m=0.0, damping_matrix=model.damping_matrix(), rtol=rtol), lin)
        for rtol in (1e-8, 1e-10)
    }
    y, v, a = errs[1e-10]
    assert y < 10 * 1e-10 and v < 500 * 1e-10 and a < 8000 * 1e-10
    # the difference is the reference's own integration error: it shrinks with the tolerance
    assert all(coarse > 30 * fine for coarse, fine in zip(errs[1e-8], errs[1e-10]))


def test_sampled_input_reports_absolute_motion_as_simulate_does():
    model = ChainModel(20, MASS, K, preload_N=PRELOAD)
    lin = linear(model)
    ref = chain(clearance_m=0.0, damping_matrix=model.damping_matrix())
    np.testing.assert_array_equal(ref.z_m, lin.z_m)
    for ours, theirs in ((ref.x_m, lin.x_m), (ref.v_m_s, lin.v_m_s), (ref.a_m_s2, lin.a_m_s2)):
        assert np.abs(ours - theirs).max() < 1e-6 * np.abs(theirs - theirs.mean()).max()


def test_sampled_input_with_friction_is_what_simulate_converges_to():
    """simulate's friction splitting is second order in its sub-step; with the same sampled input the
    reference is its limit."""
    model = ChainModel(20, MASS, K, preload_N=PRELOAD, friction_coefficient=0.35)
    ref = chain(clearance_m=0.0, damping_matrix=model.damping_matrix(), friction_force_N=model.coulomb_force_N)
    errors = []
    for substeps in (2, 8):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SlackChainWarning)
            lin = simulate(model, CAM, T_WINDOW, steady_state=False, substeps=substeps)
        errors.append(np.abs(ref.x_m - lin.x_m).max() / np.abs(ref.y_m).max())
    assert errors[0] > 8.0 * errors[1]  # 16 at second order
    assert errors[1] < 1e-3


def test_kelvin_voigt_law_without_free_play_is_stiffness_proportional_rayleigh():
    beta = 2e-5
    lin = linear(ChainModel(20, MASS, K, preload_N=PRELOAD, rayleigh_coefficients=(0.0, beta)))
    y, v, a = rel_errors(chain(clearance_m=0.0, span_damping_beta_s=beta), lin)
    assert y < 1e-9 and v < 5e-8 and a < 8e-7


def test_free_play_never_reached_is_the_linear_chain():
    preload = 2e5  # far above the dynamic forces: no span leaves pulling contact
    model = ChainModel(20, MASS, K, preload_N=preload)
    ref = chain(preload_N=preload, damping_matrix=model.damping_matrix())
    assert ref.n_contact_changes == 0 and np.all(ref.contact_mode == 1)
    y, v, a = rel_errors(ref, linear(model))
    assert y < 1e-9 and v < 5e-8 and a < 8e-7
    np.testing.assert_allclose(ref.tension_N, model.tension_N(ref.y_m), rtol=0, atol=1e-9 * preload)


def test_held_cam_integrates_its_sampled_acceleration_exactly():
    held = HeldCam(CAM, T_WINDOW)
    s, v, a, _ = CAM.svaj(T_WINDOW)
    hs, hv, ha, _ = held.svaj(T_WINDOW)
    np.testing.assert_array_equal(ha, a)
    assert hs[0] == s[0] and hv[0] == v[0]
    mid = 0.5 * (T_WINDOW[:-1] + T_WINDOW[1:])
    np.testing.assert_allclose(held.svaj(mid)[2], 0.5 * (a[:-1] + a[1:]), rtol=0, atol=1e-12 * np.abs(a).max())
    # velocity is the integral of the held acceleration (trapezoid rule is exact for it)
    np.testing.assert_allclose(
        hv[1:], v[0] + np.cumsum(0.5 * (a[:-1] + a[1:]) * np.diff(T_WINDOW)), rtol=1e-12, atol=1e-12
    )
    z, zd = held.z_and_zdot(float(mid[7]))
    assert z == pytest.approx(held.svaj(mid[7:8])[0][0], rel=1e-15) and zd == pytest.approx(held.svaj(mid[7:8])[1][0])


# (ii) one span closing its play: the closed-form impact --------------------------------------------

M0, M1 = 2.0, 3.0
K_C = 1e8
V_APPROACH = 0.5  # m/s, closing speed of the span's two links
REDUCED = M0 * M1 / (M0 + M1)
OMEGA_C = np.sqrt(K_C / REDUCED)


def two_masses(beta=0.0, t_end=2e-3):
    """Two links joined by one span with free play GAP and no preload (the closing span of the
    2-link loop has stiffness 0, the drive 0: nothing else acts), starting mid-play, closing at V."""
    share = np.array([M1, -M0]) / (M0 + M1)  # zero momentum
    return reference_response(
        n_links=2,
        link_mass_kg=[M0, M1],
        stiffness_N_per_m=[K_C, 0.0],
        drive_stiffness_N_per_m=0.0,
        preload_N=0.0,
        clearance_m=[GAP, np.inf],
        cam=RESTING,
        t_eval_s=np.linspace(0.0, t_end, 401),
        span_damping_beta_s=beta,
        y0=[0.0, -GAP / 2],
        ydot0=V_APPROACH * share,
    )


def test_single_span_impact_lasts_pi_over_omega_and_rebounds_at_the_approach_speed():
    r = two_masses()
    times = r.contact_change_times_s
    assert r.n_contact_changes >= 6
    flight, contact = GAP / V_APPROACH, np.pi / OMEGA_C
    expected = GAP / 2 / V_APPROACH + np.cumsum([0.0] + [contact, flight] * ((times.size - 1) // 2 + 1))[: times.size]
    np.testing.assert_allclose(times, expected, rtol=1e-9)
    e_dot = r.ydot_m_s[:, 1] - r.ydot_m_s[:, 0]
    free = r.contact_mode[:, 0] == 0
    np.testing.assert_allclose(np.abs(e_dot[free]), V_APPROACH, rtol=1e-9)
    # the push contact's peak force is k V / omega_c; the pull contact's the same (no preload)
    assert r.tension_N[:, 0].min() == pytest.approx(-K_C * V_APPROACH / OMEGA_C, rel=1e-3)
    assert r.tension_N[:, 0].max() == pytest.approx(K_C * V_APPROACH / OMEGA_C, rel=1e-3)
    assert np.all(r.tension_N[:, 1] == 0.0)


def test_kelvin_voigt_impact_has_the_closed_form_restitution_and_duration():
    zeta = 0.1
    beta = 2 * zeta / OMEGA_C  # dashpot beta k: zeta = beta omega_c / 2
    r = two_masses(beta=beta, t_end=1.5e-3)
    restitution = np.exp(-zeta * np.pi / np.sqrt(1 - zeta**2))
    duration = np.pi / (OMEGA_C * np.sqrt(1 - zeta**2))
    times = r.contact_change_times_s
    assert times.size >= 5
    np.testing.assert_allclose(times[1] - times[0], duration, rtol=1e-9)
    np.testing.assert_allclose(times[3] - times[2], duration, rtol=1e-9)
    np.testing.assert_allclose(times[2] - times[1], GAP / (V_APPROACH * restitution), rtol=1e-9)
    e_dot = r.ydot_m_s[:, 1] - r.ydot_m_s[:, 0]
    after_first = (r.t_s > times[1]) & (r.t_s < times[2])
    after_second = (r.t_s > times[3]) & (r.t_s < times[4]) if times.size > 4 else r.t_s > times[3]
    np.testing.assert_allclose(e_dot[after_first], V_APPROACH * restitution, rtol=1e-9)
    np.testing.assert_allclose(e_dot[after_second], -V_APPROACH * restitution**2, rtol=1e-9)
    # the impact's lost energy is the dashpot's
    lost = 0.5 * REDUCED * V_APPROACH**2 * (1 - restitution**4)
    end = (r.t_s > times[3]) & (r.t_s < times[4])
    np.testing.assert_allclose(r.damper_dissipation_J[end], lost, rtol=1e-8)


# (iii) energy --------------------------------------------------------------------------------------

FRICTION = 0.35 * MASS * 9.80665


@pytest.mark.parametrize(
    "case",
    [
        "no free play, modal damping, friction",
        "free play, modal damping, friction",
        "free play, Kelvin-Voigt, tensioner",
    ],
)
def test_cam_work_is_dissipation_plus_change_of_stored_energy(case):
    model = ChainModel(20, MASS, K, preload_N=PRELOAD)
    t = T_WINDOW[:91]  # one index and its dwell
    if case.startswith("no free play"):
        r = chain(
            clearance_m=0.0,
            damping_matrix=model.damping_matrix(),
            friction_force_N=FRICTION,
            t_eval_s=t,
            cam_input="held",
        )
    elif "modal" in case:
        r = chain(damping_matrix=model.damping_matrix(), friction_force_N=FRICTION, t_eval_s=t, cam_input="held")
        assert r.n_contact_changes > 0
    else:
        r = chain(span_damping_beta_s=2e-5, tensioner=(2e6, 5.0, 500.0), t_eval_s=t, cam_input="held")
        assert r.n_contact_changes > 0 and np.abs(r.tensioner_u_m).max() > 1e-7
    scale = max(np.abs(r.cam_work_J).max(), r.damper_dissipation_J[-1], np.ptp(r.stored_energy_J))
    assert np.abs(r.energy_balance_residual_J).max() < 1e-6 * scale
    assert r.damper_dissipation_J[-1] > 1e-3 * scale  # every term is really there
    if "friction" in case:
        assert r.friction_dissipation_J[-1] > 1e-3 * scale


# (iv) the idler tensioner --------------------------------------------------------------------------


def test_tensioner_rests_at_u_zero_in_the_preloaded_static_state():
    r = chain(
        n=10,
        cam=RESTING,
        y0=np.zeros(10),
        ydot0=np.zeros(10),
        tensioner=(2e6, 5.0, 100.0),
        t_eval_s=np.linspace(0.0, 0.05, 51),
    )
    assert np.all(r.tensioner_u_m == 0.0) and np.all(r.y_m == 0.0)
    assert np.all(r.tension_N == PRELOAD) and r.n_contact_changes == 0


def test_stiff_tensioner_is_the_rigid_idler():
    t = T_WINDOW[:46]  # the index (45 degrees)
    rigid = chain(n=10, t_eval_s=t)
    errors = []
    for rate in (1e10, 1e11):
        sprung = chain(n=10, t_eval_s=t, tensioner=(rate, 20.0, 0.0))
        errors.append(np.abs(sprung.y_m - rigid.y_m).max() / np.abs(rigid.y_m).max())
        assert np.abs(sprung.tensioner_u_m).max() < 4 * np.abs(rigid.tension_N).max() / rate
    assert errors[1] < 3e-3 and errors[0] > 5 * errors[1]  # converges as 1/k_t
    assert idler_span_index(85) == 42 and idler_span_index(10) == 4


# (v) a chain that can only pull --------------------------------------------------------------------


def test_chain_without_end_stops_never_pushes():
    model = ChainModel(20, MASS, K, preload_N=PRELOAD)
    assert linear(model).min_tension_N < -PRELOAD  # the linear chain pushes here
    r = chain(clearance_m=np.inf, damping_matrix=model.damping_matrix())
    assert r.n_contact_changes > 0 and np.any(r.contact_mode == 0)
    assert not np.any(r.contact_mode == -1)
    assert r.tension_N.min() >= 0.0
    assert np.all(r.tension_N[r.contact_mode == 0] == 0.0)


# input checks --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "override, name",
    [
        (dict(clearance_m=-1e-4), "clearance_m"),
        (dict(link_mass_kg=[1.0, 2.0]), "link_mass_kg"),
        (dict(tensioner=(1e6, 0.0, 0.0)), "tensioner"),
        (dict(cam_input="spline"), "cam_input"),
        (dict(damping_matrix=np.eye(3)), "damping_matrix"),
        (dict(t_eval_s=[0.0, 0.0]), "t_eval_s"),
        (dict(method="Euler"), "method"),
    ],
)
def test_bad_input_names_the_input(override, name):
    with pytest.raises(DynamicsError, match=name):
        chain(**override)


def test_too_many_contact_changes_stop_the_run_with_a_reason():
    with pytest.raises(SolverFailedError, match="more than 3 contact changes"):
        chain(clearance_m=np.inf, max_events=3)


# the default scene's length --------------------------------------------------------------------------


@pytest.mark.slow
def test_85_links_with_free_play_and_friction_balance_energy():
    model = ChainModel(85, MASS, K, preload_N=PRELOAD, friction_coefficient=0.35)
    r = chain(n=85, damping_matrix=model.damping_matrix(), friction_force_N=model.coulomb_force_N, cam_input="held")
    assert r.n_contact_changes > 0
    scale = np.abs(r.cam_work_J).max()
    assert np.abs(r.energy_balance_residual_J).max() < 1e-6 * scale


@pytest.mark.slow
def test_held_cam_input_converges_to_the_cam_itself_at_second_order():
    """cam_input="exact" drives the chain by the cam; the held input's difference from it is the
    first-order hold's sampling error, O(h^2) in the sample spacing."""
    t_end = T_WINDOW[45]  # the index
    exact = chain(n=10, cam_input="exact", t_eval_s=np.linspace(0.0, t_end, 46))
    differences = []
    for per_degree in (1, 4):
        t = np.linspace(0.0, t_end, 45 * per_degree + 1)
        held = chain(n=10, t_eval_s=t)
        differences.append(np.abs(held.y_m[::per_degree] - exact.y_m).max() / np.abs(exact.y_m).max())
    assert differences[0] > 10.0 * differences[1]  # 16 at exactly second order
