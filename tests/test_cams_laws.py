import math

import numpy as np
import pytest

from dynamics.cams import MotionLaw, get_law, law_ids, register_law
from dynamics.cams.laws import MODIFIED_SINE_CA, MODIFIED_TRAPEZOID_CA
from dynamics.errors import DynamicsError

LAWS = ("modified-sine", "modified-trapezoid", "cycloidal", "poly-345", "poly-4567", "simple-harmonic")
# Segment joints of the piecewise laws (x in [0, 1]).
JOINTS = {
    "modified-sine": (1 / 8, 7 / 8),
    "modified-trapezoid": (1 / 8, 3 / 8, 5 / 8, 7 / 8),
}
# Laws whose jerk is continuous inside the rise (the handbook's piecewise laws are built so; the
# polynomials and single harmonics are smooth).
JERK_CONTINUOUS = {"modified-sine", "modified-trapezoid"}


def test_registry_holds_the_pipeline_ids():
    assert set(LAWS) <= set(law_ids())


def test_unknown_law_is_a_dynamics_error_naming_it():
    with pytest.raises(DynamicsError, match="no-such-law"):
        get_law("no-such-law")


def test_duplicate_registration_is_refused():
    with pytest.raises(DynamicsError, match="already registered"):
        register_law(MotionLaw("cycloidal", "again", get_law("cycloidal").svaj, True))


def test_exact_peak_acceleration_constants():
    assert MODIFIED_TRAPEZOID_CA == pytest.approx(8 * math.pi / (math.pi + 2), rel=1e-15)
    assert MODIFIED_SINE_CA == pytest.approx(4 * math.pi**2 / (4 + math.pi), rel=1e-15)


@pytest.mark.parametrize("law_id", LAWS)
def test_end_values(law_id):
    law = get_law(law_id)
    s, v, a, _ = law.svaj(np.array([0.0, 1.0]))
    # Built from exact constants, the ends are exact up to a few roundings of O(1) numbers.
    assert s[0] == pytest.approx(0.0, abs=1e-15)
    assert s[1] == pytest.approx(1.0, abs=1e-15)
    assert np.allclose(v, 0.0, atol=1e-15)
    if law.zero_end_acceleration:
        assert np.allclose(a, 0.0, atol=1e-14)


@pytest.mark.parametrize("law_id", sorted(JOINTS))
def test_piecewise_laws_are_continuous_at_their_joints(law_id):
    law = get_law(law_id)
    for x in JOINTS[law_id]:
        left = law.svaj(np.array([np.nextafter(x, 0.0)]))
        right = law.svaj(np.array([x]))
        # One ulp step in x moves s, v, a by at most |derivative| * 1e-16 (J <= 70); what remains
        # is rounding of O(1..70) quantities, so 1e-15 relative to each quantity's peak scale.
        for k, (l, r, scale) in enumerate(zip(left, right, (1.0, 2.0, 6.0, 70.0))):
            if k == 3 and law_id not in JERK_CONTINUOUS:
                continue
            assert abs(l[0] - r[0]) <= 2e-15 * scale, (law_id, x, k)


def _central_difference(f, x, h):
    """Sixth-order central difference; truncation error h^6 |f^(7)| / 140."""
    c = np.array([-1 / 60, 3 / 20, -3 / 4, 0.0, 3 / 4, -3 / 20, 1 / 60])
    return sum(ck * f(x + (k - 3) * h) for k, ck in enumerate(c)) / h


@pytest.mark.parametrize("law_id", LAWS)
def test_v_a_j_are_the_derivatives_of_s(law_id):
    law = get_law(law_id)
    h = 1e-3
    x = np.linspace(0.0, 1.0, 401)[1:-1]
    joints = np.array(JOINTS.get(law_id, ()))
    if joints.size:  # the stencil must not straddle a joint, where higher derivatives jump
        x = x[np.min(np.abs(x[:, None] - joints[None, :]), axis=1) > 3.5 * h]
    for k in range(3):
        numeric = _central_difference(lambda y: law.svaj(y)[k], x, h)  # noqa: B023 (called at once)
        exact = law.svaj(x)[k + 1]
        # Truncation: h^6 max|f^(7)| / 140 <= 1e-18 * (4 pi)^7 * 70 / 140 ~ 2.5e-11 for the fastest
        # harmonic (4 pi); rounding: ~eps * |f| / h ~ 1e-12 * 70. Both well under 1e-9.
        assert np.max(np.abs(numeric - exact)) < 1e-9, (law_id, k)


PEAKS = {  # (Cv, Ca, Cj) as printed in Norton's handbook / the field notes
    "modified-trapezoid": (2.0, 4.8881, 61.426),
    "modified-sine": (1.7596, 5.5280, 69.466),
    "cycloidal": (2.0, 6.2832, 39.478),
    "poly-345": (1.875, 5.7735, 60.0),
    "poly-4567": (2.1875, 7.5132, 52.5),
}


@pytest.mark.parametrize("law_id", sorted(PEAKS))
def test_peak_coefficients(law_id):
    # Spacing 2.5e-6: a smooth maximum is missed by at most |f''| dx^2 / 8 < 1e-8 (|f''| < 1e4 for
    # jerk), far below the printed digits; kinks (jerk at joints) lie on the grid.
    x = np.linspace(0.0, 1.0, 400_001)
    _, v, a, j = get_law(law_id).svaj(x)
    for computed, printed in zip((np.abs(v).max(), np.abs(a).max(), np.abs(j).max()), PEAKS[law_id]):
        # Printed to 5 significant digits: half a unit in the last place.
        assert computed == pytest.approx(printed, abs=0.5 * 10 ** (math.floor(math.log10(printed)) - 4))
