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
the finest first and each in a thread of its own, so that the coarser levels are meshed and
assembled on the second core beside the finest one's solve. One level at a time holds a
factorisation (the study's solve slot, `heap.TrimmingLock`): two levels' factors, solves and freed
temporaries side by side made the FEA's process the peak of the whole job's memory.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

from . import budget, quality
from .errors import FemError, FemWarning
from .heap import TrimmingLock, release_free_memory
from .link import LinkSolution, analyse_link_materials, check_mesh_and_materials, fallback_note
from .materials import Material
from .richardson import Extrapolation, extrapolate, rate_bracket
from .settings import LEVEL_RATIO, FeaSettings, levels_for_finest, settings_with

# Relative sizes, chosen by measurement on the default link (docs/performance.md, FEA: elements and work-precision): two
# curved-P2 levels (6 and 4.5 mm there) put k's guaranteed-under-the-model estimate below 1 %.
# Coarser levels are not in the asymptotic range there: above ~6.5 mm the 6.9 mm web under the
# pocket is crossed by flattened elements and k jumps by 1.5 % (measured, 7.5 -> 6 mm).
PITCH_FRACTION = 1 / 25
BORE_FRACTION = 0.52


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
    finest: LinkSolution  # or, read from an earlier run, its fem.adaptive.SolvedLevel (no fields)
    timing_s: dict[str, float]  # summed over levels: mesh, assembly, load, solve, post, total; the study's wall
    # one line per level whose solver was not the one asked for (LinkSolution.solver_fallback)
    solver_fallbacks: tuple[str, ...] = ()


def finest_size_for(pitch_m: float, bore_radius_m: float) -> float:
    """The default finest element size of a link with this pitch and (larger) pin-bore radius.
    Smaller holes (screw, grease holes) and a smaller pin bore are refined locally
    (geometry.meshing's size fields), not by a smaller size everywhere."""
    return min(PITCH_FRACTION * pitch_m, BORE_FRACTION * bore_radius_m)


def default_mesh_sizes(source) -> tuple[float, ...]:
    """Default levels (coarse to fine) for the link (a `geometry.Part`, or a source it resolves):
    relative to its pitch and pin bores."""
    pitch_m, bore_radius_m, _ = part_scale(source)
    return levels_for_finest(finest_size_for(pitch_m, bore_radius_m))


def part_scale(source) -> tuple[float, float, float]:
    """(pitch, larger pin-bore radius, smallest other hole radius or inf) in metres of the link: a
    `geometry.Part`, or a source it resolves (a STEP path or `LinkSource`: the body and pin bores
    the meshes use; None or `LinkDimensions`: the built-in link's nominal pitch and bore)."""
    from geometry.part import as_part

    scale = as_part(source, symmetry=False).scale
    return scale.pitch_m, scale.bore_radius_m, scale.smallest_hole_radius_m


def stiffness_study(
    source=None,
    material: Material | None = None,
    settings: FeaSettings | None = None,
    *,
    progress: Callable[[str], None] | None = None,
    **changes,
) -> StiffnessEstimate:
    """Mesh the link (a `geometry.Part`, or a source it resolves; None = built-in default) at 2-3
    sizes (`settings.mesh_sizes_m`; None: `default_mesh_sizes`), solve each, extrapolate k.

    settings: `FeaSettings` (None: the defaults); keyword `changes` replace its fields
    (`stiffness_study(None, material, order=1)`). See `stiffness_studies`.
    """
    if material is None:
        raise FemError("stiffness_study: a material is required")
    return stiffness_studies(source, [material], settings, progress=progress, **changes)[material.name]


def stiffness_studies(
    source,
    materials: Sequence[Material],
    settings: FeaSettings | None = None,
    *,
    progress: Callable[[str], None] | None = None,
    **changes,
) -> dict[str, StiffnessEstimate]:
    """`stiffness_study` for several materials, meshing each level once for all of them.

    `progress`, if given, gets one line per solve (level, material, DOFs, k, seconds).
    `settings.concurrent_levels`: solve each level in a thread of its own as soon as it is meshed, so
    that meshing the next level and the levels' solves overlap on the machine's cores (gmsh, numpy
    and PARDISO release the GIL; the levels share nothing but the solve slot: one level at a time
    factorises and solves, a level that must wait for it gives the heap's free pages back first,
    and each level's thread does when its level is done). False where the caller already keeps
    every core busy, as the design study's workers do (one task per core).
    `settings.mirror_symmetry`: where the link is mirror symmetric about the plane through its bore
    axes (checked, geometry.symmetry), solve the finest level on its half (`LinkSolution.mirrored`),
    the same discrete problem as the whole link meshed as that half and its mirror image, at about
    half the unknowns. The coarser levels stay whole: on the half (its surfaces meshed by MeshAdapt,
    conforming to the plane) a coarse level comes out stiffer for its unknowns than the whole link's,
    erratically near 6 mm, which widened the built-in link's estimate from 0.85 to 0.99 % for 1.2-2.4
    CPU s less (docs/performance.md, "The FEA's CPU in the whole job"). The extrapolation's h is
    DOFs^(-1/3) of the whole link's mesh (`whole_link_dofs`). False: every level on the whole link.
    """
    import geometry
    from geometry.mesh_estimate import estimated_dofs

    if not materials:
        raise FemError("stiffness_studies: expected at least one material")
    settings = settings_with(settings, changes)  # checked before meshing
    order, concurrent_levels, mirror_symmetry = settings.order, settings.concurrent_levels, settings.mirror_symmetry
    start = study_start = time.perf_counter()
    part = geometry.as_part(source, symmetry=mirror_symmetry)
    sizes, wall_reference_m = planned_mesh_sizes(part, settings)
    mesh_time = time.perf_counter() - start

    def mesh_level(level: int, level_sizes: tuple[float, ...]):
        return mesh_planned_level(part, settings, level_sizes, level, wall_reference_m)

    def estimate_levels(level_sizes: tuple[float, ...]) -> list[float]:
        """Unknowns of every level (finest first) estimated before meshing."""
        features = part.geometry.mesh_features
        half = mirror_symmetry and part.mirror_plane is not None
        return [
            estimated_dofs(
                features, h, settings.bore_refinement * h, settings.mesh_order, half and i == 0, wall_reference_m
            )
            for i, h in enumerate(reversed(level_sizes))
        ]

    start = time.perf_counter()
    sizes, finest_link = _within_budget(
        sizes,
        mesh_level,
        estimate_levels,
        order,
        budget.MemoryBudget.gigabytes(settings.max_memory_gb),
        given=settings.mesh_sizes_m is not None,
    )
    mesh_time += time.perf_counter() - start
    # finest first: it is the longest solve, so the coarser levels are meshed and solved beside it;
    # one level at a time factorises and solves (`solve_slot`), the others meanwhile meshed and assembled
    solve_slot = TrimmingLock()
    with ThreadPoolExecutor(max_workers=len(sizes) if concurrent_levels else 1, thread_name_prefix="fem-level") as pool:
        pending = {}
        for level in reversed(range(len(sizes))):
            start = time.perf_counter()
            finest = level == len(sizes) - 1
            link = finest_link if finest else mesh_level(level, sizes)
            if finest:
                wall = quality.thin_wall_warning(
                    link, refined_down_to_m(part.geometry.mesh_features.walls, wall_reference_m)
                )
                if wall:
                    warnings.warn(wall, FemWarning, stacklevel=2)
            mesh_time += time.perf_counter() - start
            # shape warnings concern the mesh whose stresses are reported
            check_mesh_and_materials(link, materials, order, warn_quality=finest)
            pending[level] = pool.submit(
                _solve_level,
                concurrent_levels,
                link,
                materials,
                order=order,
                load_N=settings.load_N,
                solver=settings.solver,
                stress=finest,
                checked=True,
                solve_slot=solve_slot,
            )
            if not concurrent_levels:
                pending[level].result()  # an error stops the study before the next level is meshed
        solved = [pending[level].result() for level in range(len(sizes))]
    release_free_memory()  # the levels' arrays, before the caller's next stage
    solutions: dict[str, list[LinkSolution]] = {m.name: [s[m.name] for s in solved] for m in materials}
    if progress is not None:
        for level, (h, by_material) in enumerate(zip(sizes, solved), start=1):
            for solution in by_material.values():
                progress(
                    f"FEA level {level}/{len(sizes)}, {solution.material.name}: h = {h * 1e3:.2f} mm, "
                    f"{solution.dofs} DOFs, k = {solution.stiffness_N_per_m:.5g} N/m, "
                    f"{sum(solution.timing_s.values()):.1f} s{fallback_note(solution)}"
                )
    # Meshing is shared and booked to the first material, as analyse_link_materials books the
    # shared assembly: the first material's timing is the cost of the study, the others' the extra.
    # Its "wall" is the study's elapsed time (less than the stages' sum where levels overlap).
    wall_s = time.perf_counter() - study_start
    return {
        name: estimate_from_levels(
            sizes, sols, mesh_time if i == 0 else 0.0, order=order, wall_s=wall_s if i == 0 else None
        )
        for i, (name, sols) in enumerate(solutions.items())
    }


def _solve_level(side_by_side: bool, link, materials: Sequence[Material], **options) -> dict[str, LinkSolution]:
    """`analyse_link_materials` in a level's thread; with the levels `side_by_side`, the heap's free
    pages then given back: the level's arrays were freed into its thread's own malloc arena, which
    the other levels' threads do not reuse, so that they would otherwise stay resident under the
    next level's factorisation. One level after the other, the next level reuses them in the same
    thread (trimming there would only fault them in again)."""
    try:
        return analyse_link_materials(link, materials, **options)
    finally:
        if side_by_side:
            release_free_memory()


def planned_mesh_sizes(part, settings: FeaSettings) -> tuple[tuple[float, ...], float]:
    """(the stiffness study's level sizes coarse to fine before the memory budget, the finest size
    asked for) of `part` (a `geometry.Part`): settings.mesh_sizes_m or `default_mesh_sizes`, with
    `with_wall_check_level`'s third level where a thin wall is refined.

    The sizes measure the part; with `settings.mirror_symmetry` it is measured keeping its mirror
    half (`Part.measure_keeping_half`), which the finest level (`mesh_planned_level`, meshed first)
    then meshes instead of building the CAD again. A part measured already keeps nothing.

    Thin walls (geometry.walls: planar, rings round holes) thinner than half the finest size asked
    for get a size field on every level, the same fraction of each level's size
    (geometry.meshing.THIN_WALL_FRACTION). The reference is the finest size asked for, kept where the
    budget coarsens the levels (which keeps their number)."""
    if settings.mirror_symmetry:
        part.measure_keeping_half()
    sizes = default_mesh_sizes(part) if settings.mesh_sizes_m is None else settings.mesh_sizes_m
    wall_reference_m = sizes[-1]
    return with_wall_check_level(sizes, part.geometry.mesh_features.walls, wall_reference_m), wall_reference_m


def mesh_planned_level(part, settings: FeaSettings, sizes: tuple[float, ...], level: int, wall_reference_m: float):
    """The `geometry.LinkMesh` of the stiffness study's level `level` of `sizes` (coarse to fine,
    `planned_mesh_sizes` or the budget's coarsening of them): the finest on the link's mirror half
    where `settings.mirror_symmetry` (and the link is symmetric), every level's thin walls refined
    for the same `wall_reference_m`, so that every level refines the same walls alike."""
    import geometry

    return geometry.mesh_part(
        part,
        mesh_size_m=sizes[level],
        order=settings.mesh_order,
        bore_refinement=settings.bore_refinement,
        mirror=settings.mirror_symmetry and level == len(sizes) - 1,
        wall_reference_m=wall_reference_m,
    )


def refined_down_to_m(walls, wall_reference_m: float) -> float:
    """The thinnest wall the size fields refine (geometry.meshing.THIN_WALL_FRACTION), inf if none."""
    from geometry.meshing import THIN_WALL_FRACTION

    refined = [wall.thickness_m for wall in walls if wall.thickness_m < THIN_WALL_FRACTION * wall_reference_m]
    return min(refined, default=math.inf)


def with_wall_check_level(sizes: tuple[float, ...], walls, wall_reference_m: float) -> tuple[float, ...]:
    """Two levels and a wall (`geometry.mesh_estimate.WallFeature`s) refined by its size field: the
    levels with a third, coarser by the same ratio, whose pair is in the extrapolation's bound
    (fem.richardson: both pairs' intervals, and the levels' scatter where they oscillate).
    Otherwise the levels as given.

    Why: a refined wall keeps about one element through its thickness on every level, so the two
    levels' difference misses the wall's error and their mesh-to-mesh noise is of its size. On the
    built-in link at --mesh-size 10 (its 2.535 mm rails refined) two levels gave 9.461e7 N/m
    +- 0.90 % against the converged 9.352e7 (+1.17 %: outside), and 13.3 / 10 mm instead of
    13.33 / 10 gave 9.406e7 +- 1.34 %; with the third level, 9.461e7 +- 1.28 %
    (tests/test_fea_thin_wall_estimate.py). No default level of the built-in link or the corpus
    refines a wall (docs/verification.md): their runs keep two levels."""
    if len(sizes) != 2 or refined_down_to_m(walls, wall_reference_m) == math.inf:
        return sizes
    return (sizes[0] ** 2 / sizes[1], *sizes)


def _fit_before_meshing(sizes: tuple[float, ...], estimate_levels, memory: budget.MemoryBudget, given: bool):
    """Sizes whose levels' unknowns estimated before meshing, at the estimate's low end, fit the
    budget: default sizes coarsened, given ones refused (FemError naming the options)."""
    for _ in range(budget.MAX_ESTIMATE_RETRIES):
        low = [budget.ESTIMATE_LOW_RATIO * n for n in estimate_levels(sizes)]
        if memory.fits(low):
            return sizes
        what = f"--mesh-size {sizes[-1] * 1e3:g}" if given else f"elements of {sizes[-1] * 1e3:.3g} mm"
        if given:
            raise FemError(budget.over_budget_message(what, low, memory, estimated=True))
        sizes = tuple(h * memory.coarsening(low) for h in sizes)
    raise FemError(budget.over_budget_message(what, low, memory, estimated=True))


def _within_budget(
    sizes: tuple[float, ...], mesh_level, estimate_levels, order: int, memory: budget.MemoryBudget, given: bool
):
    """(sizes, finest level's mesh) whose levels' solves fit the memory budget: sizes that cannot
    fit by the estimate before meshing are coarsened or refused at once; then the finest level is
    meshed and its unknowns counted before any solve; default sizes are coarsened until the
    count fits (FemWarning), given sizes that do not fit are a FemError naming the options."""
    requested = sizes
    sizes = _fit_before_meshing(sizes, estimate_levels, memory, given)
    for _ in range(budget.MAX_RETRIES + 1):
        link = mesh_level(len(sizes) - 1, sizes)
        copies = 2 if link.mirror_plane is not None else 1
        finest_dofs = budget.mesh_dofs(link.tets, link.tets10, order)
        level_dofs = [finest_dofs] + [n * copies for n in budget.levels_dofs(finest_dofs, len(sizes), LEVEL_RATIO)[1:]]
        if memory.fits(level_dofs):
            if sizes != requested:
                warnings.warn(
                    f"memory budget: the default {requested[-1] * 1e3:.3g} mm elements would exceed "
                    f"--max-memory {memory.gb:g} GB; k computed at {sizes[-1] * 1e3:.3g} mm elements "
                    "instead (its error estimate says what that costs; a larger --max-memory GB refines)",
                    FemWarning,
                    stacklevel=3,
                )
            return sizes, link
        if given:
            raise FemError(budget.over_budget_message(f"--mesh-size {sizes[-1] * 1e3:g}", level_dofs, memory))
        factor = memory.coarsening(level_dofs)
        sizes = tuple(h * factor for h in sizes)
    raise FemError(budget.over_budget_message(f"elements of {sizes[-1] * 1e3:.3g} mm", level_dofs, memory))


def estimate_from_levels(
    sizes: Sequence[float],
    solutions: list[LinkSolution],
    mesh_time_s: float,
    fit_last: int | None = None,
    order: int = 2,
    wall_s: float | None = None,
) -> StiffnessEstimate:
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
        solver_fallbacks=tuple(
            f"level of {h * 1e3:.3g} mm: {s.solver_fallback}" for h, s in zip(sizes, solutions) if s.solver_fallback
        ),
    )
