"""The idler tensioner's carriage (dynamics.models.clearance's model of it), apart from the chain
models so that the settings check its three options without importing them (numba, SciPy)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from dynamics.errors import DynamicsError


@dataclass(frozen=True)
class Tensioner:
    """The idler carriage: spring rate k_t (N/m, >= 0), mass m_t (kg, > 0), damping c_t (N s/m, >= 0)."""

    rate_N_per_m: float
    mass_kg: float
    damping_N_s_per_m: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_N_per_m) and self.rate_N_per_m >= 0):
            raise DynamicsError(f"tensioner rate_N_per_m: expected a finite value >= 0, got {self.rate_N_per_m!r}")
        if not (math.isfinite(self.mass_kg) and self.mass_kg > 0):
            raise DynamicsError(f"tensioner mass_kg: expected a finite mass > 0, got {self.mass_kg!r}")
        if not (math.isfinite(self.damping_N_s_per_m) and self.damping_N_s_per_m >= 0):
            raise DynamicsError(
                f"tensioner damping_N_s_per_m: expected a finite value >= 0, got {self.damping_N_s_per_m!r}"
            )


def tensioner_from(rate_N_per_m, mass_kg, damping_N_s_per_m) -> Tensioner | None:
    """The optional idler tensioner from its three settings (None when none is given)."""
    if rate_N_per_m is None and mass_kg is None and damping_N_s_per_m is None:
        return None
    if mass_kg is None:
        raise ValueError("the tensioner needs its carriage mass (--tensioner-mass KG) with its rate or damping")
    return Tensioner(
        0.0 if rate_N_per_m is None else rate_N_per_m, mass_kg, 0.0 if damping_N_s_per_m is None else damping_N_s_per_m
    )
