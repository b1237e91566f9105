"""The contract between the models (chain, replica) and the solvers.

A model is M x'' + C x' + K x = f(t) + g(x, x'), with f sampled and held linearly between
samples (first-order hold) and g an optional nonlinear force (friction). Units are whatever the
model uses consistently; the default chain model uses SI.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from dynamics.errors import DynamicsError

NonlinearForce = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (x, v) -> force, shape (n,)


@dataclass(frozen=True)
class SecondOrderSystem:
    """M, C, K (n, n) and an optional g(x, v). The matrices are kept as read-only float copies: a
    system cannot change once made, so what the solvers derive from it (modes, step matrices) can be
    cached under `cache_key`, computed once per system instead of on every solve."""

    mass: np.ndarray  # (n, n)
    damping: np.ndarray  # (n, n)
    stiffness: np.ndarray  # (n, n)
    nonlinear_force: NonlinearForce | None = None

    def __post_init__(self):
        for name in ("mass", "damping", "stiffness"):
            try:
                matrix = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise DynamicsError(f"system.{name}: expected a real (n, n) array") from None
            matrix.flags.writeable = False
            object.__setattr__(self, name, matrix)

    @property
    def n_dof(self) -> int:
        return self.mass.shape[0]

    @cached_property
    def cache_key(self) -> tuple:
        """The matrices' shapes and contents: systems with equal matrices share cache entries."""
        return tuple(item for m in (self.mass, self.damping, self.stiffness) for item in (m.shape, m.tobytes()))


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
