"""Choosing the time step for a tolerance on the metrics (dynamics/response/fidelity.py)."""

import numpy as np
import pytest

import pipeline
from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.response.fidelity import choose_samples_per_degree, metric_values, relative_change, stiffness_sensitivity
from dynamics.response.metrics import StationMetrics
from stages.chain import chain_model, simulate_scenario
from stages.fea import MaterialFea


def _stations(value: float) -> dict:
    return {"tight-side": StationMetrics(3, *([value] * 8))}


def test_relative_change_ignores_metrics_that_are_zero_in_both():
    assert relative_change(np.array([0.0, 2.0]), np.array([0.0, 1.0])) == 0.5
    assert relative_change(np.zeros(3), np.zeros(3)) == 0.0


def test_sampling_doubles_until_a_second_order_metric_settles():
    # A metric converging as 1 + h^2 with h = 1 / samples_per_degree: going from h to h/2 changes
    # it by 3/4 h^2 / (1 + h^2); that is 2.9e-3 from 16 to 32 samples per degree (below 3e-3) and
    # 1.2e-2 from 8 to 16 (above), so the finer of the first pair that agrees, 32, is chosen.
    choice, stations = choose_samples_per_degree(lambda spd: _stations(1.0 + spd**-2.0), 3e-3)
    assert choice.samples_per_degree == 32
    assert choice.tried == (1, 2, 4, 8, 16, 32)
    assert choice.rel_error_estimate <= 3e-3
    assert metric_values(stations)[0] == pytest.approx(1.0 + 32**-2.0)


def test_tolerance_outside_zero_one_is_refused():
    with pytest.raises(DynamicsError, match="tolerance"):
        choose_samples_per_degree(lambda spd: _stations(1.0), 1.5)


def test_stiffness_sensitivity_of_the_chain_metrics_is_measured_not_assumed():
    # A real scenario: metrics move when k moves by 1 %, and not at all when it does not move.
    cfg = pipeline.parse_cli(["--drive", "link", "--links", "12", "--friction", "0", "--cams", "modified-sine"])
    fea = MaterialFea(
        "al6061-t6",
        9e7,
        0.01,
        0.373,
        1.38e-4,
        0.1125,
        0.0095,
        1e5,
        1e5,
        1e5,
        0.0,
        "test",
        276e6,
        1000,
        0.005,
        {},
        [],
        False,
        None,
    )

    def stations_with_k(k):
        return simulate_scenario(cfg, chain_model(cfg, fea, k), "al6061-t6", "modified-sine", 0.1125, 2).stations

    reference = stations_with_k(9e7)
    moved = stiffness_sensitivity(stations_with_k, 9e7, 0.01, reference)
    assert 1e-4 < moved < 0.2
    assert stiffness_sensitivity(stations_with_k, 9e7, 0.0, reference) == 0.0
    assert isinstance(chain_model(cfg, fea), ChainModel)
