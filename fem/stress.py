"""Peak von Mises stress converged by refining the mesh where the peak is (`stress_study`).

A peak stress means something only where it converges: at a fillet, a bore or a smooth bend it
does once the elements there are small against the radius; at a sharp re-entrant edge or at the
rim of the clamped bore (a bonded pin: clamped and free surfaces meet at a right angle) it grows
without bound under refinement. So:

- the peak is taken away from the clamped bore's rims: over element nodes farther than
  `CLAMP_EXCLUSION_RADIUS_FRACTION` (0.25) bore radii from them (`LinkSolution.
  peak_von_mises_away_from_clamp_Pa_per_N`). Near the clamp the stress is thereby reported at that
  documented distance, not at the singular rim itself; a real pin in a bore with clearance
  would need a contact model, which we do not build;
- the mesh is refined in balls around the hot spots (nodes within `HOT_SPOT_FRACTION` of the peak),
  element size halved each level, and the study stops when the last halving changed the peak by
  at most `tolerance` (5 % by default). The reported value is the finest level's peak; its
  estimated relative error is that last change (for a smooth peak P2 stresses converge as h^2,
  so the change overstates the remaining error about threefold).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from . import quality
from .errors import FemError, FemWarning
from .heap import release_free_memory
from .link import MIN_CURVED_JACOBIAN_RATIO, LinkSolution, analyse_link_materials, skfem_mesh
from .materials import Material
from .quality import QUALITY_WARNING_PREFIX
from .settings import FeaSettings, settings_with

HOT_SPOT_FRACTION = 0.8  # element nodes within 20 % of the peak are refined around
MAX_HOT_SPOTS = 8
MAX_LEVELS = 4  # refinement levels after the base mesh (local size base / 2^4 at most)
# Ball radius around a hot spot, in the previous level's element sizes: the peak must stay inside it
# as it moves by a fraction of an element from level to level; the balls shrink with the elements,
# so each level adds about as many DOFs as the one before.
BALL_RADIUS_ELEMENTS = 1.5
# Curved cells of the stress levels are straightened at MIN_CURVED_JACOBIAN_RATIO everywhere, not
# only near the bores as the k studies may (fem.link.closest_to_cad keeps the rounds' volume): a
# nearly folded curved cell carries a spurious stress spike. Measured on the default link: with the
# k studies' cells the 4.5 mm half peaked at 39.8 MPa/kN (13.6 straightened) and the local levels
# jumped 14.6 / 20.5 / 16.7 / 20.3 MPa/kN without converging; straightened they converge (13.8).
# Straightening is a local O(h^2) geometry error, and the levels refine where the peak is.
STRESS_AWAY_RATIOS = (MIN_CURVED_JACOBIAN_RATIO,)


@dataclass(frozen=True, eq=False)
class StressEstimate:
    """Peak von Mises stress per newton of pin load, away from the clamped bore, converged locally."""

    peak_Pa_per_N: float  # finest level
    rel_change: float  # |finest - previous| / finest: the estimate of its relative error
    converged: bool  # rel_change <= tolerance
    tolerance: float
    location_m: tuple[float, float, float]
    clamp_distance_m: float  # stress within this distance of the clamped bore's rims is left out
    levels: tuple[tuple[float, int, float], ...]  # (local element size m, DOFs, peak Pa/N), coarse to fine
    finest: LinkSolution
    timing_s: float  # this material's share of the study's wall time
    level_seconds: tuple[float, ...] = ()  # wall time from the study's start to the end of each level

    @property
    def description(self) -> str:
        """What this stress is, for reports (one line)."""
        state = "converged" if self.converged else "NOT converged"
        return (
            f"peak von Mises away from the clamped bore (beyond {self.clamp_distance_m * 1e3:.2g} mm of its rims), "
            f"{state} under local refinement to {self.rel_change * 100:.1f} % "
            f"({len(self.levels)} levels, finest local element {self.levels[-1][0] * 1e3:.2g} mm)"
        )


def hot_spots(
    solution: LinkSolution,
    fraction: float = HOT_SPOT_FRACTION,
    max_spots: int = MAX_HOT_SPOTS,
    separation_m: float | None = None,
) -> list[np.ndarray]:
    """Centres (3,) of up to `max_spots` separate regions whose stress (DOF-averaged, away from the
    clamp) is within `fraction` of the peak, highest first."""
    from . import problem

    points = problem.dof_locations(solution.basis)
    stress = solution.von_mises_at_dofs_Pa.copy()
    stress[~solution.away_from_clamp_at_dofs] = 0.0
    peak = stress.max()
    if not peak > 0:
        raise FemError("no stress away from the clamped bore: nothing to refine")
    separation = 2 * solution.mesh_size_m if separation_m is None else separation_m
    order = np.argsort(-stress)
    spots: list[np.ndarray] = []
    for i in order:
        if stress[i] < fraction * peak or len(spots) == max_spots:
            break
        if all(np.linalg.norm(points[:, i] - s) > separation for s in spots):
            spots.append(points[:, i].copy())
    return spots


def stress_study(
    source,
    materials: Sequence[Material],
    settings: FeaSettings | None = None,
    *,
    base_mesh_size_m: float,
    base: dict[str, LinkSolution] | None = None,
    progress: Callable[[str], None] | None = None,
    **changes,
) -> dict[str, StressEstimate]:
    """Converge the peak stress of the link (a `geometry.Part`, or a source it resolves; None =
    built-in) by local refinement, per material, until a level changes the peak by at most
    `settings.stress_tolerance`.

    settings: `FeaSettings` (None: the defaults; its order, solver, load, bore refinement and mirror
    symmetry are used); keyword `changes` replace its fields. `base`, if given, holds the materials'
    solutions on the base mesh (e.g. the finest level of a stiffness study at `base_mesh_size_m`),
    which are not solved again if they are on the mesh the study would use (the same half or whole
    link, the same straightened cells: STRESS_AWAY_RATIOS); otherwise its mesh is solved again. The
    hot spots are those of the first material (Poisson's ratio barely moves them); every level is
    solved for all materials on one mesh (`analyse_link_materials`). Where the link is mirror
    symmetric and `settings.mirror_symmetry`, every level is meshed and solved on its half (the same
    discrete problem as the whole link meshed as that half and its mirror image, fem.link): the
    hot spots of both sides are refined at about half the unknowns.
    """
    import geometry
    from geometry.meshing import Refinement, refined

    settings = settings_with(settings, changes)
    tolerance, order = settings.stress_tolerance, settings.order
    start = time.perf_counter()
    part = geometry.as_part(source, symmetry=settings.mirror_symmetry)
    half = settings.mirror_symmetry and part.mirror_plane is not None
    mesh_order = 2 if order == 2 else 1
    names = [m.name for m in materials]

    def mesh(balls: Sequence[Refinement], on_half: bool = half):
        with refined(balls):
            return geometry.mesh_part(
                part,
                mesh_size_m=base_mesh_size_m,
                order=mesh_order,
                bore_refinement=settings.bore_refinement,
                mirror=on_half,
            )

    def solve(link) -> dict[str, LinkSolution]:
        return analyse_link_materials(
            link,
            materials,
            order=order,
            load_N=settings.load_N,
            solver=settings.solver,
            away_ratios=STRESS_AWAY_RATIOS,
        )

    def refined_level(spots: list[np.ndarray], radius: float, size: float) -> dict[str, LinkSolution]:
        """The level solved on the half, or on the whole link where the half's mesh has poor tets
        near a hot spot or near the peak it gives (MeshAdapt's surfaces with local balls left one
        or two at radius ratio 0.05-0.09 on the default link, away from the peak; more with P1)."""
        plane = part.mirror_plane
        if half:
            link = mesh([Refinement(_coordinates(_on_positive_side(s, plane)), radius, size) for s in spots])
            near = radius + base_mesh_size_m
            if not any(_poor_tets_near(link, _on_positive_side(s, plane), near) for s in spots):
                solved = solve(link)
                peak = np.asarray(solved[names[0]].peak_von_mises_away_location_m)
                if not _poor_tets_near(link, peak, base_mesh_size_m):
                    return solved
        both = spots + [plane.reflect(s) for s in spots] if plane is not None else spots
        return solve(mesh([Refinement(_coordinates(s), radius, size) for s in both], on_half=False))

    if base is None or any(n not in base for n in names):
        base = solve(mesh(()))
    elif not _reusable(base[names[0]], half):
        base = solve(base[names[0]].link)
    levels = {n: [(base_mesh_size_m, base[n].dofs, base[n].peak_von_mises_away_from_clamp_Pa_per_N)] for n in names}
    seconds = [time.perf_counter() - start]
    current = {n: base[n] for n in names}
    local = base_mesh_size_m
    for _ in range(MAX_LEVELS):
        radius = BALL_RADIUS_ELEMENTS * local
        spots = hot_spots(current[names[0]], separation_m=radius)
        local /= 2
        with warnings.catch_warnings(record=True) as caught:  # re-issued for the finest level only
            warnings.simplefilter("always", FemWarning)
            current = refined_level(spots, radius, local)
        release_free_memory()  # the previous level's arrays
        for n in names:
            levels[n].append((local, current[n].dofs, current[n].peak_von_mises_away_from_clamp_Pa_per_N))
        seconds.append(time.perf_counter() - start)
        moved = [_change(levels[n]) for n in names]
        if progress is not None:
            progress(
                f"stress level {len(levels[names[0]]) - 1}: local element {local * 1e3:.2g} mm at {len(spots)} hot "
                f"spot(s), {current[names[0]].dofs} DOFs, peak "
                + ", ".join(f"{n} {levels[n][-1][2] * 1e3 / 1e6:.4g} MPa/kN" for n in names)
                + f", change {max(moved) * 100:.2g} %"
            )
        if max(moved) <= tolerance:
            break
    for w in caught if not current[names[0]].mirrored else ():  # a half's poor tets are away from the peak
        if str(w.message).startswith(QUALITY_WARNING_PREFIX):
            warnings.warn(f"stress study's finest mesh: {w.message}", FemWarning, stacklevel=2)
    elapsed = time.perf_counter() - start
    return {n: _estimate(levels[n], current[n], tolerance, elapsed / len(names), tuple(seconds)) for n in names}


def _coordinates(point: np.ndarray) -> tuple[float, float, float]:
    return tuple(float(x) for x in point)


def _on_positive_side(point: np.ndarray, plane) -> np.ndarray:
    """A hot spot of a whole-link solution moved to the meshed half (its mirror image) if needed."""
    return plane.reflect(point) if plane.distance_m(point) < 0 else point


def _poor_tets_near(link, point: np.ndarray, distance_m: float) -> bool:
    """Whether a tet of radius ratio below fem.quality's threshold has its centroid within
    `distance_m` of `point`."""
    poor = quality.radius_ratios(link.points_m, link.tets) < quality.POOR_QUALITY_THRESHOLD
    if not poor.any():
        return False
    centroids = link.points_m[:, link.tets[:, poor]].mean(axis=1)
    return bool(np.min(np.linalg.norm(centroids - np.asarray(point).reshape(3, 1), axis=0)) <= distance_m)


def _reusable(solution: LinkSolution, half: bool) -> bool:
    """Whether a given base solution is on the mesh the study solves: the half or the whole link as
    the study meshes it, its curved cells straightened as STRESS_AWAY_RATIOS straightens them."""
    if solution.mirrored != half:
        return False
    if solution.basis.mesh.affine:
        return True
    mesh, _ = skfem_mesh(solution.link, solution.order, away_ratios=STRESS_AWAY_RATIOS)
    return mesh.doflocs.shape == solution.basis.mesh.doflocs.shape and np.array_equal(
        mesh.doflocs, solution.basis.mesh.doflocs
    )


def _change(levels: list[tuple[float, int, float]]) -> float:
    return abs(levels[-1][2] - levels[-2][2]) / levels[-1][2]


def _estimate(
    levels, solution: LinkSolution, tolerance: float, seconds: float, level_seconds: tuple[float, ...]
) -> StressEstimate:
    change = _change(levels)
    return StressEstimate(
        peak_Pa_per_N=levels[-1][2],
        rel_change=change,
        converged=change <= tolerance,
        tolerance=tolerance,
        location_m=tuple(solution.peak_von_mises_away_location_m),
        clamp_distance_m=solution.clamp_exclusion_radius_m,
        levels=tuple(levels),
        finest=solution,
        timing_s=seconds,
        level_seconds=level_seconds,
    )


__all__ = ["StressEstimate", "hot_spots", "stress_study"]
