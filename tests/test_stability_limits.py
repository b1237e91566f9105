"""Stability: the central-difference limit on both sides, unconditional stability of Newmark, the map's
outcomes, and the default solver across stiffness 1e5..1e10 N/m against independent references."""

import warnings

import numpy as np
import pytest

from dynamics.cams.program import CamProgram
from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.models.chain import ChainModel
from dynamics.response.sweep import cam_cycle_samples, chain_modes, modal_periodic_response
from dynamics.solvers import solve
from dynamics.solvers.simulate import SlackChainWarning, simulate
from verification.stability import (
    central_difference_limit_s,
    central_difference_spectral_radius,
    classify,
    stability_map,
)
from verification.workprecision import chain_problem, reference_response


def run(problem, method, **opts):
    return solve(problem.system, problem.force, problem.t_eval_s, method=method, x0=problem.x0, v0=problem.v0, **opts).x


def on_step_grid(problem, step):
    """Outputs every `step` s over the problem's span, so the solver's step is exactly `step` (it splits
    each output interval into whole steps, which would otherwise shrink a step just above the limit)."""
    t = np.arange(0.0, problem.t_eval_s[-1], step)
    return lambda method, **opts: (
        solve(problem.system, problem.force, t, method=method, x0=problem.x0, v0=problem.v0, **opts).x
    )


@pytest.mark.parametrize("stiffness", [1e6, 9e7, 1e10])
def test_central_difference_just_below_the_limit_is_bounded_and_accurate(stiffness):
    # At 0.99 of 2/omega_max only the top modes sit near omega dt = 2, and the cam's uniform base
    # excitation barely reaches them; the excited low modes have omega dt << 1, where the scheme's
    # phase error is (omega dt)^2 / 24. 1 % of the peak response is a loose bound on that.
    problem = chain_problem(20, stiffness_N_per_m=stiffness, cycles=1)
    step = 0.99 * central_difference_limit_s(problem.system)
    run_at = on_step_grid(problem, step)
    ref = run_at("exact")
    x = run_at("central-difference", dt=step)
    assert np.max(np.abs(x - ref)) <= 1e-2 * np.max(np.abs(ref))


@pytest.mark.parametrize("stiffness", [1e6, 9e7, 1e10])
def test_central_difference_just_above_the_limit_is_refused(stiffness):
    problem = chain_problem(20, stiffness_N_per_m=stiffness, cycles=1)
    step = 1.01 * central_difference_limit_s(problem.system)
    with pytest.raises(SolverDivergedError, match="stability limit"):
        on_step_grid(problem, step)("central-difference", dt=step)


def test_limit_matches_the_chain_top_frequency():
    # omega_max of the ring with the drive spring lies just above 2 sqrt(k/m), the free ring's top
    model = ChainModel(20, 2.0, 9e7)
    limit = central_difference_limit_s(model.system())
    assert limit == pytest.approx(2.0 / model.modes()[0][-1], rel=1e-12)
    assert 0.9 < limit * np.sqrt(9e7 / 2.0) <= 1.0


def test_spectral_radius_on_both_sides_of_the_limit():
    assert central_difference_spectral_radius(1.99) == pytest.approx(1.0)
    assert central_difference_spectral_radius(2.0) == pytest.approx(1.0)
    assert central_difference_spectral_radius(2.01) > 1.1


def test_undamped_central_difference_recurrence_grows_only_above_the_limit():
    # Independent of the solver's refusal: step one undamped mode by the bare recurrence
    # x+ = (2 - (w dt)^2) x - x- and watch the amplitude. Below w dt = 2 it stays at its initial
    # size (|x| <= 1/sin(theta/2) for the neutral oscillation); above, it grows by the spectral radius.
    for wdt, grows in ((1.99, False), (2.01, True)):
        x_prev, x = 1.0, 1.0
        peak = 1.0
        for _ in range(2000):
            x_prev, x = x, (2.0 - wdt**2) * x - x_prev
            peak = max(peak, abs(x))
        rho = float(central_difference_spectral_radius(wdt))
        if grows:
            assert peak > 0.1 * rho**2000
        else:
            assert peak < 20.0


def test_newmark_is_bounded_far_above_the_explicit_limit():
    # Average acceleration is unconditionally stable: at a step 60x the central-difference limit
    # (k = 1e10) it stays bounded; its error is the period error of the modes it cannot resolve.
    problem = chain_problem(20, stiffness_N_per_m=1e10, cycles=1)
    ref = reference_response(problem)
    dt = problem.output_step_s
    assert dt > 50 * central_difference_limit_s(problem.system)
    x = run(problem, "newmark", dt=dt)
    assert np.max(np.abs(x)) < 1.5 * np.max(np.abs(ref))


def test_classify_outcomes():
    problem = chain_problem(10, stiffness_N_per_m=1e8, cycles=1)
    ref = reference_response(problem)
    limit = central_difference_limit_s(problem.system)
    assert classify(problem, "central-difference", "dt_s", 2 * limit, ref).outcome == "diverged"
    assert classify(problem, "central-difference", "dt_s", 0.5 * limit, ref).outcome == "accurate"
    coarse = classify(problem, "newmark", "dt_s", problem.output_step_s, ref, accuracy=1e-3)
    assert coarse.outcome == "inaccurate" and coarse.relative_error > 1e-3
    assert classify(problem, "exact", "", np.nan, ref).relative_error < 1e-12
    with pytest.raises(DynamicsError, match="accuracy"):
        classify(problem, "exact", "", np.nan, ref, accuracy=2.0)


def test_stability_map_coarse():
    cases = stability_map(("central-difference", "exact"), (1e6, 1e10), (10,), quick=True)
    for c in cases:
        if c.method == "exact":
            assert c.outcome == "accurate"
        else:  # both sides of the limit, as the map draws it
            assert c.outcome == ("diverged" if c.parameter > c.central_difference_limit_s else "accurate")
    assert {c.outcome for c in cases} == {"accurate", "diverged"}


@pytest.mark.parametrize("stiffness", [1e5, 1e6, 1e7, 1e8, 1e9, 1e10])
def test_default_solver_right_at_every_stiffness(stiffness):
    # The default path (simulate, exact, periodic steady state) against closed-form modal
    # superposition solved by DFT (dynamics.response.sweep): independent algebra, same discretisation, so
    # they agree to rounding (measured <= 2e-11 relative) at every stiffness.
    model = ChainModel(85, 2.0, stiffness)
    program = CamProgram.indexing("modified-sine")
    n = 90
    t = program.cycle_s * np.arange(n + 1) / n
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SlackChainWarning)
        r = simulate(model, program, t, links=[0, 63])
    _, zdd, _ = cam_cycle_samples("modified-sine", n, pitch_m=0.1125, index_deg=45, dwell_deg=45, rpm=180)
    y, a = modal_periodic_response(chain_modes(model), zdd, t[1], [0, 63])
    y_sim = (r.x_m - r.z_m[:, None])[:-1]
    assert np.max(np.abs(y - y_sim)) <= 1e-8 * np.max(np.abs(y_sim))
    assert np.max(np.abs(a - r.a_m_s2[:-1])) <= 1e-8 * np.max(np.abs(r.a_m_s2))


@pytest.mark.parametrize("stiffness", [1e5, 1e10])
def test_default_solver_against_a_fine_implicit_solve(stiffness):
    # A second, integrator-based reference: Radau IIA at rtol 1e-8 from rest. Its own error is
    # ~1e-9 relative (stability map, 10 and 85 links), so 1e-6 leaves a wide margin.
    problem = chain_problem(10, stiffness_N_per_m=stiffness, cycles=1)
    x_exact = run(problem, "exact")
    x_radau = run(problem, "radau", rtol=1e-8, atol=1e-8 * 1e-3 * np.max(np.abs(x_exact)))
    assert np.max(np.abs(x_exact - x_radau)) <= 1e-6 * np.max(np.abs(x_exact))
