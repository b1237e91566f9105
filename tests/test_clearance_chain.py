"""The clearance chain (issue #11): span law, reduction to the linear chain, energy balance,
convergence order of the explicit integrator, stability limit on both sides, steady state."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain, Tensioner, contact_state, span_energy_J, span_force_N
from dynamics.models.system import SampledForce
from dynamics.scene import MAX_STEP_DOUBLINGS, Validity, choose_model, simulate_chain
from dynamics.solvers import clearance_verlet as verlet
from dynamics.solvers import solve
from dynamics.solvers.simulate import simulate

K, MASS, P = 9e7, 2.2, 2224.0


def _chain(n=8, **kw) -> ChainModel:
    return ChainModel(n_links=n, link_mass_kg=MASS, stiffness_N_per_m=K, preload_N=kw.pop("preload_N", P), **kw)


def _cam(rpm=180.0):
    return CamProgram.indexing("modified-sine", pitch_m=0.1125, rpm=rpm)


def _times(degrees=90.0, per_degree=2, rpm=180.0):
    return np.arange(int(degrees * per_degree) + 1) / per_degree / (6.0 * rpm)


def test_span_law_is_continuous_and_its_energy_integrates_it():
    g = 1e-4
    e = np.linspace(-P / K - 3 * g, 2 * P / K, 20001)
    t = span_force_N(e, P, K, g)
    assert np.max(np.abs(np.diff(t))) <= K * (e[1] - e[0]) * (1 + 1e-9)  # continuous, slope k or 0
    assert span_force_N(-P / K - g / 2, P, K, g) == 0.0
    assert span_force_N(-P / K - 2 * g, P, K, g) == pytest.approx(-K * g)
    np.testing.assert_allclose(span_force_N(e, P, K, 0.0), P + K * e, rtol=0, atol=1e-9)  # g = 0: linear
    assert np.all(span_force_N(e, P, K, np.inf) >= 0.0)  # g = inf: can only pull
    de = 1e-9
    mid = e[1:-1]
    numeric = (span_energy_J(mid + de, P, K, g) - span_energy_J(mid - de, P, K, g)) / (2 * de)
    np.testing.assert_allclose(numeric, span_force_N(mid, P, K, g), rtol=1e-5, atol=1e-3)
    assert set(np.unique(contact_state(e, P, K, g))) == {-1, 0, 1}


def test_bad_parameters_are_refused():
    with pytest.raises(DynamicsError, match="clearance_m"):
        ClearanceChain(_chain(), -1e-6)
    with pytest.raises(DynamicsError, match="span_damping"):
        ClearanceChain(_chain(), 1e-4, span_damping="coulomb")
    with pytest.raises(DynamicsError, match="mass_kg"):
        Tensioner(1e5, 0.0)


def test_kelvin_voigt_in_full_contact_equals_rayleigh_beta():
    beta = 2e-5
    rayleigh = _chain(rayleigh_coefficients=(0.0, beta), preload_N=1e7)  # preload keeps every span in contact
    kv = ClearanceChain(_chain(preload_N=1e7), 1e-4, span_damping="kelvin-voigt", kv_beta_s=beta)
    glob = ClearanceChain(rayleigh, 1e-4)
    t = _times()
    _, v, a, _ = _cam().svaj(np.linspace(0, t[-1], 8 * (t.size - 1) + 1))
    h = t[-1] / (8 * (t.size - 1))
    runs = [verlet.integrate(m, v, a, h, np.zeros(8), -v[0] * np.ones(8), out_every=8) for m in (kv, glob)]
    np.testing.assert_allclose(runs[0].y, runs[1].y, rtol=0, atol=1e-12 * np.max(np.abs(runs[1].y)))


@pytest.mark.parametrize("preload_N, clearance_m", [(P, 0.0), (1e7, 94e-6)])
def test_auto_is_the_exact_linear_solution_where_no_span_leaves_contact(preload_N, clearance_m):
    chain = _chain(friction_coefficient=0.35, preload_N=preload_N)
    t = _times()
    r, s = simulate_chain(ClearanceChain(chain, clearance_m), _cam(), t)
    ref = simulate(chain, _cam(), t)
    assert s.model == "linear" and ("clearance 0" in s.reason or "never leaves" in s.reason)
    for got, want in ((r.x_m, ref.x_m), (r.v_m_s, ref.v_m_s), (r.a_m_s2, ref.a_m_s2), (r.tension_N, ref.tension_N)):
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=0)
    assert s.preload_for_full_contact_N == pytest.approx(max(preload_N - ref.min_tension_N, 0.0))


def test_default_like_scene_chooses_the_clearance_model_and_the_preload_it_reports_is_enough():
    chain = _chain(friction_coefficient=0.35)
    t = _times()
    r, s = simulate_chain(ClearanceChain(chain, 94e-6), _cam(), t)
    assert s.model == "clearance" and "leaves pulling contact" in s.reason
    assert s.contact_lost and s.free_play_time_fraction > 0 and s.impacts_per_cycle > 0
    assert s.steady_state.found and s.steady_state.period_cycles == 1
    # with the reported preload the linear chain stays in pulling contact: auto picks it
    stiff = _chain(friction_coefficient=0.35, preload_N=s.preload_for_full_contact_N * (1 + 1e-9) + 1e-6)
    assert simulate_chain(ClearanceChain(stiff, 94e-6), _cam(), t)[1].model == "linear"


def test_choices_and_their_limits():
    m = ClearanceChain(_chain(), 94e-6)
    assert choose_model(m, "linear", -1.0)[0] == "linear"
    assert choose_model(m, "clearance", 1.0)[0] == "clearance"
    tensioned = ClearanceChain(_chain(), 0.0, tensioner=Tensioner(1e5, 5.0, 100.0))
    assert choose_model(tensioned, "auto", 1.0)[0] == "clearance"
    for n in (401, 2000):  # the global law's reduced form (dynamics.models.reduced_damping): no fallback at any length
        long = ClearanceChain(_chain(n=n), 94e-6)
        assert long.damping_is_reduced
        assert choose_model(long, "clearance", -1.0)[0] == "clearance"
        which, reason, validity = choose_model(long, "auto", -1.0)
        assert which == "clearance" and "NOT valid" not in reason and validity == Validity.VALID
    assert choose_model(m, "auto", -1.0).validity == Validity.VALID
    with pytest.raises(DynamicsError, match="model"):
        choose_model(m, "nonlinear", 1.0)


def _linear_problem(n=8, per_degree=2):
    """The chain from rest under the cam's acceleration held linearly between output samples (the
    exact solver's first-order hold), so the two methods solve the same equations."""
    chain = _chain(n=n)
    t = _times(per_degree=per_degree)
    _, v, a, _ = _cam().svaj(t)
    ref = solve(
        chain.system(), SampledForce(t, chain.base_excitation_force(a)), t, x0=np.zeros(n), v0=-v[0] * np.ones(n)
    )
    return chain, t, v, a, ref


def _integrate_held(model, t, v, a, sub, **kw):
    tf = np.linspace(t[0], t[-1], sub * (t.size - 1) + 1)
    return verlet.integrate(
        model,
        np.interp(tf, t, v),
        np.interp(tf, t, a),
        tf[1] - tf[0],
        np.zeros(model.n_links),
        -v[0] * np.ones(model.n_links),
        out_every=sub,
        **kw,
    )


def test_integrator_converges_to_the_linear_chain_at_second_order_for_zero_clearance():
    chain, t, v, a, ref = _linear_problem()
    model = ClearanceChain(chain, 0.0)
    errors = [np.max(np.abs(_integrate_held(model, t, v, a, sub).y - ref.x)) for sub in (16, 32, 64)]
    scale = np.max(np.abs(ref.x))
    assert errors[-1] < 1e-4 * scale
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 1.8) & (orders < 2.3)), orders


def test_integrator_is_second_order_through_impacts():
    model = ClearanceChain(_chain(n=8, friction_coefficient=0.35, preload_N=100.0), 94e-6)
    t = _times(per_degree=2)
    _, v, a, _ = _cam().svaj(np.linspace(t[0], t[-1], 512 * (t.size - 1) + 1))

    def run(sub):
        idx = np.arange(0, 512 * (t.size - 1) + 1, 512 // sub)
        return verlet.integrate(model, v[idx], a[idx], t[1] / sub, np.zeros(8), -v[0] * np.ones(8), out_every=sub)

    ref = run(512)
    assert ref.impacts > 10
    errors = [np.max(np.abs(run(sub).y - ref.y)) for sub in (16, 32, 64)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.7), orders


@pytest.mark.parametrize("damping", ["global", "kelvin-voigt"])
@pytest.mark.parametrize("clearance_m", [0.0, 94e-6])
def test_energy_balance(damping, clearance_m):
    """Cam work = dissipated + change of stored energy, to 1e-6 of the cam work, over an index."""
    chain = _chain(n=6, friction_coefficient=0.35)
    model = ClearanceChain(chain, clearance_m, span_damping=damping, tensioner=Tensioner(2e5, 3.0, 50.0))
    t = _times(degrees=60.0, per_degree=1)
    sub = 400
    tf = np.linspace(t[0], t[-1], sub * (t.size - 1) + 1)
    _, v, a, _ = _cam().svaj(tf)
    y0, w0 = np.zeros(6), -v[0] * np.ones(6)
    r = verlet.integrate(model, v, a, tf[1] - tf[0], y0, w0, out_every=sub, track_energy=True)
    if clearance_m > 0:
        assert r.free_play_fraction > 0
    start = model.stored_energy_J(y0, w0, v[0])
    end = model.stored_energy_J(r.y[-1], r.w[-1], v[-1], r.u[-1], r.ud[-1])
    residual = r.cam_work_J - (r.dissipated_damping_J + r.dissipated_friction_J + end - start)
    assert abs(residual) <= 1e-6 * abs(r.cam_work_J)


def _short_run(model, predictor="euler", compiled=None):
    t = _times(degrees=20)
    sub = 8
    tf = np.linspace(t[0], t[-1], sub * (t.size - 1) + 1)
    _, v, a, _ = _cam().svaj(tf)
    n = model.n_links
    return verlet.integrate(
        model, v, a, tf[1], np.zeros(n), -v[0] * np.ones(n), out_every=sub, compiled=compiled, predictor=predictor
    )


@pytest.mark.parametrize("n_links", [6, 7])  # even and odd: one or two links on the mirror line
@pytest.mark.parametrize("predictor", ["euler", "ab2"])
def test_numpy_path_equals_the_compiled_path(predictor, n_links):
    if verlet.numba is None:
        pytest.skip("numba not installed: only the numpy path exists")
    model = ClearanceChain(_chain(n=n_links, friction_coefficient=0.35), 94e-6, tensioner=Tensioner(2e5, 3.0, 50.0))
    runs = [_short_run(model, predictor, c) for c in (True, False)]
    np.testing.assert_allclose(runs[0].y, runs[1].y, rtol=0, atol=1e-12 * np.max(np.abs(runs[1].y)))
    assert runs[0].impacts == runs[1].impacts
    assert n_links == 6 or runs[0].impacts > 0  # the odd chain's window has impacts: their metrics compared
    _assert_same_impact_metrics(*runs)


def _assert_same_impact_metrics(compiled, numpy_path):
    np.testing.assert_allclose(compiled.impact_speeds_m_s, numpy_path.impact_speeds_m_s, rtol=1e-9)
    for name in ("impact_force_spike_N", "impact_kinetic_energy_J", "impact_max_speed_m_s", "impact_dissipated_J"):
        assert getattr(compiled, name) == pytest.approx(getattr(numpy_path, name), rel=1e-9)


def test_numpy_path_equals_the_compiled_path_in_the_kelvin_voigt_impact_metrics():
    if verlet.numba is None:
        pytest.skip("numba not installed: only the numpy path exists")
    model = ClearanceChain(_chain(n=7, friction_coefficient=0.35), 94e-6, span_damping="kelvin-voigt")
    runs = [_short_run(model, "euler", c) for c in (True, False)]
    assert runs[0].impacts == runs[1].impacts > 0 and runs[1].impact_dissipated_J > 0
    _assert_same_impact_metrics(*runs)


def _blocked(cmat: np.ndarray, w: np.ndarray) -> np.ndarray:
    blocks = verlet.reflection_blocks(cmat)
    work = tuple(np.zeros(n) for n in (blocks[0].shape[1], blocks[1].shape[1], blocks[0].shape[0], blocks[1].shape[0]))
    out = np.zeros(cmat.shape[0])
    verlet._mirror_product(*blocks, cmat.shape[0], w, *work, out)
    return out


@pytest.mark.parametrize("n_links", [3, 4, 7, 8, 85])
@pytest.mark.parametrize("rayleigh", [None, (3.0, 2e-5)])
def test_the_damping_product_in_reflection_blocks_equals_the_whole_matrix(n_links, rayleigh):
    if verlet.numba is None:
        pytest.skip("numba not installed: the blocks serve the compiled path only")
    cmat = ClearanceChain(_chain(n=n_links, rayleigh_coefficients=rayleigh), 94e-6).damping_matrix
    sym, anti = verlet.reflection_blocks(cmat)
    pairs = (n_links - 1) // 2
    assert anti.shape[0] >= pairs > 0 and sym.shape[0] >= n_links - pairs  # the chain is symmetric: two blocks
    if n_links == 85:  # padded blocks: 4224 multiply-adds against 7225
        assert sym.size + anti.size < 0.6 * n_links**2
    w = np.random.default_rng(n_links).standard_normal(n_links)
    np.testing.assert_allclose(_blocked(cmat, w), cmat @ w, rtol=0, atol=1e-13 * np.abs(cmat).max() * np.abs(w).sum())


def test_a_damping_matrix_without_the_mirror_symmetry_is_multiplied_whole():
    if verlet.numba is None:
        pytest.skip("numba not installed: the blocks serve the compiled path only")
    rng = np.random.default_rng(1)
    cmat = rng.standard_normal((9, 9))
    cmat = cmat + cmat.T
    sym, anti = verlet.reflection_blocks(cmat)
    assert anti.shape[0] == 0 and sym.shape[0] >= 9
    w = rng.standard_normal(9)
    np.testing.assert_allclose(_blocked(cmat, w), cmat @ w, rtol=1e-13)


def test_the_friction_law_of_both_paths_is_tanh_to_the_last_bit_of_one_and_saturates_exactly():
    """The steps evaluate tanh from one exp (`_tanh_array`, numpy) or in arithmetic
    (`_tanh_branch_free`, compiled), not the library's tanh: within 2.3e-16 (one ulp of 1, so within
    2.3e-16 F_c of the law), and exactly +-1 where the compiled step takes it without computing it
    (|x| >= TANH_IS_ONE)."""
    import math

    x = np.concatenate(
        [
            np.linspace(-40, 40, 80001),
            np.geomspace(1e-300, 1e-3, 50),
            -np.geomspace(1e-300, 1e-3, 50),
            [0.0, verlet.TANH_IS_ONE, np.nextafter(verlet.TANH_IS_ONE, 0), 800.0, np.inf, -np.inf],
        ]
    )
    exact = np.tanh(x)
    assert np.max(np.abs(verlet._tanh_array(x) - exact)) <= 2.3e-16
    saturated = np.abs(x) >= verlet.TANH_IS_ONE
    assert np.all(verlet._tanh_array(x[saturated]) == np.sign(x[saturated]))
    assert math.tanh(verlet.TANH_IS_ONE) == 1.0
    if verlet.numba is None:
        return
    scalar = np.array([verlet._tanh_branch_free(float(v)) for v in x[::17]])
    assert np.max(np.abs(scalar - exact[::17])) <= 2.3e-16
    fc, inv_vs = 7.0, 200.0
    par = np.zeros(13)
    par[6], par[7] = fc, inv_vs
    w = np.concatenate([np.linspace(-0.2, 0.2, 4001), x[saturated][:50] / inv_vs])
    fr = np.empty_like(w)
    power = verlet._friction_into(0.01, w, par, fr)
    # the tanh bound times F_c, and the two products' roundings (half an ulp of F_c each)
    np.testing.assert_allclose(fr, -fc * np.tanh((0.01 + w) * inv_vs), rtol=0, atol=2.3e-16 * fc + np.spacing(fc))
    assert np.all(
        fr[np.abs((0.01 + w) * inv_vs) >= verlet.TANH_IS_ONE]
        == -fc * np.sign(0.01 + w)[np.abs((0.01 + w) * inv_vs) >= verlet.TANH_IS_ONE]
    )
    assert power == pytest.approx(np.sum(fc * np.tanh((0.01 + w) * inv_vs) * (0.01 + w)), rel=1e-12)


@pytest.mark.parametrize("zeta", [0.0, 0.13, 0.5])
def test_step_stability_limit_both_sides(zeta):
    limit = verlet.stable_omega_h(zeta)
    assert verlet.spectral_radius(0.99 * limit, zeta) <= 1.0 + 1e-12
    assert verlet.spectral_radius(1.01 * limit, zeta) > 1.0
    if zeta == 0.0:
        assert limit == pytest.approx(2.0)


@pytest.mark.parametrize("zeta", [0.0, 0.13, 0.5])
def test_ab2_predictor_stability_limit_both_sides_and_below_euler(zeta):
    limit = verlet.stable_omega_h(zeta, "ab2")
    assert verlet.spectral_radius(0.99 * limit, zeta, "ab2") <= 1.0 + 1e-12
    assert verlet.spectral_radius(1.01 * limit, zeta, "ab2") > 1.0
    assert limit <= verlet.stable_omega_h(zeta) + 1e-12


def test_ab2_predictor_linear_chain_diverges_just_above_its_limit_and_not_just_below():
    model = ClearanceChain(_chain(n=8), 0.0)
    h_limit = verlet.stable_step_s(model, safety=1.0, predictor="ab2")
    n = 4000
    for factor, diverges in ((0.99, False), (1.01, True)):
        h = factor * h_limit
        tf = h * np.arange(n + 1)
        _, v, a, _ = _cam().svaj(tf)

        def run(v=v, a=a, h=h):
            return verlet.integrate(model, v, a, h, np.zeros(8), -v[0] * np.ones(8), out_every=n, predictor="ab2")

        if diverges:
            with pytest.raises(SolverDivergedError, match="diverged"):
                run()
        else:
            assert np.all(np.isfinite(run().y))


def test_ab2_predictor_changes_the_run_and_is_refused_for_kelvin_voigt():
    model = ClearanceChain(_chain(n=6, friction_coefficient=0.35), 94e-6, tensioner=Tensioner(2e5, 3.0, 50.0))
    euler, ab2 = _short_run(model), _short_run(model, "ab2")
    assert np.max(np.abs(euler.y - ab2.y)) > 1e-9 * np.max(np.abs(euler.y))  # the option is not ignored
    with pytest.raises(DynamicsError, match="predictor"):
        _short_run(ClearanceChain(_chain(n=6), 94e-6, span_damping="kelvin-voigt"), "ab2")
    with pytest.raises(DynamicsError, match="predictor"):
        _short_run(model, "rk4")


def _final_state(model, h, duration):
    n = int(round(duration / h))
    tf = h * np.arange(n + 1)
    _, v, a, _ = _cam().svaj(tf)
    return verlet.integrate(model, v, a, h, np.zeros(8), -v[0] * np.ones(8), out_every=n).y[-1]


def test_linear_chain_diverges_just_above_the_step_limit_and_not_just_below():
    model = ClearanceChain(_chain(n=8), 0.0)
    h_limit = verlet.stable_step_s(model, safety=1.0)
    assert np.all(np.isfinite(_final_state(model, 0.99 * h_limit, 4000 * h_limit)))
    with pytest.raises(SolverDivergedError, match="diverged"):
        _final_state(model, 1.01 * h_limit, 4000 * h_limit)


def test_free_play_hides_an_unstable_step_it_does_not_blow_up_but_is_wrong():
    """Above the limit the growing top mode opens spans into free play, which bounds it: the run
    finishes with nonsense instead of diverging, so the step must come from the full-contact
    frequency (stable_step_s), never from a divergence check."""
    model = ClearanceChain(_chain(n=8), 94e-6)
    h_limit = verlet.stable_step_s(model, safety=1.0)
    duration = 4000 * h_limit
    ref = _final_state(model, h_limit / 64, duration)
    scale = np.max(np.abs(ref))
    assert np.max(np.abs(_final_state(model, 0.99 * h_limit, duration) - ref)) < 0.02 * scale
    assert np.max(np.abs(_final_state(model, 1.01 * h_limit, duration) - ref)) > 1.0 * scale


def test_no_steady_state_is_said_plainly_never_claimed():
    chain = _chain(n=30, friction_coefficient=0.35)
    _, s = simulate_chain(ClearanceChain(chain, 94e-6), _cam(), _times(), max_cycles=1)
    assert not s.steady_state.found and s.steady_state.period_cycles is None
    assert s.steady_state.statement.startswith("NO periodic steady state")


def test_steady_state_repeats_after_one_period():
    chain = _chain(n=30, friction_coefficient=0.35)
    t = _times(degrees=180.0, per_degree=4)  # two cam periods
    r, s = simulate_chain(ClearanceChain(chain, 94e-6), _cam(), t)
    assert s.model == "clearance" and s.steady_state.found and s.steady_state.cycles >= 2
    half = (t.size - 1) // 2
    y = r.x_m - r.z_m[:, None]
    np.testing.assert_allclose(y[half], y[0], rtol=0, atol=1e-5 * np.max(np.abs(y)))


@pytest.mark.parametrize("predictor", ["euler", "ab2"])
def test_stability_map_both_sides_of_the_limit(predictor):
    """Map cases (verification.clearance_stability) at 1e8 N/m, each predictor at its own limit (ab2: the
    default run's): without free play the limit is sharp; with it a step just above the limit finishes
    and is wrong instead of diverging, and far above it diverges."""
    from verification.clearance_stability import step_case

    assert step_case(1e8, 0.0, 0.99, predictor=predictor).outcome == "accurate"
    assert step_case(1e8, 0.0, 1.01, predictor=predictor).outcome == "diverged"
    assert step_case(1e8, 94e-6, 0.99, predictor=predictor).outcome == "accurate"
    assert step_case(1e8, 94e-6, 1.1, predictor=predictor).outcome == "inaccurate"
    assert step_case(1e8, 94e-6, 2.0, predictor=predictor).outcome == "diverged"


def test_the_default_run_takes_ab2_for_the_global_law_and_euler_for_kelvin_voigt():
    chain = _chain(n=30, friction_coefficient=0.35)
    t = _times(degrees=20.0, per_degree=4)
    for law, predictor in (("global", "ab2"), ("kelvin-voigt", "euler")):
        model = ClearanceChain(chain, 94e-6, span_damping=law)
        assert verlet.default_predictor(model) == predictor
        _, s = simulate_chain(model, _cam(), t, steady_state=False)
        h_limit = verlet.stable_step_s(model, 1.0, predictor)
        start = verlet.substeps_for(model, t[1], verlet.default_safety(model, predictor), predictor)
        assert s.steps_per_output == start and s.step_error_estimate is None
        assert (t[1] / s.steps_per_output) <= verlet.default_safety(model, predictor) * h_limit * (1 + 1e-12)
        # with an accuracy: that step halved until the metrics change by at most it
        _, s = simulate_chain(model, _cam(), t, steady_state=False, accuracy=1e-3)
        doublings = round(math.log2(s.steps_per_output / start))
        assert s.steps_per_output == start * 2**doublings and 1 <= doublings <= MAX_STEP_DOUBLINGS
        assert s.step_error_estimate <= 1e-3 or doublings == MAX_STEP_DOUBLINGS


def _fake_period_map(flip_every: int):
    """An integrator whose period map repeats after `flip_every` periods (a stand-in for a
    subharmonic response; the detection logic is what is tested here)."""
    calls = {"n": 0}

    def integrate(model, zd, zdd, h, y0, w0, *, u0=0.0, ud0=0.0, out_every=1, **_):
        calls["n"] += 1
        phase = calls["n"] % flip_every
        y_end = np.full(model.n_links, 1e-3 * (1 + phase))
        rows = np.vstack([np.asarray(y0, dtype=float), y_end])
        zeros = np.zeros_like(rows)
        return verlet.Run(
            rows, zeros + 0.1, zeros, np.zeros(2), np.zeros(2), 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, h, 1
        )

    return integrate


@pytest.mark.parametrize("k, found", [(2, True), (3, True), (7, False)])
def test_subharmonic_is_detected_and_named_and_chaos_is_not_called_a_steady_state(monkeypatch, k, found):
    from dynamics import scene

    monkeypatch.setattr(scene.verlet, "integrate", _fake_period_map(k))
    model = ClearanceChain(_chain(n=4), 94e-6)
    state = (np.zeros(4), np.zeros(4), 0.0, 0.0)
    _, ss = scene._periodic_state(model, _cam(), 0.0, 1e-4, state, 1e-6, 20)
    assert ss.found is found
    if found:
        assert ss.period_cycles == k and f"every {k} cam cycles" in ss.statement
    else:
        assert ss.period_cycles is None and ss.statement.startswith("NO periodic steady state")


@pytest.mark.parametrize(
    "method, options", [("rk45", {"rtol": 1e-7, "atol": 1e-12}), ("central-difference", {"dt": None})]
)
def test_the_common_solver_interface_solves_the_same_clearance_chain(method, options):
    """ClearanceChain.system(): the span law as a nonlinear force on the linear chain, solved by the
    existing methods (dynamics.solvers.solve), agrees with the fast integrator."""
    chain = _chain(n=8, friction_coefficient=0.0, preload_N=300.0)
    model = ClearanceChain(chain, 94e-6)
    t = _times(degrees=45.0, per_degree=2)
    _, v, a, _ = _cam().svaj(t)
    sub = 64
    if method == "central-difference":
        options = {"dt": (t[1] - t[0]) / sub}
    r = solve(
        model.system(),
        SampledForce(t, chain.base_excitation_force(a)),
        t,
        method=method,
        x0=np.zeros(8),
        v0=-v[0] * np.ones(8),
        **options,
    )
    fast = _integrate_held(model, t, v, a, sub)
    assert fast.impacts > 5
    scale = np.max(np.abs(r.x))
    assert np.max(np.abs(fast.y - r.x)) < 1e-3 * scale
    with pytest.raises(DynamicsError, match="global damping"):
        ClearanceChain(chain, 94e-6, span_damping="kelvin-voigt").system()


def _former_packed_parameters(model, bound):
    """The ring's packing as it was built before it was read from the topology: straight from the
    chain and the tensioner (the oracle for `packed_parameters`)."""
    c, t = model.chain, model.tensioner
    par = np.array(
        [
            c.link_mass_kg,
            c.stiffness_N_per_m,
            c.drive_stiffness,
            c.preload_N,
            c.stiffness_N_per_m * model.clearance_m,
            model.beta_s,
            c.coulomb_force_N,
            1.0 / c.friction_velocity_scale_m_s,
            t.mass_kg if t else 1.0,
            t.rate_N_per_m if t else 0.0,
            t.damping_N_s_per_m if t else 0.0,
            2.0 * c.preload_N,
            bound,
        ]
    )
    kv = model.span_damping == "kelvin-voigt"
    ipar = [model.idler_span, int(t is not None), int(kv), int(not kv and model.damping_is_reduced)]
    return par, np.array(ipar, dtype=np.int64)


@pytest.mark.parametrize("damping", ["global", "kelvin-voigt"])
@pytest.mark.parametrize("tensioner", [None, Tensioner(2e5, 3.0, 50.0)])
@pytest.mark.parametrize("n_links", [7, 8])
def test_the_rings_packing_read_from_its_topology_is_the_chains_bit_for_bit(damping, tensioner, n_links):
    """packed_parameters reads the masses, stiffnesses, preload, idler span and carriage from the
    ring's topology (clearance_verlet.ring_packing on ChainTopology.span_arrays, the machine's
    packing of the spans too): the same numbers, bit for bit, as read from the chain and the
    tensioner, odd and even N, both laws, with and without the carriage (a drive stiffness of its own)."""
    chain = _chain(n=n_links, friction_coefficient=0.35, drive_stiffness_N_per_m=3e7)
    model = ClearanceChain(chain, 94e-6, span_damping=damping, tensioner=tensioner)
    par, ipar, _ = verlet.packed_parameters(model, 1.0)
    old_par, old_ipar = _former_packed_parameters(model, 1.0)
    assert np.array_equal(par, old_par)
    assert np.array_equal(ipar, old_ipar)


def test_the_rings_packing_refuses_a_topology_that_is_not_a_ring():
    """ring_packing: the ring's step takes only the ring's topology; a chain on wheels (links held on
    a sprocket, spans to wheel DOFs) is refused with the reason."""
    from dynamics.models.layout import MachineLayout
    from dynamics.models.wheels import Wheel

    wheels = MachineLayout("wheels", Wheel(12, 0.1125, 6, 0.1), Wheel(12, 0.1125, 6, 0.1), None, True)
    topology = wheels.machine(_chain(n=40), None).topology
    with pytest.raises(DynamicsError, match="expected a ring topology"):
        verlet.ring_packing(topology)
    assert verlet.ring_packing(_chain(n=40).topology()).idler_span is None
