"""The FEA's settings in one object: `FeaSettings`, what every stiffness and stress study takes
(`fem.study`, `fem.adaptive`, `fem.stress`) instead of a list of keywords each passes on.

Defaults and checks live here; a run's settings (`stages`) and `python -m fem` build one from their
options. Frozen and made of plain values, so a run's configuration can hold one and a new setting
is one field here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .budget import DEFAULT_MAX_MEMORY_GB, check_max_memory_gb
from .errors import FemError
from .options import check_element_order, check_linear_solver

#: Successive mesh levels differ by this size ratio.
LEVEL_RATIO = 4 / 3
DEFAULT_LEVELS = 2
# Element size at the bores as a fraction of the size elsewhere. On the default link the stiffness
# error lives mostly away from the bores (thin rails, sharp pocket edges): per DOF, 0.7 was more
# accurate than 0.4 (geometry's default), 0.25 and 0.15 (measured, see the report).
DEFAULT_BORE_REFINEMENT = 0.7
#: The pin load for the fields and images (N); k and the stresses per newton do not depend on it.
DEFAULT_LOAD_N = 1000.0
#: The stress study stops when the last halving of the local element size moved the peak by at most this.
DEFAULT_STRESS_TOLERANCE = 0.05


def levels_for_finest(finest_m: float, n_levels: int = DEFAULT_LEVELS, ratio: float = LEVEL_RATIO) -> tuple[float, ...]:
    """Mesh sizes coarse to fine ending at `finest_m`, successive ratio `ratio`."""
    return tuple(finest_m * ratio**i for i in reversed(range(n_levels)))


def check_sizes(sizes: Sequence[float]) -> tuple[float, ...]:
    """2 or 3 positive mesh sizes in metres, decreasing (coarse to fine), as floats."""
    sizes = tuple(float(h) for h in sizes)
    if len(sizes) not in (2, 3):
        raise FemError(f"mesh_sizes_m: expected 2 or 3 sizes, got {len(sizes)}")
    if not all(np.isfinite(h) and h > 0 for h in sizes):
        raise FemError(f"mesh_sizes_m: sizes must be positive numbers in metres, got {list(sizes)}")
    if any(b >= a for a, b in zip(sizes, sizes[1:])):
        raise FemError(f"mesh_sizes_m: sizes must decrease (coarse to fine), got {list(sizes)}")
    return sizes


@dataclass(frozen=True)
class FeaSettings:
    """How the link is discretised and solved (SI units). Checked on construction (FemError)."""

    # the stiffness study's levels, coarse to fine (2 or 3); None: relative to the part
    # (fem.study.default_mesh_sizes). `with_finest` builds them from the finest size.
    mesh_sizes_m: tuple[float, ...] | None = None
    order: int = 2  # 1: linear tetrahedra, 2: quadratic
    curved: bool = True  # order 2 on curved (isoparametric) cells whose mid-edge nodes lie on the CAD
    # solve the finest level on the half of a link that is mirror symmetric about the plane through
    # its bore axes (checked); False: the whole link everywhere (python -m fem --full-model)
    mirror_symmetry: bool = True
    load_N: float = DEFAULT_LOAD_N
    solver: str = "auto"  # the linear solver (fem.solvers): auto, pardiso, amg or spsolve
    bore_refinement: float = DEFAULT_BORE_REFINEMENT  # element size at the bores / size elsewhere
    # mesh the next level while the previous ones solve (threads); False where every core already
    # runs a task (the design study's workers)
    concurrent_levels: bool = True
    stress_tolerance: float = DEFAULT_STRESS_TOLERANCE
    # the memory budget of the stiffness study's solves (fem.budget), checked before solving
    max_memory_gb: float = DEFAULT_MAX_MEMORY_GB

    def __post_init__(self) -> None:
        check_element_order(self.order)  # by name: fem.problem and fem.solvers load scikit-fem and SciPy
        check_linear_solver(self.solver)
        if self.mesh_sizes_m is not None:
            object.__setattr__(self, "mesh_sizes_m", check_sizes(self.mesh_sizes_m))
        if not (isinstance(self.load_N, (int, float)) and math.isfinite(self.load_N) and self.load_N > 0):
            raise FemError(f"load_N must be a positive number, got {self.load_N!r}")
        if not (isinstance(self.stress_tolerance, (int, float)) and 0 < self.stress_tolerance < 1):
            raise FemError(f"tolerance={self.stress_tolerance!r}: expected a relative change in (0, 1), e.g. 0.05")
        check_max_memory_gb(self.max_memory_gb)

    @classmethod
    def with_finest(cls, finest_m: float | None, **fields) -> FeaSettings:
        """Settings whose levels end at `finest_m` (DEFAULT_LEVELS of them, LEVEL_RATIO apart); None:
        relative to the part."""
        return cls(mesh_sizes_m=None if finest_m is None else levels_for_finest(finest_m), **fields)

    @property
    def mesh_order(self) -> int:
        """The geometry's element order: 2 (curved quadratic cells) for curved P2, else 1."""
        return 2 if (self.order == 2 and self.curved) else 1


def settings_with(settings: FeaSettings | None, changes: dict) -> FeaSettings:
    """`settings` (None: the defaults) with the fields in `changes` replaced: the studies' keyword
    form, `stiffness_study(part, material, order=1)`, for a caller with no settings object."""
    base = FeaSettings() if settings is None else settings
    return replace(base, **changes) if changes else base
