"""Model no more than the question needs: pick the time step for a relative tolerance on the metrics.

The reported metrics are the station values (RMS and peak acceleration, deviations, residual
vibration). Their error from the time step is estimated by halving the step: the exact solver's
only discretisation is the first-order hold of the cam force and the output sampling, both
second order, so the change between step h and h/2 bounds the error at h/2 (it is about 3x the
remaining error). Their sensitivity to an error in the link stiffness is measured by re-running
with k perturbed by its FEA error estimate.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.response.metrics import StationMetrics

MAX_SAMPLES_PER_DEGREE = 64


def metric_values(stations: Mapping[str, StationMetrics]) -> np.ndarray:
    """All station metrics of one scenario as one vector (link numbers left out)."""
    return np.array([getattr(s, f.name) for s in stations.values() for f in fields(s) if f.name != "link"])


def relative_change(new: np.ndarray, old: np.ndarray) -> float:
    """Largest relative difference over the metrics; metrics that are zero in both are skipped."""
    scale = np.maximum(np.abs(new), np.abs(old))
    nonzero = scale > 0
    if not np.any(nonzero):
        return 0.0
    return float(np.max(np.abs(new - old)[nonzero] / scale[nonzero]))


@dataclass(frozen=True)
class StepChoice:
    samples_per_degree: int
    rel_error_estimate: float  # from the last halving
    tried: tuple[int, ...]


def choose_samples_per_degree(
    station_metrics_at: Callable[[int], Mapping[str, StationMetrics]],
    rel_tolerance: float,
    *,
    start: int = 1,
) -> tuple[StepChoice, Mapping[str, StationMetrics]]:
    """Double the output sampling from `start` until the metrics change by less than the tolerance.

    Returns the choice and the metrics at the chosen (finer) sampling.
    """
    if not (0 < rel_tolerance < 1):
        raise DynamicsError(f"tolerance: got {rel_tolerance!r}; expected a relative tolerance in (0, 1)")
    spd = start
    coarse = station_metrics_at(spd)
    tried = [spd]
    while True:
        spd *= 2
        fine = station_metrics_at(spd)
        tried.append(spd)
        change = relative_change(metric_values(fine), metric_values(coarse))
        if change <= rel_tolerance or spd >= MAX_SAMPLES_PER_DEGREE:
            return StepChoice(spd, change, tuple(tried)), fine
        coarse = fine


def stiffness_sensitivity(
    station_metrics_with_k: Callable[[float], Mapping[str, StationMetrics]],
    stiffness_N_per_m: float,
    stiffness_rel_error: float,
    reference: Mapping[str, StationMetrics],
) -> float:
    """Largest relative change of the metrics when k moves by its estimated relative error."""
    perturbed = station_metrics_with_k(stiffness_N_per_m * (1.0 - stiffness_rel_error))
    return relative_change(metric_values(perturbed), metric_values(reference))
