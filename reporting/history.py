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
    tension_N: np.ndarray  # (n_times, n_springs), every spring of the chain
    dwell_mask: np.ndarray  # (n_times,) True inside dwells
    links: tuple[int, ...] | None = None  # 1-based link of each column of x/v/a; None: every link in order

    def column(self, link: int) -> int:
        """Column of the 1-based `link` in x_m, v_m_s, a_m_s2."""
        return link - 1 if self.links is None else self.links.index(link)
