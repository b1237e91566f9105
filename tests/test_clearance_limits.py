"""Where the clearance chain's methods fail (issue #11), each limit asserted on both sides: the
event-located reference's contact-change budget (max_events), central difference's stiffness limit on
the common interface, and the accuracy limit of the exact solver's Heun splitting of the span law.
The reference's absolute tolerance against the contact stiffness, too. The fast integrator's own step
limit is in tests/test_clearance_chain.py. Cases: 10 links, the first
30 degrees of an index from rest (verification.clearance_stability.small_case)."""

import numpy as np
import pytest

from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.solvers import clearance_verlet as verlet
from verification.clearance_stability import event_case, method_case, small_case


def test_reference_within_its_event_budget_agrees_and_one_change_over_is_refused():
    case = small_case(1e8, 1e-5)
    ref = case.reference(1e-8)
    changes = ref.n_contact_changes
    assert changes >= 4  # spans open and close in this window
    inside = case.reference(1e-8, max_events=changes)
    fast = case.fast(verlet.stable_step_s(case.model, safety=1.0) / 32)
    # fast integrator's error at h_max/32 is second order, ~1e-6 of the peak here (measured 2e-6)
    assert np.max(np.abs(inside.y_m - fast.y)) <= 2e-5 * np.max(np.abs(fast.y))
    refusal = rf"more than {changes - 1} contact changes \(max_events\).*clearance_verlet"
    with pytest.raises(DynamicsError, match=refusal) as err:
        case.reference(1e-8, max_events=changes - 1)
    assert "\n" not in str(err.value)


def _stiffness_for_omega_h(omega_h, k0=1e8):
    """The link stiffness at which one step per output interval has omega_max h = omega_h."""
    case = small_case(k0, 94e-6, friction_coefficient=0.0)
    omega_h0 = case.model.max_frequency_rad_s() * (case.t[1] - case.t[0])
    return k0 * (omega_h / omega_h0) ** 2


def test_central_difference_on_the_clearance_chain_both_sides_of_its_stiffness_limit():
    """At a fixed step (one per output sample) the stiffness sets omega_max h; the full-contact K's
    limit 2 / omega_max holds with free play too (the span law only softens the chain). Just below
    it the run finishes bounded; the top mode, which the impacts excite, is barely damped by the
    scheme there, so 1 % accuracy needs omega_max h <= 1.9 (measured 8.5e-3 at 1.9, 1.3e-2 at 1.98)."""
    accurate = method_case("central-difference", _stiffness_for_omega_h(1.9), 1.8)
    assert accurate.setting == pytest.approx(1.9, rel=1e-3) and accurate.outcome == "accurate"
    below = method_case("central-difference", _stiffness_for_omega_h(1.98), 1.9)
    assert below.setting == pytest.approx(1.98, rel=1e-3)
    assert below.outcome in ("accurate", "inaccurate") and below.relative_error < 3e-2
    above = method_case("central-difference", _stiffness_for_omega_h(2.02), 1.9)
    assert above.setting == pytest.approx(2.02, rel=1e-3)
    assert above.outcome == "diverged"
    case = small_case(_stiffness_for_omega_h(2.02), 94e-6, friction_coefficient=0.0)
    with pytest.raises(SolverDivergedError, match="stability limit"):
        case.common("central-difference", dt=case.t[1] - case.t[0])


def test_exact_solver_heun_splitting_loses_accuracy_at_large_contact_steps():
    """The exact solver integrates the linear chain exactly but the span law's departure from it by a
    Heun predictor-corrector: bounded at any step, accurate (1e-2) to omega_max h about 1, not at 3.4."""
    fine = method_case("exact", 1e8, 1.0)
    coarse = method_case("exact", 1e8, 3.0)
    assert fine.setting < 1.2 and fine.outcome == "accurate"
    assert coarse.setting > 3.0 and coarse.outcome == "inaccurate"
    assert np.isfinite(coarse.relative_error) and coarse.relative_error < 1.0


def test_reference_at_loose_tolerance_loses_stiff_contacts_unless_atol_follows_the_response():
    """The reference's default atol (rtol x 10 um, sized for the default chain's stretch P/k = 24 um)
    is 5e-4 of the 2.2 um response of a 1e10 N/m chain at rtol 1e-4: off by 1.3e-2 (measured); at
    rtol 1e-6, or with atol set to the response's scale, it is accurate (9e-6, 2e-7)."""
    loose = event_case(1e10, 1e-5, rtol=1e-4)
    assert loose.outcome == "inaccurate" and loose.relative_error > 5e-3
    tight = event_case(1e10, 1e-5, rtol=1e-6)
    assert tight.outcome == "accurate" and tight.relative_error < 1e-4
    case = small_case(1e10, 1e-5)
    fast = case.fast(verlet.stable_step_s(case.model, safety=1.0) / 32).y
    scaled = case.reference(1e-4, atol=1e-13)
    assert np.max(np.abs(scaled.y_m - fast)) < 1e-4 * np.max(np.abs(fast))
