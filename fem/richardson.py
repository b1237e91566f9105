"""Richardson extrapolation of a mesh-dependent quantity from two or three mesh levels, with a bound.

The mesh spacing of a level is h = N^(-1/3) (N = DOF count, 3D), which stays meaningful for
graded, non-nested meshes (Roache's GCI practice). The model is q(h) = q_inf + C h^p with the
rate p unknown but bracketed:

- from below by 1: the worst singular edges these parts have are the rim of the clamped bore (a
  clamped/free right-angle edge, stress ~ r^(lambda-1) with lambda ~ 0.71, so the energy and k
  converge as h^(2 lambda) ~ h^1.42; the field notes measured ~1.5) and a sharp re-entrant
  270-degree free edge (lambda ~ 0.545: h^1.09);
- from above by 2 x the element order + 1: the energy (and so k = F^2 / 2U) of a smooth solution
  converges as h^(2k) for elements of degree k (h^4 for curved P2, whose geometry error is of the
  same order), and nothing converges faster; the + 1 is for h = N^(-1/3) itself, which is the
  spacing only asymptotically: with the node layers on the boundary N grows more slowly than
  h^-3 on coarse meshes (the Lame cylinder refined uniformly from 4 to 8 cells across has 6.6x the
  DOFs, not 8x), so a true h^4 shows as h^4.15 there (measured in
  tests/test_fea_estimate_verification.py).

q_inf(p) from the two finest levels, q_fine - (q_coarse - q_fine) / (r^p - 1) with r the spacing
ratio, is monotone in p, so for data that follow the model with any p in the bracket q_inf lies
between q_inf(p_min) and q_inf(p_max). The reported value is the middle of that interval and its
error estimate the half-width: a guaranteed bound under the model, whatever the rate in the
bracket (smooth verification parts as well as singular links). With three levels the coarser
pair's interval is included too (it catches mesh-to-mesh noise), and levels that oscillate report
their scatter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import FemError

MIN_RATE = 1.0  # sharp re-entrant edge: h^1.09; clamped bore rim: h^1.42


def rate_bracket(order: int) -> tuple[float, float]:
    """Rates p of k(h) = k_inf + C h^p, h = DOFs^(-1/3), possible with elements of `order` (module doc)."""
    return (MIN_RATE, 2.0 * order + 1.0)


DEFAULT_BRACKET = rate_bracket(2)


@dataclass(frozen=True)
class Extrapolation:
    extrapolated: float  # middle of the interval of q_inf over the rate bracket, two finest levels
    rate_bracket: tuple[float, float]  # (p_min, p_max)
    observed_rate: float | None  # from three monotone levels (for information), else None
    monotone: bool  # successive differences have one sign
    rel_error_estimate: float  # bound on |q_inf - q_exact| / |q_inf| under the model (half-width)
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
    # imported here: two levels (the default study) never get here, and SciPy's optimize costs
    # the FEA's process about 0.2 CPU s to import
    from scipy.optimize import brentq

    return float(brentq(mismatch, lo, hi, xtol=1e-10))


def extrapolate(values, dofs, bracket: tuple[float, float] = DEFAULT_BRACKET) -> Extrapolation:
    """Extrapolate 2-3 levels ordered coarse to fine by DOF count (see the module docstring)."""
    values = np.asarray(values, dtype=float)
    dofs = np.asarray(dofs, dtype=float)
    if len(values) not in (2, 3) or len(dofs) != len(values):
        raise FemError(f"Richardson extrapolation needs 2 or 3 mesh levels, got {len(values)}")
    if np.any(np.diff(dofs) <= 0):
        raise FemError(f"mesh levels must have strictly increasing DOF counts, got {dofs.astype(int).tolist()}")
    if not 0 < bracket[0] <= bracket[1]:
        raise FemError(f"rate bracket {bracket!r}: expected 0 < p_min <= p_max")
    h = dofs ** (-1.0 / 3.0)
    ends = [pair_extrapolation(values[-2], values[-1], h[-2], h[-1], p) for p in bracket]
    q_inf = 0.5 * (ends[0] + ends[1])
    if len(values) == 3:
        ends += [pair_extrapolation(values[0], values[1], h[0], h[1], p) for p in bracket]
    differences = np.diff(values)
    monotone = bool(np.all(differences > 0) or np.all(differences < 0))
    error = max(abs(e - q_inf) for e in ends) / abs(q_inf)
    if not monotone:
        # Oscillating levels: the model does not hold; the scatter itself is the error scale.
        error = max(error, float(np.max(np.abs(differences))) / abs(q_inf))
    return Extrapolation(
        extrapolated=float(q_inf),
        rate_bracket=(float(bracket[0]), float(bracket[1])),
        observed_rate=observed_rate(values, h) if len(values) == 3 else None,
        monotone=monotone,
        rel_error_estimate=float(error),
        finest_rel_error_estimate=float(abs(values[-1] - q_inf) / abs(q_inf)),
    )
