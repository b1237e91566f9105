"""The linear model's own numbers carry their validity (dynamics.scene.LinearModelValidity): its minimum
tension and the preload for full contact hold while it deforms no span by more than
LINEAR_ELASTIC_STRAIN_LIMIT of the pitch; in summary.json, the report's tension table and paragraph,
and the study records."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.machine_scene import machine_model, simulate_machine
from dynamics.models.chain import ChainModel
from dynamics.scene import (
    LINEAR_ELASTIC_STRAIN_LIMIT,
    ChainModelKind,
    ContactSummary,
    Validity,
    linear_model_validity,
    linear_validity_at_yield,
    with_yield_load,
)
from geometry.dimensions import LinkDimensions
from settings import RunConfig
from stages.chain import chain_scene

PITCH_M = LinkDimensions().pitch_m  # the default link's, which the wheels are sized on
K_AL, M_AL = 9.325e7, 2.03  # the default aluminium link's FEA k (N/m) and lumped mass (kg)
RPM = 180.0
# the default aluminium link's yield load: 6061-T6's 276 MPa over its converged 13.8 MPa per kN
YIELD_LOAD_N = 276e6 / 1.38e4


def _machine(links: int, k: float, **cfg):
    chain = ChainModel(links, M_AL, k, damping_ratio=0.13, friction_coefficient=0.0)
    return machine_model(chain_scene(RunConfig(**cfg), PITCH_M), chain)


def _one_index(samples_per_degree: int = 1):
    """One index cycle (90 cam degrees) of output samples, its end included."""
    return np.arange(90 * samples_per_degree + 1) / samples_per_degree / (6 * RPM)


CAM = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=RPM)


def test_the_bound_is_the_elastic_strain_limit_of_the_pitch_and_holds_up_to_itself():
    k, bound = 1e8, LINEAR_ELASTIC_STRAIN_LIMIT * PITCH_M
    at = linear_model_validity(-bound * k, 10.0, k, PITCH_M)
    assert at.valid and at.deformation_bound_m == bound and at.span_deformation_m == pytest.approx(bound, rel=1e-15)
    above = linear_model_validity(-np.nextafter(bound, 1.0) * k * (1 + 1e-12), 10.0, k, PITCH_M)
    assert above.validity == Validity.OUTSIDE_LINEAR_MODEL and not above.valid
    # the largest |span force| either way: a peak tension deforms the span as a push of the same size does
    stretched = linear_model_validity(-1.0, 2 * bound * k, k, PITCH_M)
    assert not stretched.valid and stretched.largest_span_force_N == 2 * bound * k
    assert stretched.span_deformation_m == pytest.approx(2 * bound, rel=1e-15)


def test_a_preload_above_the_yield_load_is_said_and_leaves_the_numbers_validity_alone():
    valid = linear_model_validity(-5e4, 6e4, K_AL, PITCH_M)
    above = with_yield_load(valid, 5.2e4, YIELD_LOAD_N)
    assert above.valid and above.preload_above_yield_load and above.yield_load_N == YIELD_LOAD_N
    assert "not a preload a designer can apply" in above.reason
    below = with_yield_load(valid, 1e4, YIELD_LOAD_N)
    assert below.preload_above_yield_load is False and below.reason == valid.reason


@pytest.mark.parametrize(
    "links, k, cfg, valid",
    [
        (16, K_AL, {}, True),  # the default link, short chain: the clearance model runs, its linear model holds
        (16, K_AL, {"pin_clearance_m": 0.0}, True),  # the linear model is the answer
        (16, K_AL / 100, {}, False),  # exaggerated compliance: spans deformed by ~15 mm, 13 % of the pitch
    ],
)
def test_the_machines_linear_model_validity_measures_its_own_span_forces(links, k, cfg, valid):
    """The field is the linear machine's: its largest |span force| over the window is the one the linear
    machine run on its own (choice "linear") gives, to the two runs' step difference (the auto run
    chooses at the default safety, the linear run steps its window WINDOW_REFINEMENT finer: 5e-4 to
    7e-4 on the station metrics, benchmarks/bench_accuracy.py); valid exactly where that force / k is
    within the bound."""
    model = _machine(links, k, **cfg)
    _, auto = simulate_machine(model, CAM, _one_index(), steady_state=False)
    _, linear = simulate_machine(model, CAM, _one_index(), steady_state=False, choice="linear")
    v = auto.linear_model_validity
    force = max(abs(linear.min_tension_N), abs(linear.peak_tension_N))
    assert v.largest_span_force_N == pytest.approx(force, rel=5e-3)
    assert v.span_deformation_m == pytest.approx(v.largest_span_force_N / k, rel=1e-15)
    assert v.deformation_bound_m == pytest.approx(LINEAR_ELASTIC_STRAIN_LIMIT * PITCH_M, rel=1e-15)
    assert v.valid == valid == (v.span_deformation_m <= v.deformation_bound_m)
    # the numbers it qualifies are as they were: the preload for full contact is P - the linear minimum
    assert auto.preload_for_full_contact_N == max(model.chain.preload_N - auto.linear_min_tension_N, 0.0)


def test_the_default_85_link_machine_holds_in_the_linear_model():
    """The default run's scene (85 aluminium links, 0.094 mm, steady state): the linear model's largest
    span force, 49 kN, deforms a span by 0.53 mm, under half the 1.125 mm bound; its preload for full
    contact (46 kN) is above the link's yield load (20 kN)."""
    model = _machine(85, K_AL)
    _, summary = simulate_machine(model, CAM, _one_index(4))
    v = summary.linear_model_validity
    assert v.valid and v.span_deformation_m < 0.5 * v.deformation_bound_m
    at_yield = linear_validity_at_yield(summary, 276e6, 1.38e4)
    assert at_yield.valid and at_yield.preload_above_yield_load


def _contact(validity=None) -> ContactSummary:
    return ContactSummary(
        ChainModelKind.CLEARANCE, "asked for", Validity.VALID, 1e-4, True, 0.1, 2.0, 900.0, 5e3, -6.77e6, 6.77e6,
        -6.77e6, linear_model_validity=validity,
    )  # fmt: skip


def test_summary_json_carries_the_validity_beside_the_numbers():
    from reporting.outputs import _contact_summary

    outside = linear_model_validity(-6.77e6, 5e4, 9.0e7, PITCH_M)
    contact = _contact(outside)
    summary = json.loads(json.dumps(_contact_summary(contact), allow_nan=False))
    assert summary["preload_for_full_contact_N"] == 6.77e6 and summary["linear_min_tension_N"] == -6.77e6
    record = summary["linear_model_validity"]
    assert record["validity"] == "outside the linear model" and record["span_deformation_m"] == pytest.approx(
        6.77e6 / 9.0e7, rel=1e-15
    )
    assert record["yield_load_N"] is None and record["preload_above_yield_load"] is None
    at_yield = linear_validity_at_yield(contact, 276e6, 1.38e4)
    summary = json.loads(json.dumps(_contact_summary(contact, at_yield), allow_nan=False))
    assert summary["linear_model_validity"]["yield_load_N"] == pytest.approx(YIELD_LOAD_N)
    assert summary["linear_model_validity"]["preload_above_yield_load"] is True
    # the single-link drive: no pitch in its dynamics, no verdict
    assert json.loads(json.dumps(_contact_summary(_contact())))["linear_model_validity"] is None
    assert linear_validity_at_yield(_contact(), 276e6, 1.38e4) is None


def _tension_rows(validity) -> tuple:
    from reporting.outputs import _tension_table

    scenario = {
        "model": "clearance",
        "peak_tension_N": 5e4,
        "min_tension_N": -4e4,
        "preload_for_full_contact_N": 6.77e6,
        "linear_model_validity": validity,
        "peak_link_stress_Pa": 6.9e8,
        "yield_safety_factor": 0.4,
    }
    materials = {"al6061-t6": {"cams": {"modified-sine": scenario}, "safety_factor_stress": "converged"}}
    return _tension_table(materials).rows[0]


def test_the_tension_table_marks_a_preload_from_outside_the_linear_model():
    """The preload stays a number (the CSV's column is numeric); the column beside it says whether the
    linear model it comes from holds."""
    outside = vars(linear_model_validity(-6.77e6, 5e4, 9.0e7, PITCH_M))
    assert _tension_rows(outside)[9:11] == (6770.0, "outside the linear model")
    valid = vars(linear_model_validity(-4.4e4, 5e4, 9.0e7, PITCH_M))
    assert _tension_rows(valid)[9:11] == (6770.0, "valid")
    assert _tension_rows(None)[9:11] == (6770.0, "")


def test_the_model_paragraph_marks_the_linear_minimum_tension_outside_the_linear_model():
    from reporting import sections

    def paragraph(*validities):
        scenarios = {
            ("al6061-t6", cam): SimpleNamespace(contact=_contact(v))
            for cam, v in zip(("modified-sine", "cycloidal"), validities)
        }
        return sections._model_paragraphs(SimpleNamespace(scenarios=scenarios))

    valid = linear_model_validity(-4.4e4, 5e4, K_AL, PITCH_M)
    outside = linear_model_validity(-6.77e6, 5e4, K_AL, PITCH_M)
    assert "outside the linear model" not in paragraph(valid, valid)
    text = paragraph(valid, outside)
    assert text.startswith('<p class="warn">') and "outside the linear model for al6061-t6 / cycloidal" in text


def test_the_study_records_carry_the_validity_and_the_preload_against_yield():
    """A study point on the wheels with the exaggerated compliance: its linear model does not hold; with
    the default link it does, and its preload for full contact is above the yield load."""
    from stages.chain import simulate_scenario
    from stages.fea import MaterialFea
    from study.records import FLAGS, blank_metrics, chain_metrics

    cfg = RunConfig(links=16, samples_per_degree=1, cams=("modified-sine",), steady_state=False)
    fea = MaterialFea(
        "al6061-t6", K_AL, 0.01, 0.373, 1.38e-4, PITCH_M, 0.0095, 1.38e4, 1.38e4, 1.38e4, 0.0, "converged",
        276e6, 1000, 0.005, {}, [], False, None,
    )  # fmt: skip
    rows = {}
    for k in (K_AL, K_AL / 100):
        chain = ChainModel(16, M_AL, k, damping_ratio=0.13, friction_coefficient=0.0)
        scenario = simulate_scenario(cfg, chain, "al6061-t6", "modified-sine", PITCH_M, 1)
        rows[k] = chain_metrics(scenario, fea, "tight-side", M_AL, 1.0)
    assert rows[K_AL]["linear_model_valid"] is True and rows[K_AL / 100]["linear_model_valid"] is False
    assert rows[K_AL / 100]["preload_above_yield_load"] is (
        rows[K_AL / 100]["preload_for_full_contact_N"] > YIELD_LOAD_N
    )
    assert all(blank_metrics()[name] is None for name in FLAGS)
    assert all(math.isnan(value) for name, value in blank_metrics().items() if name not in FLAGS)


def test_the_study_records_describe_the_models_limit_without_the_dynamics_heavy_imports():
    """The study's column says the bound the model applies (dynamics.options.LINEAR_ELASTIC_STRAIN_LIMIT,
    which dynamics.scene applies), and reading the columns, as a study's client does, imports neither
    numba, SciPy nor dynamics.scene."""
    import subprocess
    import sys
    from pathlib import Path

    import dynamics.options
    import dynamics.scene
    from study.records import METRICS

    assert dynamics.scene.LINEAR_ELASTIC_STRAIN_LIMIT is dynamics.options.LINEAR_ELASTIC_STRAIN_LIMIT
    percent = dynamics.options.LINEAR_ELASTIC_STRAIN_LIMIT * 100
    assert f"deforms no span by more than {percent:g} % of the pitch" in METRICS["linear_model_valid"]
    code = "import json, sys, study.records; print(json.dumps(sorted(sys.modules)))"
    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True)
    loaded = json.loads(out.stdout.splitlines()[-1])
    assert "dynamics.options" in loaded
    heavy = ("numba", "scipy", "dynamics.scene", "dynamics.solvers", "dynamics.models")
    assert [m for m in loaded if any(m == h or m.startswith(h + ".") for h in heavy)] == []
