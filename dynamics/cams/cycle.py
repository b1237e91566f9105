"""Where a time falls in a cam's cycle: shared by the analytic programs and the tabulated cams."""

from __future__ import annotations

import numpy as np

from dynamics.errors import DynamicsError


def checked_times(t_s, one_shot: str | None) -> np.ndarray:
    """t_s as floats; finite, and not before t = 0 when `one_shot` names a one-shot motion (None:
    periodic, any time is within some cycle)."""
    t = np.asarray(t_s, dtype=float)
    if not np.all(np.isfinite(t)):
        raise DynamicsError("t_s: got non-finite times; expected finite times in seconds")
    if one_shot is not None and np.any(t < 0):
        raise DynamicsError(f"t_s: got {float(t.min())!r} s; a one-shot {one_shot} starts at t = 0, expected t >= 0")
    return t


def wrap(phase: np.ndarray, period: float, advance_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Phase within its cycle and the displacement (m) the completed cycles have added."""
    cycles = np.floor(phase / period)
    return phase - cycles * period, cycles * advance_m
