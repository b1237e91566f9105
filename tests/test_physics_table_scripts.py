"""The scripts that reproduce docs/physics.md's tables (benchmarks/impacts_single_link.py,
impacts_on_wheels.py, seating_table.py, tooth_phase_table.py) import and run, on a short chain and
window; their full runs are the commands in the docs."""

from __future__ import annotations

import numpy as np

from benchmarks import impacts_on_wheels, impacts_single_link, seating_table, tooth_phase_table
from dynamics.models.chain import ChainModel

SHORT_CHAIN = ChainModel(31, 2.0296, 9.331e7)
SAMPLES = 201  # 50 cam degrees: the index (45) and the start of the dwell


def test_the_single_link_impacts_run_on_a_short_chain():
    contact = impacts_single_link.contact_summary(n_links=31, samples=SAMPLES)
    assert contact.peak_tension_N > 0
    assert contact.impacts.closing_speed_max_m_s >= contact.impacts.closing_speed_median_m_s >= 0.0


def test_the_impacts_on_wheels_run_on_a_short_chain():
    contact = impacts_on_wheels.contact_summary(SHORT_CHAIN, samples=SAMPLES)
    assert contact.peak_tension_N > 0 and len(contact.seating.speed_m_s) == 2


def test_the_seating_verdict_at_phase_zero_holds_on_a_short_chain():
    verdict = seating_table.verdict(0.0, SHORT_CHAIN, samples=SAMPLES)
    assert verdict.valid and verdict.cam_speed_fraction == 0.0


def test_a_tooth_phase_row_on_a_short_chain():
    phase, k, residual_mm, peak_station, peak_any, tension_N, seating = tooth_phase_table.row(
        0.25, tooth_phase_table.DEFAULT_TOOTH_STIFFNESS_N_PER_M, SHORT_CHAIN, samples=SAMPLES
    )
    assert (phase, k) == (0.25, tooth_phase_table.DEFAULT_TOOTH_STIFFNESS_N_PER_M)
    assert np.isfinite(residual_mm) and 0 < peak_station <= peak_any and tension_N > 0
