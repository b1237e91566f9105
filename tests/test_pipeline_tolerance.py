"""--tolerance orchestration: the FEA refinement pass builds on the first pass (no level solved twice)."""

from types import SimpleNamespace

import pytest

import pipeline
from stages import tolerance
from stages.progress import Progress


def test_refinement_pass_shares_the_first_pass_levels(monkeypatch):
    calls = []

    def fea(cfg, progress, stiffness_tolerance, levels, part=None):
        calls.append((stiffness_tolerance, levels))
        return {"al6061-t6": SimpleNamespace(stiffness_rel_error_estimate=stiffness_tolerance)}

    def dynamics(cfg, fea_results, progress):
        k_error = fea_results["al6061-t6"].stiffness_rel_error_estimate
        # metrics that move 3x as much as k: the first pass's k is not good enough
        return {}, {("al6061-t6", "modified-sine"): SimpleNamespace(rel_error_estimate={"stiffness": 3 * k_error})}

    monkeypatch.setattr(tolerance, "run_fea", fea)
    monkeypatch.setattr(tolerance, "run_dynamics", dynamics)
    cfg = pipeline.parse_cli(["--tolerance", "0.02", "--materials", "al6061-t6", "-q"])
    timing: dict = {}
    tolerance.run_to_tolerance(cfg, Progress(quiet=True), timing)
    (first_tol, first_levels), (second_tol, second_levels) = calls
    assert first_tol == pytest.approx(0.01)  # half the tolerance goes to k
    assert second_tol == pytest.approx(0.8 * 0.01 * 0.01 / 0.03)  # what the measured 3x sensitivity asks for
    assert second_levels is first_levels  # one dict of solved levels across both passes
    assert set(timing) == {"fea", "dynamics"}


def test_no_second_pass_when_k_is_good_enough(monkeypatch):
    calls = []
    monkeypatch.setattr(
        tolerance,
        "run_fea",
        lambda cfg, progress, tol, levels, part=None: (
            calls.append(tol) or {"al6061-t6": SimpleNamespace(stiffness_rel_error_estimate=tol)}
        ),
    )
    monkeypatch.setattr(
        tolerance,
        "run_dynamics",
        lambda cfg, fea, progress: (
            {},
            {("al6061-t6", "modified-sine"): SimpleNamespace(rel_error_estimate={"stiffness": 0.5 * 0.01})},
        ),
    )
    cfg = pipeline.parse_cli(["--tolerance", "0.02", "--materials", "al6061-t6", "-q"])
    tolerance.run_to_tolerance(cfg, Progress(quiet=True), {})
    assert calls == [pytest.approx(0.01)]


def test_the_clearance_chains_step_gets_a_quarter_of_the_tolerance():
    """--tolerance: half to the time step, split between the output sampling and the clearance
    chain's step control (dynamics.scene.simulate_chain(accuracy=)); none without it or for --model linear."""
    from stages.chain import chain_scene

    pitch_m = 0.1125
    assert chain_scene(pipeline.parse_cli(["--tolerance", "0.02", "-q"]), pitch_m).accuracy == pytest.approx(0.005)
    assert chain_scene(pipeline.parse_cli(["-q"]), pitch_m).accuracy is None
    linear = pipeline.parse_cli(["--tolerance", "0.02", "--model", "linear", "-q"])
    assert chain_scene(linear, pitch_m).accuracy is None
