"""The samplers of a study's range variables, in one registry (as meshio registers its formats).

A sampler turns the ranges' lower and upper bounds into the sampled values, one row per sample.
It says how its size is given (`levels` per range for a full grid, or a total of `points`), whether
its points fill the box at random (the sensitivity estimate needs that), and any check of its own.
A new sampler is one `register_sampler` call; the study file's `sampling.method` accepts it at once.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SamplingSize:
    levels: int  # per range (full grid)
    points: int  # in all (space-filling samplers)
    seed: int


@dataclass(frozen=True)
class Sampler:
    name: str
    values: Callable[[np.ndarray, np.ndarray, SamplingSize], np.ndarray]  # (lows, highs, size) -> (n, d)
    size_key: str  # "levels" or "points": the [sampling] key that sizes it
    space_filling: bool  # random or quasi-random points over the whole box (sensitivity can be estimated)
    check: Callable[[SamplingSize], str | None] = lambda size: None  # why the size is refused, or None


SAMPLERS: dict[str, Sampler] = {}


def register_sampler(sampler: Sampler) -> None:
    SAMPLERS[sampler.name] = sampler


def _grid(lows, highs, size: SamplingSize) -> np.ndarray:
    axes = [np.linspace(lo, hi, size.levels) for lo, hi in zip(lows, highs)]
    return np.array(list(itertools.product(*axes)), dtype=float)


def _qmc(engine_of: Callable[[int, int], object]):
    def values(lows, highs, size: SamplingSize) -> np.ndarray:
        from scipy.stats import qmc

        return qmc.scale(engine_of(len(lows), size.seed).random(size.points), lows, highs)

    return values


def _latin_hypercube(d: int, seed: int):
    from scipy.stats import qmc

    return qmc.LatinHypercube(d=d, seed=seed)


def _sobol(d: int, seed: int):
    from scipy.stats import qmc

    return qmc.Sobol(d=d, scramble=True, seed=seed)


def _power_of_two(size: SamplingSize) -> str | None:
    if size.points & (size.points - 1):
        return f"sampling.points: Sobol sampling needs a power of 2 to stay balanced, got {size.points}"
    return None


register_sampler(Sampler("grid", _grid, "levels", space_filling=False))
register_sampler(Sampler("lhs", _qmc(_latin_hypercube), "points", space_filling=True))
register_sampler(Sampler("sobol", _qmc(_sobol), "points", space_filling=True, check=_power_of_two))
