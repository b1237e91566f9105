"""A solved link's fields at its nodes, for pictures and files: numpy only, so that a process that
draws them (the run's image process, stages.fea) does not import scikit-fem to receive them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class NodalFields:
    """A solution's nodes, cells (VTK node order) and fields at them, for pictures and files."""

    points_m: np.ndarray  # (3, n)
    cells: np.ndarray  # (n_cells, 4 or 10)
    displacement_m: np.ndarray  # (3, n)
    von_mises_Pa: np.ndarray  # (n,)
