"""What the reporting layer needs of one simulated scenario (one material, one cam law)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CamHistory:
    """Time histories of one scenario, SI units. Link arrays are (n_times, n_links)."""

    material: str
    cam: str
    t_s: np.ndarray
    z_m: np.ndarray  # cam input displacement, (n_times,)
    zdot_m_s: np.ndarray
    zddot_m_s2: np.ndarray
    x_m: np.ndarray
    v_m_s: np.ndarray
    a_m_s2: np.ndarray
    tension_N: np.ndarray
    dwell_mask: np.ndarray  # (n_times,) True inside dwells

    @property
    def n_links(self) -> int:
        return self.x_m.shape[1]
