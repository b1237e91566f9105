"""Richardson extrapolation of a mesh-dependent quantity from two or three mesh levels.

The mesh spacing of a level is h = N^(-1/3) (N = DOF count, 3D), which stays meaningful for
graded, non-nested meshes (Roache's GCI practice). The model is q(h) = q_inf + C h^p.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from .errors import FemError

# The link's stiffness converges at about h^1.5: the rim of the clamped bore is a clamped/free
# right-angle edge whose singular stress field ~ r^(lambda - 1), lambda ~ 0.71, limits the energy
# error to h^(2 lambda) ~ h^1.42 for any element order (and the field notes measured ~1.5).
# An observed rate above this is pre-asymptotic, so it is capped here; a lower observed rate is
# used as it is (it gives the larger, safer error estimate).
SINGULAR_RATE = 1.5
MIN_OBSERVED_RATE = 0.25


@dataclass(frozen=True)
class Extrapolation:
    extrapolated: float  # q_inf
    rate: float  # p used
    observed_rate: float | None  # from three monotone levels, else None
    monotone: bool  # successive differences have one sign
    rel_error_estimate: float  # |q_finest - q_inf| / |q_inf|


def observed_rate(values: np.ndarray, spacing: np.ndarray) -> float | None:
    """Rate p from three levels (coarse to fine) of q = q_inf + C h^p, or None if not monotone."""
    q1, q2, q3 = values
    h1, h2, h3 = spacing
    d12, d23 = q1 - q2, q2 - q3
    if d12 == 0 or d23 == 0 or np.sign(d12) != np.sign(d23):
        return None
    ratio = d12 / d23

    def mismatch(p: float) -> float:
        return (h1**p - h2**p) / (h2**p - h3**p) - ratio

    lo, hi = MIN_OBSERVED_RATE, 12.0
    if mismatch(lo) * mismatch(hi) > 0:
        return None
    return float(brentq(mismatch, lo, hi, xtol=1e-10))


def extrapolate(values, dofs, assumed_rate: float = SINGULAR_RATE) -> Extrapolation:
    """Extrapolate the finest of 2-3 levels (ordered coarse to fine by DOF count)."""
    values = np.asarray(values, dtype=float)
    dofs = np.asarray(dofs, dtype=float)
    if len(values) not in (2, 3) or len(dofs) != len(values):
        raise FemError(f"Richardson extrapolation needs 2 or 3 mesh levels, got {len(values)}")
    if np.any(np.diff(dofs) <= 0):
        raise FemError(f"mesh levels must have strictly increasing DOF counts, got {dofs.astype(int).tolist()}")
    spacing = dofs ** (-1.0 / 3.0)
    differences = np.diff(values)
    monotone = bool(np.all(differences > 0) or np.all(differences < 0))
    seen = observed_rate(values, spacing) if len(values) == 3 else None
    rate = assumed_rate if seen is None else min(seen, assumed_rate)
    h_coarse, h_fine = spacing[-2], spacing[-1]
    q_coarse, q_fine = values[-2], values[-1]
    q_inf = q_fine - (q_coarse - q_fine) * h_fine**rate / (h_coarse**rate - h_fine**rate)
    error = abs(q_fine - q_inf) / abs(q_inf)
    if not monotone:
        # Oscillating levels: the scatter itself is the honest error scale.
        error = max(error, float(np.max(np.abs(differences))) / abs(q_inf))
    return Extrapolation(float(q_inf), float(rate), seen, monotone, float(error))
