"""A memory budget for the stiffness study, checked on the finest mesh before anything is solved.

The study's peak memory is set by the sparse direct solve of its levels (solved side by side, see
fem.study), which grows faster than the unknowns (PARDISO's factor of a 3D mesh fills about as
n^(4/3)). The model below, peak = BASE + PER_DOF_POWER * n^(4/3) summed over the levels, is fitted
to peak resident memory measured on the built-in link and corpus parts (docs/incoming-wildcad.md,
"the memory model"; `/usr/bin/time -f "%M KB" python -m fem FILE --material al6061-t6 --json`):

    unknowns (coarse + fine)              peak measured    model
    39,432 + 39,012 (built-in link)       0.73 GB          0.88 GB
    55,749 + 93,609 (robot-arm link)      0.91 GB          1.35 GB
    74,070 + 122,325 (arm bar)            1.45 GB          1.70 GB
    190,449 + 369,156 (arm bar, 3.5 mm)   4.41 GB          5.23 GB
    193,707 + 368,547 (upper leg --bores) 5.18 GB          5.25 GB

Before any meshing, every level's unknowns are estimated from the part's volume, surface and holes
(geometry.mesh_estimate); sizes that cannot fit even at the estimate's low end are coarsened
(default sizes) or refused (sizes the user gave) at once, instead of after minutes of meshing.
Then the finest level is meshed (meshing costs little memory next to the solve) and its real
unknowns counted; if its solve and the coarser level's would exceed the budget, default sizes are
coarsened until they fit (the run says so in one line, with the k it gives), and sizes the user
gave are refused, naming the options that help. DEFAULT_MAX_MEMORY_GB suits a 2-core, 24 GB machine shared with other work.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from settings.run import LIMITS, MIN_MAX_MEMORY_GB

from .errors import FemError

DEFAULT_MAX_MEMORY_GB = 6.0
# Fitted to the measured peaks in the module docstring so that the model covers the largest ones
# (they decide whether a run fits): bytes. The base is also the smallest budget settings.LIMITS allows.
BASE_BYTES = MIN_MAX_MEMORY_GB * 1e9
PER_DOF_POWER_BYTES = 125.0
DOF_EXPONENT = 4 / 3
# Coarsen default sizes by at least this factor per retry (the estimate is rough; a few retries).
MIN_COARSENING = 1.1
MAX_RETRIES = 4
# Before meshing, the unknowns are estimated from the part (geometry.mesh_estimate); real / estimate
# was 0.85-1.04 on every default level measured (1.22 on the built-in link at 15 mm), so sizes whose
# estimate times this still exceeds the budget cannot fit and are coarsened or refused before gmsh
# meshes them. Sizes that pass are meshed and
# their real unknowns checked again (the estimate does not replace the count).
ESTIMATE_LOW_RATIO = 0.8
MAX_ESTIMATE_RETRIES = 20


@dataclass(frozen=True)
class MemoryBudget:
    """The most memory (bytes) a study may use."""

    max_bytes: float

    def __post_init__(self) -> None:
        check_max_memory_gb(self.max_bytes / 1e9)

    @classmethod
    def gigabytes(cls, gb: float) -> MemoryBudget:
        return cls(float(gb) * 1e9)

    @property
    def gb(self) -> float:
        return self.max_bytes / 1e9

    def fits(self, level_dofs: list[int]) -> bool:
        return peak_bytes(level_dofs) <= self.max_bytes

    def coarsening(self, level_dofs: list[int]) -> float:
        """The factor to multiply the element sizes by so that levels of these unknowns fit
        (unknowns scale as size^-3)."""
        over = (peak_bytes(level_dofs) - BASE_BYTES) / (self.max_bytes - BASE_BYTES)
        return max(MIN_COARSENING, over ** (1 / (3 * DOF_EXPONENT)))


def check_max_memory_gb(gb: float) -> float:
    """`gb` if settings.LIMITS allows it as a memory budget (the range's one home), else FemError."""
    problem = LIMITS["max_memory_gb"].problem(gb)
    if problem:
        raise FemError(problem)
    return gb


def peak_bytes(level_dofs: list[int]) -> float:
    """Estimated peak memory of solving levels of these many unknowns side by side."""
    return BASE_BYTES + PER_DOF_POWER_BYTES * float(np.sum(np.asarray(level_dofs, float) ** DOF_EXPONENT))


def mesh_dofs(tets: np.ndarray, tets10: np.ndarray | None, order: int) -> int:
    """Unknowns (3 per node) of a mesh for elements of `order`: P2 nodes are the vertices and the
    edges' midpoints (those of tets10 where given, else counted from the tets' edges)."""
    if order == 1:
        return 3 * len(np.unique(tets))
    if tets10 is not None:
        return 3 * len(np.unique(tets10))
    pairs = np.sort(np.hstack([tets[[i, j]] for i, j in ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))]), axis=0)
    return 3 * (len(np.unique(tets)) + len(np.unique(pairs, axis=1).T))


def levels_dofs(finest_dofs: int, n_levels: int, ratio: float) -> list[int]:
    """Unknowns of every level estimated from the finest's: coarser by ratio^3 per level."""
    return [int(finest_dofs / ratio ** (3 * i)) for i in range(n_levels)]


def over_budget_message(what: str, level_dofs: list[float], budget: MemoryBudget, estimated: bool = False) -> str:
    how = "at least about" if estimated else "about"
    when = " (estimated before meshing)" if estimated else ""
    return (
        f"{what}: {how} {int(sum(level_dofs))} unknowns over the levels{when} would need {how} "
        f"{peak_bytes(level_dofs) / 1e9:.1f} GB, over the memory budget of {budget.gb:g} GB; pass a larger "
        "--mesh-size in mm or a larger --max-memory GB"
    )
