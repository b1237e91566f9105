"""A new study sampler is one registration: the study file accepts it, its points are the study's
design points, its size key and its own check are enforced, and the sensitivity estimate takes it
when it fills the box."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from study_cluster import small_study

from study.samplers import SAMPLERS, Sampler, SamplingSize
from study.sampling import design_points
from study.spec import StudyError, parse_study
from study.tasks import base_config


def _halton(lows, highs, size: SamplingSize) -> np.ndarray:
    from scipy.stats import qmc

    return qmc.scale(qmc.Halton(d=len(lows), seed=size.seed).random(size.points), lows, highs)


def _at_most_16(size: SamplingSize) -> str | None:
    return None if size.points <= 16 else f"sampling.points: halton takes at most 16, got {size.points}"


@pytest.fixture
def halton(monkeypatch):
    monkeypatch.setitem(SAMPLERS, "halton", Sampler("halton", _halton, "points", True, _at_most_16))


def _study(points: int) -> str:
    return small_study().replace('method = "grid"\nlevels = 2', f'method = "halton"\npoints = {points}')


def test_a_registered_sampler_gives_the_design_points(halton):
    spec = parse_study(tomllib.loads(_study(5)))
    points = design_points(spec, base_config(spec.settings))
    combos = int(np.prod([len(c.values) for c in spec.choices.values()]))
    assert len(points) == 5 * combos
    name, bounds = next(iter(spec.ranges.items()))
    sampled = {p.inputs[name] for p in points}
    expected = _halton(np.array([bounds.min]), np.array([bounds.max]), SamplingSize(0, 5, spec.sampling.seed))
    assert sorted(sampled) == pytest.approx(sorted(expected[:, 0]), rel=1e-12)


def test_its_size_key_and_check_are_enforced(halton):
    with pytest.raises(StudyError, match="halton takes at most 16"):
        parse_study(tomllib.loads(_study(32)))
    with pytest.raises(StudyError, match="sampling.levels: only for grid; halton takes points"):
        parse_study(tomllib.loads(_study(4).replace("points = 4", "points = 4\nlevels = 3")))


def test_unregistered_method_is_refused_naming_the_registered_ones():
    with pytest.raises(StudyError, match="sampling.method: expected one of grid, lhs, sobol"):
        parse_study(tomllib.loads(_study(4)))
