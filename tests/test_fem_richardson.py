import numpy as np
import pytest

from fem import FemError, extrapolate
from fem.richardson import observed_rate, rate_bracket


def levels(k_inf, c, p, dofs):
    h = np.asarray(dofs, float) ** (-1 / 3)
    return k_inf + c * h**p


def test_reported_value_is_the_middle_of_the_bracket_and_the_estimate_its_half_width():
    dofs = [40_000, 90_000]
    k = levels(9.0e7, 4.0e9, 1.5, dofs)
    h = np.asarray(dofs, float) ** (-1 / 3)
    r = h[0] / h[1]
    ends = [k[1] - (k[0] - k[1]) / (r**p - 1) for p in (1.0, 5.0)]
    fit = extrapolate(k, dofs)
    assert fit.rate_bracket == (1.0, 5.0) == rate_bracket(2)
    assert fit.extrapolated == pytest.approx(0.5 * sum(ends), rel=1e-12)
    assert fit.rel_error_estimate == pytest.approx(0.5 * abs(ends[0] - ends[1]) / fit.extrapolated, rel=1e-9)
    assert fit.finest_rel_error_estimate == pytest.approx((k[-1] - fit.extrapolated) / fit.extrapolated, rel=1e-9)


# The bracket [1, 2 x order + 1]: from a sharp re-entrant edge's h^1.09 (and the clamp rim's
# h^1.42) to the smooth rate of P2 energy, h^4, which the Lame cylinder shows (as h^4.15 in
# h = DOFs^(-1/3)). The old estimate (p = 1.5, error from p in [1, 2]) did not bound rates above 2
# at these level ratios.
@pytest.mark.parametrize("true_rate", [1.0, 1.09, 1.3, 1.8, 2.0, 3.0, 4.0, 5.0])
@pytest.mark.parametrize("n_levels", [2, 3])
def test_error_estimate_bounds_the_true_error_for_any_rate_in_the_bracket(true_rate, n_levels):
    dofs = [30_000, 70_000, 160_000][-n_levels:]
    k = levels(9.0e7, 6.0e9, true_rate, dofs)
    fit = extrapolate(k, dofs)
    assert abs(fit.extrapolated - 9.0e7) / fit.extrapolated <= fit.rel_error_estimate * (1 + 1e-9)


def test_p1_bracket_is_one_to_three():
    assert rate_bracket(1) == (1.0, 3.0)
    dofs = [30_000, 70_000]
    for p in (1.0, 2.0, 3.0):
        k = levels(9.0e7, 6.0e9, p, dofs)
        fit = extrapolate(k, dofs, rate_bracket(1))
        assert abs(fit.extrapolated - 9.0e7) / fit.extrapolated <= fit.rel_error_estimate * (1 + 1e-9)


def test_observed_rate_is_recovered_from_three_levels():
    dofs = [40_000, 90_000, 200_000]
    assert extrapolate(levels(1.0, 30.0, 1.2, dofs), dofs).observed_rate == pytest.approx(1.2, abs=1e-8)
    assert extrapolate(levels(1.0, 30.0, 1.2, dofs[:2]), dofs[:2]).observed_rate is None


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
