"""Truncated modal coordinates for long chains: y = shapes q with the r lowest modes.

The chain's dense matrices grow as N^2 (N = 10,000 links: 800 MB each, and a dense eigensolve of
minutes), so for long chains `simulate(..., n_modes=r)` solves the same model in its r lowest
mass-normalised modes: M_r = I, C_r = diag(c_j), K_r = diag(w_j^2), modal forces shapes^T f. The
modes come from a sparse eigensolve (`dynamics.response.sweep.chain_modes`), the damping is the model's
modal damping, and friction is projected (shapes^T g(shapes q, shapes q')), so the same solvers and
the same steady-state iteration run on an r-DOF system. Truncation converges in these relative
coordinates (the cam's rigid motion is exact; on the default 85-link chain the first mode carries
84 % of the effective mass, see dynamics.response.sweep).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from dynamics.models.chain import ChainModel
from dynamics.models.system import SecondOrderSystem
from dynamics.options import DENSE_LINK_LIMIT  # declared where the settings read it without SciPy


@dataclass(frozen=True, eq=False)
class ModalBasis:
    shapes: np.ndarray  # (N, r) mass-normalised mode shapes
    system: SecondOrderSystem  # the r-DOF modal system
    participation: np.ndarray  # (r,) shapes^T M 1: the modal weight of the base excitation -M 1 z''


def modal_basis(model: ChainModel, n_modes: int) -> ModalBasis:
    from dynamics.response.sweep import chain_modes

    # the modes of the linear chain; friction enters later as a projected force
    modes = chain_modes(replace(model, friction_coefficient=0.0), n_modes)
    system = SecondOrderSystem(np.eye(modes.n_modes), np.diag(modes.damping_1_s), np.diag(modes.omega_rad_s**2))
    return ModalBasis(modes.shapes, system, modes.participation)


class ProjectedForce:
    """A force g(t, y, y') on the links, seen by the modal coordinates: shapes^T g(t, shapes q, shapes q')."""

    def __init__(self, force, shapes: np.ndarray):
        self.force = force
        self.shapes = shapes

    def __call__(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        y = self.shapes @ q if self._positions else None
        return self.shapes.T @ self.force(t, y, self.shapes @ qd)

    def batch(self, t: np.ndarray, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        y = q @ self.shapes.T if self._positions else None
        return self.force.batch(t, y, qd @ self.shapes.T) @ self.shapes

    @property
    def _positions(self) -> bool:
        """False for a force that says it reads the velocities only (friction): then one (N x r)
        product of the three per call is left out."""
        return getattr(self.force, "uses_positions", True)


# Above DENSE_LINK_LIMIT links (dynamics.options) the pipeline solves in the lowest MODES_FOR_LONG_CHAINS modes: the dense
# path's cost grows as N^2.65 (4 s per scenario at N = 1000) and its memory as N^2. 400 modes put
# the truncation error of a 10,000-link chain at 6e-6 (residual vibration) and 1e-4 (peak
# acceleration) relative to 800 modes (benchmarks/chart_dynamics_cost.py).
MODES_FOR_LONG_CHAINS = 400


def modes_to_keep(n_links: int) -> int | None:
    """None (all link coordinates) for short chains, else the number of modes to solve in."""
    return None if n_links <= DENSE_LINK_LIMIT else MODES_FOR_LONG_CHAINS


@lru_cache(maxsize=16)
def lowest_natural_frequencies_Hz(model: ChainModel, count: int) -> np.ndarray:
    """The `count` lowest undamped natural frequencies, without a dense eigensolve for long chains.
    Cached (read-only result): the progress line, the summary and the report all ask for them."""
    if model.n_links <= DENSE_LINK_LIMIT:
        frequencies = model.natural_frequencies_Hz()[:count]
    else:
        from dynamics.response.sweep import chain_modes

        modes = chain_modes(replace(model, friction_coefficient=0.0), min(count, model.n_links))
        frequencies = modes.natural_frequencies_Hz
    frequencies.flags.writeable = False
    return frequencies
