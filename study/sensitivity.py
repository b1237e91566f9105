"""Which inputs drive each metric of a study: first-order variance-based (Sobol') indices estimated
from the study's own points.

A study sampled with Latin hypercube or Sobol' is a sample of its inputs: the range variables
uniform on their ranges, each list variable uniform over its values (every range sample is crossed
with every combination of the lists). The first-order index of an input is the share of a metric's
variance that the input explains alone, S_i = Var(E[Y | X_i]) / Var(Y), so the indices of the
inputs of one metric add up to at most 1 (the rest is interaction).

Estimators (chosen by measurement on the Ishigami function, benchmarks/bench_sensitivity.py):

- range variables: RBD-FAST (SALib's `rbd_fast`, Tarantola et al. 2006 with Tissot and Prieur's
  bias correction, `HARMONICS` harmonics), a given-data method that works on any space-filling
  sample, on the metric averaged over the list combinations of each range sample ybar(x). Because
  E[Y | x_i] = E[ybar | x_i], the index is RBD-FAST's index of ybar scaled by Var(ybar) / Var(Y).
  Its interval is SALib's bootstrap (half-size resamples, so on the wide side) scaled the same way.
- list variables: the between-value variance of the metric's means, exact for a design crossed in
  full, with a bootstrap interval over the range samples.

Points whose metric was not computed (an infeasible link, a failed chain) leave out their whole
range sample for that metric (`MetricSensitivity.dropped`). Too few range samples, or intervals too
wide to tell inputs apart, make `adequate` false with the reason in `adequacy`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from study.samplers import SAMPLERS

#: Harmonics RBD-FAST sums: 4 had the smallest error on Ishigami at 32-256 points (6 and 10, the
#: SALib default, were worse below 256 points: benchmarks/bench_sensitivity.py).
HARMONICS = 4
RESAMPLES = 100  # bootstrap resamples per interval
CONF_LEVEL = 0.95
#: Fewer range samples than this: the 95 % intervals span most of [0, 1] (about +-0.6 at 32 points
#: on Ishigami), so no ranking can be read.
MIN_SAMPLES = 64
#: Fewer than this and RBD-FAST cannot estimate at all: its bias correction divides by 1 - 2M/n and
#: its bootstrap draws n/2 points, which must exceed 2M.
MIN_TO_ESTIMATE = 4 * HARMONICS + 2
#: Largest interval half-width at which indices are read as a ranking: inputs whose indices differ by
#: more than twice this are told apart.
MAX_HALF_WIDTH = 0.2
#: The range variables' share of the variance below which it is rounding, not an effect (a metric
#: the list variables alone set: its mean over them varies in the last digits only).
SHARE_TOLERANCE = 1e-12
ESTIMATOR = (
    f"first-order Sobol' indices: RBD-FAST (SALib, {HARMONICS} harmonics) for range variables, "
    f"between-value variance for list variables; {CONF_LEVEL:.0%} bootstrap intervals"
)


@dataclass(frozen=True)
class InputIndex:
    input: str
    kind: str  # "range" or "list"
    first_order: float  # S1, share of the metric's variance the input explains alone
    half_width: float  # half-width of the CONF_LEVEL interval of S1


@dataclass(frozen=True)
class MetricSensitivity:
    metric: str
    samples: int  # range samples used
    dropped: int  # range samples left out: the metric is missing at one of their points
    indices: tuple[InputIndex, ...]  # largest first
    adequate: bool
    adequacy: str  # one sentence: why the indices can or cannot be read as a ranking

    def ranking(self) -> list[str]:
        return [i.input for i in self.indices]

    def standing_out(self) -> list[InputIndex]:
        """The inputs whose interval lies above zero, largest first: the part of the ranking the
        intervals vouch for (the others are not told from no effect)."""
        return [i for i in self.indices if i.first_order - i.half_width > 0]


def first_order_indices(
    X: np.ndarray, range_names: list[str], Y: np.ndarray, list_labels: dict[str, list], seed: int
) -> tuple[InputIndex, ...]:
    """Indices of every input, largest first.

    X: (n, d) range samples; Y: (n, K) the metric at each range sample (rows) and list combination
    (columns); list_labels: each list variable's value in each of the K columns.
    """
    total = float(Y.var())
    if not total > 0:
        return tuple(
            InputIndex(n, k, 0.0, 0.0)
            for n, k in [*((n, "range") for n in range_names), *((n, "list") for n in list_labels)]
        )
    out = [
        *_range_indices(X, range_names, Y, total, seed),
        *(_list_index(name, labels, Y, total, seed) for name, labels in list_labels.items()),
    ]
    return tuple(sorted(out, key=lambda i: -i.first_order))


def _range_indices(X: np.ndarray, names: list[str], Y: np.ndarray, total: float, seed: int) -> list[InputIndex]:
    if not names:
        return []
    from SALib.analyze import rbd_fast

    mean_over_lists = Y.mean(axis=1)
    share = float(mean_over_lists.var()) / total
    if not share > SHARE_TOLERANCE:  # RBD-FAST on rounding noise would divide 0 by 0
        return [InputIndex(n, "range", 0.0, 0.0) for n in names]
    problem = {"num_vars": len(names), "names": list(names), "bounds": [[0.0, 1.0]] * len(names)}
    found = rbd_fast.analyze(
        problem,
        np.asarray(X, dtype=float),
        mean_over_lists,
        M=HARMONICS,
        num_resamples=RESAMPLES,
        conf_level=CONF_LEVEL,
        seed=seed,
    )
    return [
        InputIndex(n, "range", float(s) * share, float(c) * share)
        for n, s, c in zip(names, found["S1"], found["S1_conf"])
    ]


def _between_values(labels: list, Y: np.ndarray, total: float) -> float:
    columns = np.asarray([str(v) for v in labels])
    grand = Y.mean()
    values = np.unique(columns)
    return float(sum((columns == v).mean() * (Y[:, columns == v].mean() - grand) ** 2 for v in values) / total)


def _list_index(name: str, labels: list, Y: np.ndarray, total: float, seed: int) -> InputIndex:
    from scipy.stats import norm

    rng = np.random.default_rng(seed)
    estimate = _between_values(labels, Y, total)
    boot = []
    for _ in range(RESAMPLES):
        rows = Y[rng.integers(0, len(Y), len(Y))]
        variance = float(rows.var())
        boot.append(_between_values(labels, rows, variance) if variance > 0 else 0.0)
    half_width = float(norm.ppf(0.5 + CONF_LEVEL / 2) * np.std(boot, ddof=1))
    return InputIndex(name, "list", estimate, half_width)


def adequacy(samples: int, indices: tuple[InputIndex, ...]) -> tuple[bool, str]:
    """(adequate, why): enough range samples and intervals narrow enough to rank the inputs."""
    if samples < MIN_SAMPLES:
        return False, (
            f"too few points: {samples} range samples, at least {MIN_SAMPLES} needed for a ranking "
            f"(raise [sampling] points)"
        )
    widest = max((i.half_width for i in indices), default=0.0)
    if widest > MAX_HALF_WIDTH:
        return False, (
            f"too few points: intervals up to +-{widest:.2f} (at most +-{MAX_HALF_WIDTH} to rank inputs) "
            f"with {samples} range samples (raise [sampling] points)"
        )
    return True, f"{samples} range samples; intervals at most +-{widest:.2f}"


def study_sensitivity(spec, rows: list[dict], metrics: list[str]) -> list[MetricSensitivity] | None:
    """The indices of each metric over the study's varied inputs; None when the study was not
    sampled with Latin hypercube or Sobol' or has no range variable (nothing to estimate from)."""
    if not SAMPLERS[spec.sampling.method].space_filling or not spec.ranges:
        return None
    range_names = list(spec.ranges)
    combos = math.prod(len(c.values) for c in spec.choices.values())
    list_names = [n for n, c in spec.choices.items() if len(c.values) > 1]
    samples = spec.sampling.points
    by_point = {r["point"]: r for r in rows}
    labels = {n: [None] * combos for n in list_names}
    for point, r in by_point.items():
        for n in list_names:
            labels[n][point % combos] = r[n]
    X = np.full((samples, len(range_names)), np.nan)
    for point, r in by_point.items():
        X[point // combos] = [float(r[n]) for n in range_names]
    return [
        _metric_sensitivity(m, X, range_names, by_point, combos, samples, labels, spec.sampling.seed) for m in metrics
    ]


def _metric_sensitivity(
    metric: str,
    X: np.ndarray,
    range_names: list[str],
    by_point: dict,
    combos: int,
    samples: int,
    labels: dict,
    seed: int,
) -> MetricSensitivity:
    Y = np.full((samples, combos), np.nan)
    for point, r in by_point.items():
        value = r.get(metric)
        if value is not None:
            Y[point // combos, point % combos] = float(value)
    complete = np.all(np.isfinite(Y), axis=1)
    used = int(complete.sum())
    if used < MIN_TO_ESTIMATE or any(None in v for v in labels.values()):
        return MetricSensitivity(
            metric,
            used,
            samples - used,
            (),
            False,
            f"too few points: {metric} computed at {used} complete range samples, at least "
            f"{MIN_TO_ESTIMATE} needed to estimate and {MIN_SAMPLES} to rank (raise [sampling] points)",
        )
    indices = first_order_indices(X[complete], range_names, Y[complete], labels, seed)
    ok, why = adequacy(used, indices)
    return MetricSensitivity(metric, used, samples - used, indices, ok, why)


def as_rows(results: list[MetricSensitivity]) -> list[dict]:
    """The tidy table: one row per (metric, input)."""
    return [
        {
            "metric": r.metric,
            **asdict(i),
            "samples": r.samples,
            "dropped": r.dropped,
            "adequate": r.adequate,
            "adequacy": r.adequacy,
        }
        for r in results
        for i in r.indices
    ]


def as_json(results: list[MetricSensitivity]) -> dict:
    return {
        "estimator": ESTIMATOR,
        "conf_level": CONF_LEVEL,
        "harmonics": HARMONICS,
        "min_samples": MIN_SAMPLES,
        "max_half_width": MAX_HALF_WIDTH,
        "metrics": [{**asdict(r), "indices": [asdict(i) for i in r.indices]} for r in results],
    }
