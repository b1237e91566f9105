"""Richardson extrapolation of a mesh-dependent quantity from two or three mesh levels.

The mesh spacing of a level is h = N^(-1/3) (N = DOF count, 3D), which stays meaningful for
graded, non-nested meshes (Roache's GCI practice). The model is q(h) = q_inf + C h^p.

The link's rate is set by its singular edges, not by the element order:
- the rim of the clamped bore is a clamped/free right-angle edge, singular stress ~ r^(lambda-1)
  with lambda ~ 0.71, so the energy (and k) error goes as h^(2 lambda) ~ h^1.42 (the field notes
  measured ~1.5);
- a sharp re-entrant 270-degree free edge (a pocket without corner radii) has lambda ~ 0.545:
  h^1.09;
- without singularities P2 would converge at h^4, but such a rate is never seen on these parts at
  affordable meshes.
So q_inf is extrapolated with p = 1.5 from the two finest levels, and its error is estimated as
the largest change of q_inf when p moves over [1, 2] or (three levels) when the coarser pair of
levels is used instead. For data that follow the model with any p in [1, 2] the bracket part is a
guaranteed bound (q_inf is monotone in p); the pair part catches mesh-to-mesh noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from .errors import FemError

ASSUMED_RATE = 1.5
RATE_BRACKET = (1.0, 2.0)


@dataclass(frozen=True)
class Extrapolation:
    extrapolated: float  # q_inf with the assumed rate, from the two finest levels
    rate: float  # p used
    observed_rate: float | None  # from three monotone levels (for information), else None
    monotone: bool  # successive differences have one sign
    rel_error_estimate: float  # estimated |q_inf - q_exact| / |q_inf|
    finest_rel_error_estimate: float  # |q_finest - q_inf| / |q_inf|: error of the finest level itself


def pair_extrapolation(q_coarse: float, q_fine: float, h_coarse: float, h_fine: float, rate: float) -> float:
    """q_inf from two levels of q = q_inf + C h^p with p = rate."""
    return q_fine - (q_coarse - q_fine) * h_fine**rate / (h_coarse**rate - h_fine**rate)


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

    lo, hi = 0.05, 12.0
    if mismatch(lo) * mismatch(hi) > 0:
        return None
    return float(brentq(mismatch, lo, hi, xtol=1e-10))


def extrapolate(values, dofs, rate: float = ASSUMED_RATE, bracket: tuple[float, float] = RATE_BRACKET) -> Extrapolation:
    """Extrapolate 2-3 levels ordered coarse to fine by DOF count (see the module docstring)."""
    values = np.asarray(values, dtype=float)
    dofs = np.asarray(dofs, dtype=float)
    if len(values) not in (2, 3) or len(dofs) != len(values):
        raise FemError(f"Richardson extrapolation needs 2 or 3 mesh levels, got {len(values)}")
    if np.any(np.diff(dofs) <= 0):
        raise FemError(f"mesh levels must have strictly increasing DOF counts, got {dofs.astype(int).tolist()}")
    h = dofs ** (-1.0 / 3.0)
    q_inf = pair_extrapolation(values[-2], values[-1], h[-2], h[-1], rate)
    alternatives = [pair_extrapolation(values[-2], values[-1], h[-2], h[-1], p) for p in bracket]
    if len(values) == 3:
        alternatives.append(pair_extrapolation(values[0], values[1], h[0], h[1], rate))
    differences = np.diff(values)
    monotone = bool(np.all(differences > 0) or np.all(differences < 0))
    error = max(abs(a - q_inf) for a in alternatives) / abs(q_inf)
    if not monotone:
        # Oscillating levels: the model does not hold; the scatter itself is the error scale.
        error = max(error, float(np.max(np.abs(differences))) / abs(q_inf))
    return Extrapolation(
        extrapolated=float(q_inf),
        rate=float(rate),
        observed_rate=observed_rate(values, h) if len(values) == 3 else None,
        monotone=monotone,
        rel_error_estimate=float(error),
        finest_rel_error_estimate=float(abs(values[-1] - q_inf) / abs(q_inf)),
    )
