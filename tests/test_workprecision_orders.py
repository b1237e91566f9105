"""Claims of the work-precision chart on coarse settings: the reference, each method's convergence order,
modal truncation, tolerances, the force-sampling floor."""

import numpy as np
import pytest

from dynamics.errors import DynamicsError
from dynamics.solvers import solve
from verification.stability import central_difference_limit_s
from verification.workprecision import (
    chain_problem,
    force_sampling_error,
    measure,
    observed_order,
    reference_response,
    settings,
    work_precision,
)


@pytest.fixture(scope="module")
def problem():
    return chain_problem(10, cycles=1)


@pytest.fixture(scope="module")
def ref(problem):
    return reference_response(problem)


def errors(problem, ref, method, name, values):
    return [measure(problem, method, ref, name, v).error_m for v in values]


def test_reference_agrees_with_modal_superposition(problem, ref):
    # two exact formulations of the same discretised problem (matrix exponential vs eigenmodes):
    # rounding only, ~1e-14 relative measured
    x_modal = solve(problem.system, problem.force, problem.t_eval_s, method="modal", x0=problem.x0, v0=problem.v0).x
    assert np.max(np.abs(x_modal - ref)) <= 1e-11 * np.max(np.abs(ref))


def test_exact_is_at_roundoff(problem, ref):
    err = measure(problem, "exact", ref).error_m
    assert err <= 1e-12 * np.max(np.abs(ref))


@pytest.mark.parametrize("method", ["newmark", "hht"])
def test_implicit_fixed_step_methods_are_second_order(problem, ref, method):
    # trapezoidal / HHT (alpha -0.05, gamma = 1/2 - alpha keeps second order): error ~ dt^2
    h = problem.output_step_s
    dts = [h / 4, h / 8, h / 16]
    order = observed_order(dts, errors(problem, ref, method, "dt_s", dts))
    assert 1.8 < order < 2.2


def test_central_difference_is_second_order(problem, ref):
    limit = central_difference_limit_s(problem.system)
    dts = [0.5 * limit, 0.25 * limit, 0.125 * limit]
    order = observed_order(dts, errors(problem, ref, "central-difference", "dt_s", dts))
    assert 1.8 < order < 2.2


def test_modal_truncation_error_falls_with_modes(problem, ref):
    errs = errors(problem, ref, "modal", "n_modes", [1, 3, 6, 10])
    assert errs[0] > errs[1] > errs[2] > errs[3]
    assert errs[3] <= 1e-11 * np.max(np.abs(ref))  # all 10 modes: exact


@pytest.mark.parametrize("method", ["rk45", "radau", "report-rk45"])
def test_error_falls_as_tolerance_tightens(problem, ref, method):
    loose, tight = errors(problem, ref, method, "rtol", [1e-3, 1e-7])
    assert tight < loose
    assert tight <= 1e-5 * np.max(np.abs(ref))


def test_force_sampling_floor_is_second_order():
    # the first-order hold interpolates z'' with error ~ h^2 f'' / 8: halving the sample spacing cuts
    # the response error ~4x (the cam's jerk jumps make it a little less clean: 3..5)
    coarse = force_sampling_error(chain_problem(10, cycles=1, samples_per_degree=1))
    fine = force_sampling_error(chain_problem(10, cycles=1, samples_per_degree=2))
    assert 3.0 < coarse / fine < 5.0


def test_diverged_runs_are_recorded_not_raised(problem, ref):
    limit = central_difference_limit_s(problem.system)
    m = measure(problem, "central-difference", ref, "dt_s", 2 * limit)
    assert m.status == "diverged" and np.isnan(m.error_m)


def test_work_precision_runs_every_setting(problem):
    ms = work_precision(problem, ("exact", "newmark"), quick=True)
    assert len(ms) == 1 + len(settings("newmark", problem, quick=True)[1])
    assert all(m.status == "ok" and m.wall_s > 0 for m in ms)
    with pytest.raises(DynamicsError, match="method"):
        work_precision(problem, ("no-such-method",))


def test_observed_order_checks_input():
    assert observed_order([1, 2, 4], [1, 4, 16]) == pytest.approx(2.0)
    with pytest.raises(DynamicsError):
        observed_order([1.0], [1.0])
