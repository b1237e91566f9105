"""Link stiffness with a discretisation-error estimate: 2-3 mesh levels + Richardson extrapolation.

Default levels are relative to the part (`default_mesh_sizes`), not fixed millimetres: the finest
element is the smaller of PITCH_FRACTION x pitch and BORE_FRACTION x bore radius (smaller holes,
screw and grease holes, are refined locally by geometry.meshing), and one level
LEVEL_RATIO coarser gives the second point for the extrapolation. On the default link (pitch
112.5 mm, bore radius 8.73 mm) that is 4.5 and 6 mm; a 12.7 mm-pitch roller-chain plate gets
0.5 / 0.68 mm and a link scaled to 300 mm pitch 12 / 16 mm, the same mesh relative to the part.
A link that is mirror symmetric about the plane through its bore axes has its finest level solved
on its half (`mirror_symmetry`, geometry.symmetry): the same discrete problem at about half the
unknowns.
Each level is meshed once and solved for all materials at once (`link.analyse_link_materials`),
the finest first and each in a thread of its own, so that the coarser levels are meshed and solved
on the second core beside the finest one's solve.
"""

from __future__ import annotations

import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from . import budget, quality
from .errors import FemError, FemWarning
from .link import LinkSolution, analyse_link_materials, check_mesh_and_materials
from .materials import Material
from .problem import element
from .richardson import Extrapolation, extrapolate, rate_bracket
from .solvers import resolve

# Relative sizes, chosen by measurement on the default link (README, FEA work-precision): two
# curved-P2 levels (6 and 4.5 mm there) put k's guaranteed-under-the-model estimate below 1 %.
# Coarser levels are not in the asymptotic range there: above ~6.5 mm the 6.9 mm web under the
# pocket is crossed by flattened elements and k jumps by 1.5 % (measured, 7.5 -> 6 mm).
PITCH_FRACTION = 1 / 25
BORE_FRACTION = 0.52
LEVEL_RATIO = 4 / 3
DEFAULT_LEVELS = 2
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
    rate_bracket: tuple[float, float]  # rates p in k(h) = k_inf + C h^p, h = DOFs^(-1/3), the estimate covers
    observed_convergence_rate: float | None  # from three levels, for information
    monotone: bool
    levels: tuple[tuple[float, int, float], ...]  # (mesh_size_m, dofs, stiffness_N_per_m), coarse to fine
    finest: LinkSolution
    timing_s: dict[str, float]  # summed over levels: mesh, assembly, load, solve, post, total; the study's wall


def _check_sizes(sizes: Sequence[float]) -> tuple[float, ...]:
    sizes = tuple(float(h) for h in sizes)
    if len(sizes) not in (2, 3):
        raise FemError(f"mesh_sizes_m: expected 2 or 3 sizes, got {len(sizes)}")
    if not all(np.isfinite(h) and h > 0 for h in sizes):
        raise FemError(f"mesh_sizes_m: sizes must be positive numbers in metres, got {list(sizes)}")
    if any(b >= a for a, b in zip(sizes, sizes[1:])):
        raise FemError(f"mesh_sizes_m: sizes must decrease (coarse to fine), got {list(sizes)}")
    return sizes


def levels_for_finest(finest_m: float, n_levels: int = DEFAULT_LEVELS, ratio: float = LEVEL_RATIO) -> tuple[float, ...]:
    """Mesh sizes coarse to fine ending at `finest_m`, successive ratio `ratio`."""
    return tuple(finest_m * ratio**i for i in reversed(range(n_levels)))


def finest_size_for(pitch_m: float, bore_radius_m: float) -> float:
    """The default finest element size of a link with this pitch and (larger) pin-bore radius.
    Smaller holes (screw, grease holes) are refined locally (geometry.meshing's small-hole fields),
    not by a smaller size everywhere."""
    return min(PITCH_FRACTION * pitch_m, BORE_FRACTION * bore_radius_m)


def default_mesh_sizes(source) -> tuple[float, ...]:
    """Default levels (coarse to fine) for the link: relative to its pitch and pin bores."""
    pitch_m, bore_radius_m, _ = part_scale(source)
    return levels_for_finest(finest_size_for(pitch_m, bore_radius_m))


def part_scale(source) -> tuple[float, float, float]:
    """(pitch, larger pin-bore radius, smallest other hole radius or inf) in metres of a STEP link
    (a path or a `geometry.assembly.LinkSource`: the same body and pin bores as `load_link`
    chooses), or of the built-in link (None) or one of its `LinkDimensions` variants."""
    from geometry.assembly import inspect_part
    from geometry.dimensions import DEFAULT_LINK, LinkDimensions

    if source is None or isinstance(source, LinkDimensions):
        link = DEFAULT_LINK if source is None else source
        return link.pitch_m, link.bore_radius_m, np.inf
    from geometry.session import quiet_stdout

    with quiet_stdout():
        pins = inspect_part(source).pins
    holes = [h.hole.bore.radius_m for h in pins.ignored]
    # the larger bore sets the size: a smaller one (two unequal bores given by --bores) gets finer
    # elements of its own (geometry.meshing)
    return pins.pitch_m, float(max(pins.fixed.bore.radius_m, pins.loaded.bore.radius_m)), min(holes, default=np.inf)


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
    mirror_symmetry: bool = True,
    max_memory_gb: float = budget.DEFAULT_MAX_MEMORY_GB,
) -> StiffnessEstimate:
    """Mesh the link (None = built-in default) at 2-3 sizes (None: `default_mesh_sizes`), solve
    each, extrapolate k.

    `curved` asks geometry for isoparametric quadratic cells when order == 2; `mirror_symmetry` as
    in `stiffness_studies`.
    """
    if material is None:
        raise FemError("stiffness_study: a material is required")
    return stiffness_studies(source, [material], mesh_sizes_m=mesh_sizes_m, order=order, load_N=load_N,
                             solver=solver, curved=curved, bore_refinement=bore_refinement,
                             progress=progress, mirror_symmetry=mirror_symmetry,
                             max_memory_gb=max_memory_gb)[material.name]


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
    concurrent_levels: bool = True,
    mirror_symmetry: bool = True,
    max_memory_gb: float = budget.DEFAULT_MAX_MEMORY_GB,
) -> dict[str, StiffnessEstimate]:
    """`stiffness_study` for several materials, meshing each level once for all of them.

    `progress`, if given, gets one line per solve (level, material, DOFs, k, seconds).
    `concurrent_levels`: solve each level in a thread of its own as soon as it is meshed, so that
    meshing the next level and the levels' solves overlap on the machine's cores (gmsh, numpy and
    PARDISO release the GIL; the levels share nothing). Pass False where the caller already keeps
    every core busy, as the design study's workers do (one task per core).
    `mirror_symmetry`: where the link is mirror symmetric about the plane through its bore axes
    (checked, geometry.symmetry), solve the finest level on its half (`LinkSolution.mirrored`), the
    same discrete problem as the whole link meshed as that half and its mirror image, at about half
    the unknowns. The coarser levels stay whole: they are cheap, run beside the finest on the second
    core, and on the default link the half's coarse meshes came out stiffer than the trend of finer
    ones (the plane cuts the 6.9 mm web under the pocket), which more than doubled the estimate
    (exploratory runs, README). The extrapolation's h is DOFs^(-1/3) of the whole link's mesh
    (`whole_link_dofs`). False: every level on the whole link.
    `max_memory_gb`: the memory budget (fem.budget), checked on the finest mesh before any solve:
    default sizes are coarsened to fit (with a warning), given sizes that do not fit are refused.
    """
    import geometry

    if not materials:
        raise FemError("stiffness_studies: expected at least one material")
    element(order)  # validate before meshing
    resolve(solver)
    start = study_start = time.perf_counter()
    sizes = _check_sizes(default_mesh_sizes(source) if mesh_sizes_m is None else mesh_sizes_m)
    mesh_order = 2 if (order == 2 and curved) else 1
    mesh_time = time.perf_counter() - start

    def mesh_level(level: int, level_sizes: tuple[float, ...]):
        return geometry.load_link(source, mesh_size_m=level_sizes[level], order=mesh_order,
                                  bore_refinement=bore_refinement, mirror=mirror_symmetry and level == len(level_sizes) - 1)

    start = time.perf_counter()
    sizes, finest_link = _within_budget(sizes, mesh_level, order, budget.MemoryBudget.gigabytes(max_memory_gb),
                                        given=mesh_sizes_m is not None)
    mesh_time += time.perf_counter() - start
    # finest first: it is the longest solve, so the coarser levels are meshed and solved beside it
    with ThreadPoolExecutor(max_workers=len(sizes) if concurrent_levels else 1,
                            thread_name_prefix="fem-level") as pool:
        pending = {}
        for level in reversed(range(len(sizes))):
            start = time.perf_counter()
            finest = level == len(sizes) - 1
            link = finest_link if finest else mesh_level(level, sizes)
            if finest:
                wall = quality.thin_wall_warning(link)
                if wall:
                    warnings.warn(wall, FemWarning, stacklevel=2)
            mesh_time += time.perf_counter() - start
            # shape warnings concern the mesh whose stresses are reported
            check_mesh_and_materials(link, materials, order, warn_quality=finest)
            pending[level] = pool.submit(analyse_link_materials, link, materials, order=order, load_N=load_N,
                                         solver=solver, stress=finest, checked=True)
            if not concurrent_levels:
                pending[level].result()  # an error stops the study before the next level is meshed
        solved = [pending[level].result() for level in range(len(sizes))]
    solutions: dict[str, list[LinkSolution]] = {m.name: [s[m.name] for s in solved] for m in materials}
    if progress is not None:
        for level, (h, by_material) in enumerate(zip(sizes, solved), start=1):
            for solution in by_material.values():
                progress(f"FEA level {level}/{len(sizes)}, {solution.material.name}: h = {h * 1e3:.2f} mm, "
                         f"{solution.dofs} DOFs, k = {solution.stiffness_N_per_m:.5g} N/m, "
                         f"{sum(solution.timing_s.values()):.1f} s")
    # Meshing is shared and booked to the first material, as analyse_link_materials books the
    # shared assembly: the first material's timing is the cost of the study, the others' the extra.
    # Its "wall" is the study's elapsed time (less than the stages' sum where levels overlap).
    wall_s = time.perf_counter() - study_start
    return {name: estimate_from_levels(sizes, sols, mesh_time if i == 0 else 0.0, order=order,
                                       wall_s=wall_s if i == 0 else None)
            for i, (name, sols) in enumerate(solutions.items())}


def _within_budget(sizes: tuple[float, ...], mesh_level, order: int, memory: budget.MemoryBudget, given: bool):
    """(sizes, finest level's mesh) whose levels' solves fit the memory budget: the finest level is
    meshed and its unknowns counted before any solve; default sizes are coarsened until the
    estimate fits (FemWarning), given sizes that do not fit are a FemError naming the options."""
    requested = sizes
    for _ in range(budget.MAX_RETRIES + 1):
        link = mesh_level(len(sizes) - 1, sizes)
        copies = 2 if link.mirror_plane is not None else 1
        finest_dofs = budget.mesh_dofs(link.tets, link.tets10, order)
        level_dofs = [finest_dofs] + [n * copies for n in budget.levels_dofs(finest_dofs, len(sizes), LEVEL_RATIO)[1:]]
        if memory.fits(level_dofs):
            if sizes != requested:
                warnings.warn(f"memory budget: the default {requested[-1] * 1e3:.3g} mm elements would exceed "
                              f"--max-memory {memory.gb:g} GB; k computed at {sizes[-1] * 1e3:.3g} mm elements "
                              "instead (its error estimate says what that costs; a larger --max-memory GB refines)",
                              FemWarning, stacklevel=3)
            return sizes, link
        if given:
            raise FemError(budget.over_budget_message(f"--mesh-size {sizes[-1] * 1e3:g}", level_dofs, memory))
        factor = memory.coarsening(level_dofs)
        sizes = tuple(h * factor for h in sizes)
    raise FemError(budget.over_budget_message(f"elements of {sizes[-1] * 1e3:.3g} mm", level_dofs, memory))


def estimate_from_levels(sizes: Sequence[float], solutions: list[LinkSolution], mesh_time_s: float,
                         fit_last: int | None = None, order: int = 2, wall_s: float | None = None) -> StiffnessEstimate:
    """The estimate from solved levels (coarse to fine); k is extrapolated from the last `fit_last`
    levels (all when None), every level is recorded. `wall_s`, if given, is recorded as the
    timing's "wall" beside the stages' sum ("total")."""
    timing: dict[str, float] = {"mesh": mesh_time_s}
    for solution in solutions:
        for key, value in solution.timing_s.items():
            timing[key] = timing.get(key, 0.0) + value
    timing["total"] = sum(timing.values())
    if wall_s is not None:
        timing["wall"] = wall_s
    fitted = solutions if fit_last is None else solutions[-fit_last:]
    k = [s.stiffness_N_per_m for s in fitted]
    fit: Extrapolation = extrapolate(k, [s.whole_link_dofs for s in fitted], rate_bracket(order))
    return StiffnessEstimate(
        stiffness_N_per_m=fit.extrapolated,
        stiffness_rel_error_estimate=fit.rel_error_estimate,
        stiffness_finest_N_per_m=k[-1],
        finest_rel_error_estimate=fit.finest_rel_error_estimate,
        rate_bracket=fit.rate_bracket,
        observed_convergence_rate=fit.observed_rate,
        monotone=fit.monotone,
        levels=tuple((h, s.dofs, s.stiffness_N_per_m) for h, s in zip(sizes, solutions)),
        finest=solutions[-1],
        timing_s=timing,
    )
