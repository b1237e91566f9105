import numpy as np
import pytest

from fem import FemError, extrapolate
from fem.richardson import SINGULAR_RATE, observed_rate


def levels(k_inf, c, p, dofs):
    h = np.asarray(dofs, float) ** (-1 / 3)
    return k_inf + c * h**p


def test_three_levels_recover_rate_and_limit_exactly():
    dofs = [40_000, 90_000, 200_000]
    k = levels(9.0e7, 4.0e9, 1.2, dofs)
    fit = extrapolate(k, dofs)
    assert fit.observed_rate == pytest.approx(1.2, abs=1e-8)
    assert fit.rate == pytest.approx(1.2, abs=1e-8)
    assert fit.extrapolated == pytest.approx(9.0e7, rel=1e-10)
    assert fit.rel_error_estimate == pytest.approx((k[-1] - 9.0e7) / 9.0e7, rel=1e-6)


def test_observed_rate_above_the_singular_rate_is_capped():
    # A faster observed rate is pre-asymptotic on a part with singular edges: the cap makes the
    # error estimate larger (safer), not smaller.
    dofs = [40_000, 90_000, 200_000]
    k = levels(9.0e7, 4.0e9, 3.0, dofs)
    fit = extrapolate(k, dofs)
    assert fit.observed_rate == pytest.approx(3.0, abs=1e-8)
    assert fit.rate == SINGULAR_RATE
    assert fit.rel_error_estimate > (k[-1] - 9.0e7) / 9.0e7


def test_two_levels_use_the_singular_rate():
    dofs = [50_000, 150_000]
    k = levels(1.0e8, 1.0e10, SINGULAR_RATE, dofs)
    fit = extrapolate(k, dofs)
    assert fit.observed_rate is None
    assert fit.extrapolated == pytest.approx(1.0e8, rel=1e-12)


def test_oscillating_levels_report_their_scatter():
    fit = extrapolate([1.00e8, 0.98e8, 0.99e8], [1e4, 3e4, 9e4])
    assert not fit.monotone and fit.observed_rate is None
    assert fit.rel_error_estimate >= 0.02e8 / fit.extrapolated


def test_observed_rate_none_when_not_monotone():
    assert observed_rate(np.array([1.0, 0.9, 0.95]), np.array([1.0, 0.5, 0.25])) is None


@pytest.mark.parametrize("k, dofs", [([1.0], [10]), ([1.0, 2.0], [20, 10]), ([1, 2, 3, 4], [1, 2, 3, 4])])
def test_bad_levels_are_fem_errors(k, dofs):
    with pytest.raises(FemError):
        extrapolate(k, dofs)
