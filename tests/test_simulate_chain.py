"""simulate(): the chain under a cam, periodic steady state, friction, stiffness range, options."""

import warnings

import numpy as np
import pytest

from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.solvers.simulate import SlackChainWarning, simulate

DEG_180RPM_S = (1 / 3) / 360  # one cam degree at 180 rpm


class CycloidalIndexer:
    """Test cam (analytic, independent of dynamics.cams): a cycloidal rise of one pitch over
    `index_s`, a dwell of `dwell_s`, repeated; or a single rise then rest when not periodic."""

    def __init__(self, pitch_m=0.1125, index_s=45 * DEG_180RPM_S, dwell_s=45 * DEG_180RPM_S, periodic=True):
        self.pitch_m, self.index_s, self.dwell_s, self.periodic = pitch_m, index_s, dwell_s, periodic

    @property
    def period_s(self):
        return self.index_s + self.dwell_s if self.periodic else None

    @property
    def advance_m(self):
        return self.pitch_m if self.periodic else None

    def svaj(self, t_s):
        t = np.asarray(t_s, dtype=float)
        cycle = self.index_s + self.dwell_s
        n = np.floor(t / cycle) if self.periodic else np.zeros_like(t)
        tau = t - n * cycle
        u = np.clip(tau / self.index_s, 0.0, 1.0)
        moving = (tau < self.index_s) & (tau >= 0)
        h, b = self.pitch_m, self.index_s
        s = h * n + h * (u - np.sin(2 * np.pi * u) / (2 * np.pi))
        v = np.where(moving, h / b * (1 - np.cos(2 * np.pi * u)), 0.0)
        a = np.where(moving, 2 * np.pi * h / b**2 * np.sin(2 * np.pi * u), 0.0)
        j = np.where(moving, 4 * np.pi**2 * h / b**3 * np.cos(2 * np.pi * u), 0.0)
        return s, v, a, j


def run(model, cam, t, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SlackChainWarning)
        return simulate(model, cam, t, **kw)


def test_steady_state_is_periodic_and_equals_the_long_time_limit():
    model = ChainModel(12, 2.03, 9.27e7)
    cam = CycloidalIndexer()
    t_two = np.arange(181) * DEG_180RPM_S  # two periods at one-degree steps
    steady = run(model, cam, t_two)
    # periodic: the state one period later is the same, relative to the advanced cam
    np.testing.assert_allclose(steady.x_m[90:] - cam.pitch_m, steady.x_m[:91], atol=1e-12)
    np.testing.assert_allclose(steady.v_m_s[90:], steady.v_m_s[:91], atol=1e-9)
    # long-time limit of a run from rest: 30 periods decay the transient by exp(-zeta w1 30 T) ~ 1e-30
    t_long = np.arange(30 * 90 + 1) * DEG_180RPM_S
    transient = run(model, cam, t_long, steady_state=False)
    last = slice(29 * 90, 30 * 90 + 1)
    np.testing.assert_allclose(transient.x_m[last] - 29 * cam.pitch_m, steady.x_m[:91], atol=1e-12)
    np.testing.assert_allclose(transient.a_m_s2[last], steady.a_m_s2[:91], atol=1e-6 * np.abs(steady.a_m_s2).max())
    assert steady.diagnostics["steady_state"]["iterations"] == 0  # linear and exact: one solve


def test_steady_state_with_friction_is_periodic_and_the_long_time_limit():
    model = ChainModel(12, 2.03, 9.27e7, friction_coefficient=0.35)
    cam = CycloidalIndexer()
    t_two = np.arange(181) * DEG_180RPM_S
    steady = run(model, cam, t_two)
    info = steady.diagnostics["steady_state"]
    assert 1 <= info["iterations"] <= 10 and info["residual"] <= 1e-8
    scale = np.abs(steady.x_m - steady.z_m[:, None]).max()
    np.testing.assert_allclose(steady.x_m[90:] - cam.pitch_m, steady.x_m[:91], atol=1e-7 * scale)
    t_long = np.arange(30 * 90 + 1) * DEG_180RPM_S
    transient = run(model, cam, t_long, steady_state=False)
    last = slice(29 * 90, 30 * 90 + 1)
    # the Newton-shooting tolerance (1e-8 of the state scale) bounds the difference
    np.testing.assert_allclose(transient.x_m[last] - 29 * cam.pitch_m, steady.x_m[:91], atol=1e-6 * scale)


def test_friction_is_balanced_by_the_drive_on_average():
    """Over one steady period the links' momentum returns to its start, so the mean drive force
    (spring + the drive's share of damping acts internally) equals minus the mean total friction:
    friction enters in real newtons, N mu m g when all links slide forward."""
    model = ChainModel(12, 2.03, 9.27e7, friction_coefficient=0.35)
    cam = CycloidalIndexer()
    t = np.arange(91) * DEG_180RPM_S
    r = run(model, cam, t)
    friction = model.friction_force_N(r.v_m_s).sum(axis=1)
    momentum_rate = model.link_mass_kg * r.a_m_s2.sum(axis=1)
    damping_total = (model.damping_matrix() @ (r.v_m_s - r.zdot_m_s[:, None]).T).sum(axis=0)
    # Newton's second law for the whole chain at every sample (exact up to the splitting's rounding)
    np.testing.assert_allclose(
        momentum_rate, r.drive_force_N + friction - damping_total, atol=1e-6 * np.abs(momentum_rate).max()
    )
    mean = lambda q: np.trapezoid(q, t) / (t[-1] - t[0])
    # periodic: mean m a = 0 and mean damping = 0, so mean drive = -mean friction (trapezoid rule
    # on 90 samples: 1 % of the friction)
    assert mean(r.drive_force_N) == pytest.approx(-mean(friction), rel=1e-2)
    assert mean(friction) < -0.3 * 12 * 0.35 * 2.03 * 9.80665  # friction opposes the forward travel


@pytest.mark.parametrize("k", [1e5, 1e8, 1e10])
def test_default_method_is_right_from_soft_to_very_stiff_chains(k):
    """The exact method has no stability limit; its only error is the first-order hold of z''
    between output samples, O(h^2) (Dynacam failed at the real 9e7 N/m). One-degree sampling is
    within 2 % of the deflection of a 16x finer run at every stiffness; where the sampling rate is
    well above the chain's modes (k <= 1e8 here) halving the step cuts the difference about 4x. At
    1e10 the 2160 Hz half-degree rate sits near the first mode and the hold's error resonates, so
    no rate is asserted there, only the bound."""
    model = ChainModel(20, 2.0, k)
    cam = CycloidalIndexer()
    fine_factor = 16
    t_fine = np.arange(90 * fine_factor + 1) * DEG_180RPM_S / fine_factor
    ref = run(model, cam, t_fine)
    errs = []
    for factor in (1, 2):
        t = np.arange(90 * factor + 1) * DEG_180RPM_S / factor
        r = run(model, cam, t)
        sub = ref.x_m[:: fine_factor // factor] - ref.z_m[:: fine_factor // factor, None]
        errs.append(np.max(np.abs((r.x_m - r.z_m[:, None]) - sub)))
    scale = np.max(np.abs(ref.x_m - ref.z_m[:, None]))
    assert np.all(np.isfinite(errs))
    assert max(errs) < 0.02 * scale
    if k <= 1e8:
        assert errs[1] < errs[0] / 3  # 4x, less the 16x reference's own error


def test_stiff_chain_follows_the_quasi_static_closed_form():
    """At k = 1e10 N/m the first mode (~2 kHz) is far above the cam's content, so the deflection
    relative to the cam is the quasi-static y = -K^-1 M 1 z''(t) (drive spring N m z'' / k_d plus the
    ring's share, ~ m z'' N^2 / 8k at the far link); the dynamic correction is of order
    (f_cam / f_1)^2, well under 3 %."""
    model = ChainModel(20, 2.0, 1e10)
    cam = CycloidalIndexer()
    r = run(model, cam, np.arange(91) * DEG_180RPM_S)
    y = r.x_m - r.z_m[:, None]
    quasi_static = np.linalg.solve(model.stiffness_matrix(), model.base_excitation_force(r.zddot_m_s2).T).T
    assert np.max(np.abs(y - quasi_static)) < 0.03 * np.max(np.abs(quasi_static))


@pytest.mark.parametrize(
    "method, opts, rel_tol",
    [
        ("report-rk45", {}, 1e-6),  # MaxStep 0.1 h keeps Dormand-Prince far below rtol (measured 2e-8)
        ("modal", {}, 1e-10),  # all modes: exact
        ("modal", {"n_modes": 8}, 5e-3),  # relative coordinates: half the modes, 1e-3 (measured)
        ("radau", {"rtol": 1e-7, "atol": 1e-11}, 1e-6),  # tolerance-bounded (measured 3e-8)
    ],
)
def test_other_methods_through_simulate_agree_with_exact(method, opts, rel_tol):
    """Errors relative to the largest deflection from the cam (0.45 mm here)."""
    model = ChainModel(16, 2.03, 9.27e7)
    cam = CycloidalIndexer()
    t = np.arange(91) * DEG_180RPM_S
    ref = run(model, cam, t)
    r = run(model, cam, t, method=method, **opts)
    deflection = np.max(np.abs(ref.x_m - ref.z_m[:, None]))
    assert np.max(np.abs(r.x_m - ref.x_m)) < rel_tol * deflection


def test_friction_needs_a_method_that_handles_it():
    model = ChainModel(8, 2.0, 1e8, friction_coefficient=0.35)
    with pytest.raises(DynamicsError, match="cannot model friction"):
        run(model, CycloidalIndexer(), np.arange(91) * DEG_180RPM_S, method="newmark")


def test_slack_chain_is_flagged_and_warned():
    model = ChainModel(85, 2.03, 9.27e7)  # the report's link: dynamic forces far above the preload
    with pytest.warns(SlackChainWarning, match="slack"):
        r = simulate(model, CycloidalIndexer(), np.arange(91) * DEG_180RPM_S)
    assert r.slack and r.min_tension_N < 0
    assert r.min_tension_N == pytest.approx(r.tension_N.min())
    assert r.tension_N.shape == (91, 85)


def test_start_from_rest_and_link_selection():
    model = ChainModel(10, 2.0, 1e8)
    cam = CycloidalIndexer()
    t = np.arange(91) * DEG_180RPM_S + 10 * DEG_180RPM_S  # starts mid-rise
    r = run(model, cam, t, steady_state=False, links=[0, 7])
    assert r.links == (0, 7) and r.x_m.shape == (91, 2)
    np.testing.assert_allclose(r.x_m[0], r.z_m[0])  # at the cam's position
    np.testing.assert_allclose(r.v_m_s[0], 0.0, atol=1e-12)  # motionless
    full = run(model, cam, t, steady_state=False)
    np.testing.assert_allclose(r.a_m_s2, full.a_m_s2[:, [0, 7]])


def test_one_shot_cam_cannot_have_a_steady_state():
    cam = CycloidalIndexer(periodic=False)
    model = ChainModel(8, 2.0, 1e8)
    t = np.arange(91) * DEG_180RPM_S
    with pytest.raises(DynamicsError, match="not periodic"):
        run(model, cam, t)
    r = run(model, cam, t, steady_state=False)
    assert np.all(np.isfinite(r.x_m))


def test_bad_inputs():
    model = ChainModel(8, 2.0, 1e8)
    cam = CycloidalIndexer()
    t = np.arange(91) * DEG_180RPM_S
    with pytest.raises(DynamicsError, match="links"):
        run(model, cam, t, links=[8])
    with pytest.raises(DynamicsError, match="method"):
        run(model, cam, t, method="euler")
    with pytest.raises(DynamicsError, match="t_eval_s"):
        run(model, cam, t[::-1])


def test_friction_splitting_converges_and_agrees_with_an_adaptive_integrator():
    """Friction through the exact method's Heun splitting: second order in the sub-step (a link's
    friction switches on within microseconds when it starts to move, so the step, not v_s, sets the
    error), and the refined result agrees with the restarted Dormand-Prince scheme, which
    integrates the same force with error control. Errors are relative to the friction's own effect
    on the motion (3 % of the deflection here)."""
    cam = CycloidalIndexer()
    t = np.arange(181) * DEG_180RPM_S
    free = run(ChainModel(16, 2.03, 9.27e7), cam, t)
    model = ChainModel(16, 2.03, 9.27e7, friction_coefficient=0.35)
    ref = run(model, cam, t, substeps=16)
    effect = np.max(np.abs(ref.x_m - free.x_m))
    errs = {s: np.max(np.abs(run(model, cam, t, substeps=s).x_m - ref.x_m)) / effect for s in (1, 2, 4)}
    assert errs[1] < 0.25  # the default at one-degree steps (measured 0.14)
    assert errs[2] / errs[4] > 3.0  # second order (4x less the reference's own error)
    rk = run(model, cam, t, method="report-rk45")
    assert np.max(np.abs(rk.x_m - ref.x_m)) < 0.01 * effect
