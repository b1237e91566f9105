"""Link stiffness with a discretisation-error estimate: 2-3 mesh levels + Richardson extrapolation."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from .errors import FemError
from .link import LinkSolution, analyse_link
from .materials import Material
from .problem import element
from .richardson import Extrapolation, extrapolate
from .solvers import resolve

# Chosen by measurement on the default link (see the report / README): three curved-P2 levels
# whose total wall time (meshing + assembly + solve) stays under 20 s on 2 cores.
DEFAULT_MESH_SIZES_M = (0.0065, 0.0045, 0.0035)
# Element size at the bores as a fraction of the size elsewhere. On the default link the stiffness
# error lives mostly away from the bores (thin rails, sharp pocket edges): per DOF, 0.7 was more
# accurate than 0.4 (geometry's default), 0.25 and 0.15 (measured, see the report).
DEFAULT_BORE_REFINEMENT = 0.7


@dataclass(frozen=True, eq=False)
class StiffnessEstimate:
    """Richardson-extrapolated k with its estimated relative discretisation error (see richardson)."""

    stiffness_N_per_m: float  # extrapolated to zero mesh size
    stiffness_rel_error_estimate: float  # estimated relative error of stiffness_N_per_m
    stiffness_finest_N_per_m: float  # finest mesh itself: FE is too stiff, an upper bound
    finest_rel_error_estimate: float  # (k_finest - k) / k
    convergence_rate: float  # p used in k(h) = k_inf + C h^p, h = DOFs^(-1/3)
    observed_convergence_rate: float | None  # from three levels, for information
    monotone: bool
    levels: tuple[tuple[float, int, float], ...]  # (mesh_size_m, dofs, stiffness_N_per_m), coarse to fine
    finest: LinkSolution
    timing_s: dict[str, float]  # summed over levels: mesh, assembly, load, solve, post, total


def _check_sizes(sizes: Sequence[float]) -> tuple[float, ...]:
    sizes = tuple(float(h) for h in sizes)
    if len(sizes) not in (2, 3):
        raise FemError(f"mesh_sizes_m: expected 2 or 3 sizes, got {len(sizes)}")
    if not all(np.isfinite(h) and h > 0 for h in sizes):
        raise FemError(f"mesh_sizes_m: sizes must be positive numbers in metres, got {list(sizes)}")
    if any(b >= a for a, b in zip(sizes, sizes[1:])):
        raise FemError(f"mesh_sizes_m: sizes must decrease (coarse to fine), got {list(sizes)}")
    return sizes


def levels_for_finest(finest_m: float, n_levels: int = 3, ratio: float = 4 / 3) -> tuple[float, ...]:
    """Mesh sizes coarse to fine ending at `finest_m`, successive ratio `ratio`."""
    return tuple(finest_m * ratio**i for i in reversed(range(n_levels)))


def stiffness_study(
    source: str | Path | None = None,
    material: Material | None = None,
    *,
    mesh_sizes_m: Sequence[float] | None = None,
    order: int = 2,
    load_N: float = 1000.0,
    solver: str = "auto",
    curved: bool = True,
    bore_refinement: float = DEFAULT_BORE_REFINEMENT,
    progress: Callable[[str], None] | None = None,
) -> StiffnessEstimate:
    """Mesh the link (None = built-in default) at 2-3 sizes, solve each, extrapolate k.

    `curved` asks geometry for isoparametric quadratic cells when order == 2.
    """
    if material is None:
        raise FemError("stiffness_study: a material is required")
    return stiffness_studies(source, [material], mesh_sizes_m=mesh_sizes_m, order=order, load_N=load_N,
                             solver=solver, curved=curved, bore_refinement=bore_refinement,
                             progress=progress)[material.name]


def stiffness_studies(
    source: str | Path | None,
    materials: Sequence[Material],
    *,
    mesh_sizes_m: Sequence[float] | None = None,
    order: int = 2,
    load_N: float = 1000.0,
    solver: str = "auto",
    curved: bool = True,
    bore_refinement: float = DEFAULT_BORE_REFINEMENT,
    progress: Callable[[str], None] | None = None,
) -> dict[str, StiffnessEstimate]:
    """`stiffness_study` for several materials, meshing each level once for all of them.

    `progress`, if given, gets one line per solve (level, material, DOFs, k, seconds).
    """
    import geometry

    if not materials:
        raise FemError("stiffness_studies: expected at least one material")
    element(order)  # validate before meshing
    resolve(solver)
    sizes = _check_sizes(DEFAULT_MESH_SIZES_M if mesh_sizes_m is None else mesh_sizes_m)
    mesh_order = 2 if (order == 2 and curved) else 1
    mesh_time = 0.0
    solutions: dict[str, list[LinkSolution]] = {m.name: [] for m in materials}
    for level, h in enumerate(sizes, start=1):
        start = time.perf_counter()
        link = geometry.load_link(source, mesh_size_m=h, order=mesh_order, bore_refinement=bore_refinement)
        mesh_time += time.perf_counter() - start
        for material in materials:
            solution = analyse_link(link, material, order=order, load_N=load_N, solver=solver)
            solutions[material.name].append(solution)
            if progress is not None:
                progress(f"FEA level {level}/{len(sizes)}, {material.name}: h = {h * 1e3:.2f} mm, "
                         f"{solution.dofs} DOFs, k = {solution.stiffness_N_per_m:.5g} N/m, "
                         f"{sum(solution.timing_s.values()):.1f} s")
    # Meshing is shared: each material's timing carries its share of it.
    return {name: estimate_from_levels(sizes, sols, mesh_time / len(materials)) for name, sols in solutions.items()}


def estimate_from_levels(sizes: Sequence[float], solutions: list[LinkSolution], mesh_time_s: float,
                         fit_last: int | None = None) -> StiffnessEstimate:
    """The estimate from solved levels (coarse to fine); k is extrapolated from the last `fit_last`
    levels (all when None), every level is recorded."""
    timing: dict[str, float] = {"mesh": mesh_time_s}
    for solution in solutions:
        for key, value in solution.timing_s.items():
            timing[key] = timing.get(key, 0.0) + value
    timing["total"] = sum(timing.values())
    fitted = solutions if fit_last is None else solutions[-fit_last:]
    k = [s.stiffness_N_per_m for s in fitted]
    fit: Extrapolation = extrapolate(k, [s.dofs for s in fitted])
    return StiffnessEstimate(
        stiffness_N_per_m=fit.extrapolated,
        stiffness_rel_error_estimate=fit.rel_error_estimate,
        stiffness_finest_N_per_m=k[-1],
        finest_rel_error_estimate=fit.finest_rel_error_estimate,
        convergence_rate=fit.rate,
        observed_convergence_rate=fit.observed_rate,
        monotone=fit.monotone,
        levels=tuple((h, s.dofs, s.stiffness_N_per_m) for h, s in zip(sizes, solutions)),
        finest=solutions[-1],
        timing_s=timing,
    )
