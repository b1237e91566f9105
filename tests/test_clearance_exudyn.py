"""Cross-check of the clearance chain's reference (verification.clearance_reference) against Exudyn, an
independent multibody code (benchmarks/exudyn_chain.py builds the chain there with limit stops).

Exudyn integrates with generalized-alpha (spectral radius 1, the trapezoidal rule) at a fixed step,
so the comparison is at the accuracy of its step, and the check is that it converges to the
reference as the step shrinks. Measured on the 20-link chain below (station RMS, relative):
- no free play: second order; at 20 steps per output 2.5e-8 (x), 4.5e-6 (v), 3.3e-4 (a);
- free play with law (a) (C = beta K, dampers always on): second order; at 160 steps per output
  5.7e-9 (x), 1.3e-6 (v), 3.7e-4 (a);
- free play with law (b) (Kelvin-Voigt: the limit stops' dashpot, on only in contact): first order
  in a, because Exudyn switches a span's contact state for the whole step in which it crosses (its
  PostNewton iteration) and the dashpot force jumps at contact: 1.5e-2 at 40 and 7.2e-3 at 160
  steps per output (a), 3e-8 (x).
The bounds below are those figures with a margin of about 2, and each test also asserts the
convergence rate, so agreement is not luck at one step.
"""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks.exudyn_chain import exudyn_chain_response
from dynamics.cams import CamProgram, Segment
from dynamics.models.chain import ChainModel
from dynamics.response.metrics import rms, station_links
from dynamics.solvers.simulate import SlackChainWarning, simulate
from verification.clearance_reference import HeldCam, reference_response

N = 20
K = 9.27e7
MASS = 2.03
PRELOAD = 2224.0
GAP = 1e-4
BETA = 2e-5  # s: span damping beta k (zeta = beta omega / 2: 0.13 near 2 kHz)
T_WINDOW = np.arange(181) / (6.0 * 180.0)
CAM = CamProgram.indexing("modified-sine")
RESTING = CamProgram((Segment("dwell", 360.0),), 180.0, periodic=True, name="at rest")
HELD = HeldCam(CAM, T_WINDOW)  # the same input for all three codes
STATIONS = [link - 1 for link in station_links(N).values()]
CHAIN = dict(
    n_links=N, link_mass_kg=MASS, stiffness_N_per_m=K, drive_stiffness_N_per_m=K, preload_N=PRELOAD, t_eval_s=T_WINDOW
)


def station_differences(ours, theirs) -> np.ndarray:
    """Largest relative difference of the stations' RMS x, v, a (relative to the largest station's)."""
    out = []
    for a, b in ((ours.x_m, theirs.x_m), (ours.v_m_s, theirs.v_m_s), (ours.a_m_s2, theirs.a_m_s2)):
        ra, rb = rms(a[:, STATIONS]), rms(b[:, STATIONS])
        out.append(np.abs(ra - rb).max() / np.abs(rb).max())
    return np.array(out)


def exudyn_run(steps, **overrides):
    args = dict(CHAIN, clearance_m=GAP, cam=HELD, span_damping_beta_s=BETA, steps_per_output=steps)
    args.update(overrides)
    return exudyn_chain_response(**args)


def test_exudyn_limit_stops_hold_the_preloaded_static_state():
    t = np.linspace(0.0, 0.01, 11)
    ex = exudyn_run(10, cam=RESTING, t_eval_s=t, n_links=5)
    assert np.all(ex.x_m == 0.0)
    np.testing.assert_allclose(ex.tension_N, PRELOAD, rtol=1e-12)


def test_exudyn_without_free_play_converges_to_the_exact_linear_solver():
    model = ChainModel(N, MASS, K, preload_N=PRELOAD, rayleigh_coefficients=(0.0, BETA))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SlackChainWarning)
        lin = simulate(model, CAM, T_WINDOW, steady_state=False)  # the first-order hold HELD integrates
    held_z, held_v, _, _ = HELD.svaj(T_WINDOW)
    lin_on_held = SimpleNamespace(
        x_m=lin.x_m - lin.z_m[:, None] + held_z[:, None],
        v_m_s=lin.v_m_s - lin.zdot_m_s[:, None] + held_v[:, None],
        a_m_s2=lin.a_m_s2,
    )
    coarse, fine = (
        station_differences(exudyn_run(s, clearance_m=0.0, damping_law="kelvin-voigt"), lin_on_held) for s in (10, 20)
    )
    assert np.all(fine < [5e-8, 1e-5, 7e-4])
    assert np.all(coarse > 3.0 * fine)  # second order


def test_exudyn_with_free_play_converges_to_the_reference_rayleigh_damping():
    damping = ChainModel(N, MASS, K, rayleigh_coefficients=(0.0, BETA)).damping_matrix()
    ref = reference_response(**CHAIN, clearance_m=GAP, cam=CAM, damping_matrix=damping, cam_input="held")
    assert ref.n_contact_changes > 50 and ref.tension_N.min() < 0  # spans lose contact and push
    coarse, fine = (station_differences(exudyn_run(s, damping_law="rayleigh"), ref) for s in (40, 160))
    assert np.all(fine < [2e-8, 3e-6, 1e-3])
    assert coarse[2] > 8.0 * fine[2]  # second order in the accelerations


def test_exudyn_with_free_play_converges_to_the_reference_kelvin_voigt():
    ref = reference_response(**CHAIN, clearance_m=GAP, cam=CAM, span_damping_beta_s=BETA, cam_input="held")
    assert ref.n_contact_changes > 50
    runs = {s: exudyn_run(s, damping_law="kelvin-voigt") for s in (40, 160)}
    coarse, fine = (station_differences(runs[s], ref) for s in (40, 160))
    assert np.all(fine < [1e-7, 2e-5, 1.5e-2])
    assert coarse[2] > 1.6 * fine[2]  # first order: Exudyn switches contact at its steps
    # the span forces too: peak tension and the deepest push
    assert runs[160].tension_N.max() == pytest.approx(ref.tension_N.max(), rel=1e-2)
    assert runs[160].tension_N.min() == pytest.approx(ref.tension_N.min(), rel=2e-2)
