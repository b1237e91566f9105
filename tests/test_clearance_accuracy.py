"""The clearance chain's step control (dynamics.scene.simulate_chain(accuracy=), issue 24): on a small,
fast scene whose stability-set step alone is more than 1e-3 off, the controlled run's station metrics
are within the accuracy of a converged run, and its own estimate is not below its error."""

from __future__ import annotations

import numpy as np

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain
from dynamics.response.fidelity import metric_values, relative_change
from dynamics.response.metrics import link_metrics, station_metrics
from dynamics.scene import simulate_chain

RPM = 300.0
ACCURACY = 1e-3


def _scene():
    """15 links, 1 mm free play at 300 rpm (impacts every index), the default link's k and mass."""
    chain = ChainModel(n_links=15, link_mass_kg=2.03, stiffness_N_per_m=9.0092e7, friction_coefficient=0.35)
    cam = CamProgram.indexing("modified-sine", pitch_m=0.1125, rpm=RPM)
    t = np.arange(721) / 4 / (6 * RPM)  # the pipeline's window: 180 degrees at 4 samples per degree
    return ClearanceChain(chain, 1e-3), cam, t


def _metrics(**options):
    model, cam, t = _scene()
    r, contact = simulate_chain(model, cam, t, steady_state=False, **options)
    assert contact.model == "clearance" and contact.impacts_per_cycle > 0
    lm = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, cam.dwell_mask(t))
    return metric_values(station_metrics(lm)), contact


def test_controlled_run_is_within_its_accuracy_of_converged_where_the_stability_step_is_not():
    # converged: euler at a fixed 1/32 of its quarter-limit step; its change from 1/16 (1.0e-4 here)
    # bounds its own error (second order: about a third of that change)
    converged, _ = _metrics(predictor="euler", safety=0.25 / 32, accuracy=None)
    half_as_fine, _ = _metrics(predictor="euler", safety=0.25 / 16, accuracy=None)
    assert relative_change(half_as_fine, converged) < 0.2 * ACCURACY
    fixed, _ = _metrics()  # the default: the stability-set step alone
    assert relative_change(fixed, converged) > ACCURACY  # the control has work to do here
    controlled, contact = _metrics(accuracy=ACCURACY)
    error = relative_change(controlled, converged)
    assert error <= ACCURACY
    assert contact.step_error_estimate <= ACCURACY and contact.step_error_estimate >= error
