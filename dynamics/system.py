"""The contract between the models (chain, replica) and the solvers.

A model is M x'' + C x' + K x = f(t) + g(x, x'), with f sampled and held linearly between
samples (first-order hold) and g an optional nonlinear force (friction). Units are whatever the
model uses consistently; the default chain model uses SI.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

NonlinearForce = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (x, v) -> force, shape (n,)


@dataclass(frozen=True)
class SecondOrderSystem:
    mass: np.ndarray  # (n, n)
    damping: np.ndarray  # (n, n)
    stiffness: np.ndarray  # (n, n)
    nonlinear_force: NonlinearForce | None = None

    @property
    def n_dof(self) -> int:
        return self.mass.shape[0]


@dataclass(frozen=True)
class SampledForce:
    """Force samples f[i] at times t_s[i], linear in between (first-order hold)."""

    t_s: np.ndarray  # (m,) strictly increasing
    values: np.ndarray  # (m, n)

    def at(self, t: float) -> np.ndarray:
        i = int(np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, len(self.t_s) - 2))
        w = (t - self.t_s[i]) / (self.t_s[i + 1] - self.t_s[i])
        return (1.0 - w) * self.values[i] + w * self.values[i + 1]


@dataclass(frozen=True)
class Response:
    """Displacement, velocity and acceleration of every degree of freedom at the output times."""

    t_s: np.ndarray  # (m,)
    x: np.ndarray  # (m, n)
    v: np.ndarray  # (m, n)
    a: np.ndarray  # (m, n)
    method: str
