"""Peak von Mises stress converged by refining a sub-model where the peak is (`stress_study`).

A peak stress means something only where it converges: at a fillet, a bore or a smooth bend it
does once the elements there are small against the radius; at a sharp re-entrant edge or at the
rim of the clamped bore (a bonded pin: clamped and free surfaces meet at a right angle) it grows
without bound under refinement. So:

- the peak is taken away from the clamped bore's rims: over element nodes farther than
  `CLAMP_EXCLUSION_RADIUS_FRACTION` (0.25) bore radii from them (`LinkSolution.
  peak_von_mises_away_from_clamp_Pa_per_N`). Near the clamp the stress is thereby reported at that
  documented distance, not at the singular rim itself; a real pin in a bore with clearance
  would need a contact model, which we do not build;
- the peak is converged in a sub-model (fem.submodel): the link inside balls of
  `SUBMODEL_RADIUS_ELEMENTS` global elements about the global solution's hot spots (nodes within
  `HOT_SPOT_FRACTION` of its peak), driven on the balls' cut by the global displacements. The
  global is the stiffness study's finest level (or the link solved at the base size), no coarser
  than the part's default finest size. The sub-model's mesh is refined in smaller balls around its
  own hot spots, element size halved each level, and the study stops, after at least
  `MIN_SUBMODEL_LEVELS` sub-model levels, when the larger of the last two changes of the peak is
  at most `tolerance` (5 % by default). The reported value is the finest level's peak, that change
  its estimated relative error. A sub-model level is a few thousand DOFs where a level of the whole
  half was 43-46k: on the default link the study takes about 1.3 s instead of 19 s under the same
  load (benchmarks/bench_stress_study.py).
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
from .link import MIN_CURVED_JACOBIAN_RATIO, LinkSolution, analyse_link_materials
from .materials import Material
from .settings import FeaSettings, settings_with
from .study import default_mesh_sizes
from .submodel import GlobalField, SubModelSolution, solve_submodel

HOT_SPOT_FRACTION = 0.8  # element nodes within 20 % of the peak are refined around
MAX_HOT_SPOTS = 8
MAX_LEVELS = 4  # refinement levels after the base mesh (local size base / 2^4 at most)
# The study stops no sooner than after two sub-model levels: its estimate then holds a change between
# two meshes of the same sub-model under the same driving displacements, not only the change from the
# global mesh (another mesh, its peak possibly in a cell the sub-model resolves differently).
MIN_SUBMODEL_LEVELS = 2
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
# The sub-model's balls, in global elements: radius about the global's hot spots, and the depth
# inside their cut below which the peak is not taken (the driven boundary's error decays inward).
# Measured on the default link (4.5 mm global): balls of 3 global elements instead of 2 moved the
# levels' peaks by 0.3-0.6 %, well inside the study's estimate (2-5 %).
SUBMODEL_RADIUS_ELEMENTS = 2.0
TRUSTED_MARGIN_ELEMENTS = 0.5


@dataclass(frozen=True, eq=False)
class StressEstimate:
    """Peak von Mises stress per newton of pin load, away from the clamped bore, converged locally."""

    peak_Pa_per_N: float  # finest level
    rel_change: float  # the larger of the last two changes / finest: the estimate of its relative error
    converged: bool  # rel_change <= tolerance
    tolerance: float
    location_m: tuple[float, float, float]
    clamp_distance_m: float  # stress within this distance of the clamped bore's rims is left out
    # (local element size m, DOFs, peak Pa/N), coarse to fine: the global solution, then the sub-model's levels
    levels: tuple[tuple[float, int, float], ...]
    global_solution: LinkSolution  # the solution that drives the sub-model
    submodel: SubModelSolution  # the finest level's
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

    stress = np.where(solution.away_from_clamp_at_dofs, solution.von_mises_at_dofs_Pa, 0.0)
    separation = 2 * solution.mesh_size_m if separation_m is None else separation_m
    return _spots(problem.dof_locations(solution.basis), stress, separation, fraction, max_spots)


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
    built-in) in a sub-model around its hot spots, per material, until a level changes the peak by
    at most `settings.stress_tolerance`.

    settings: `FeaSettings` (None: the defaults; its order, solver, load, bore refinement and mirror
    symmetry are used); keyword `changes` replace its fields. The global solution is `base` (the
    materials' solutions on a mesh of `base_mesh_size_m`, e.g. the finest level of a stiffness
    study) if given, else the link meshed at `base_mesh_size_m` and solved. Its hot spots (those of
    the first material: Poisson's ratio barely moves them; its nearly folded curved cells left out)
    are the centres of the sub-model's balls (`SUBMODEL_RADIUS_ELEMENTS` global elements), cut out
    of the CAD once (geometry.ball_mesher) and meshed level after level, each level halving the
    element size in balls around the previous level's hot spots; every level is solved for all
    materials on one mesh, each driven on the cut by its own global solution (fem.submodel). Where
    the link is mirror symmetric and `settings.mirror_symmetry`, the balls are cut out of its half.
    """
    import geometry
    from geometry.ball_mesh import ball_mesher
    from geometry.meshing import Refinement

    settings = settings_with(settings, changes)
    tolerance, order = settings.stress_tolerance, settings.order
    start = time.perf_counter()
    part = geometry.as_part(source, symmetry=settings.mirror_symmetry)
    half = settings.mirror_symmetry and part.mirror_plane is not None
    names = [m.name for m in materials]
    # The global drives the sub-model, so its error reaches the peak through the cut: it is solved
    # no coarser than the part's own default finest size (fem.study) even where the run's base is
    # coarser. Measured on the default link: driven by a 10 mm global the sub-model's levels agreed
    # to 1.6-4.5 % at 12.95-13.23 MPa/kN, 6-8 % below the finely converged 14.0 (docs/physics.md);
    # driven by the 4.5 mm default (k study's cells, straightened cells, or the whole link) 13.81-13.90.
    size = min(base_mesh_size_m, default_mesh_sizes(part)[-1])
    if not _drives(base, names, half, size):
        link = geometry.mesh_part(
            part, mesh_size_m=size, order=2 if order == 2 else 1, bore_refinement=settings.bore_refinement, mirror=half
        )
        base = analyse_link_materials(
            link, materials, order=order, load_N=settings.load_N, solver=settings.solver, away_ratios=STRESS_AWAY_RATIOS
        )
    fields = [GlobalField(base[n]) for n in names]
    levels = {n: [(size, base[n].dofs, base[n].peak_von_mises_away_from_clamp_Pa_per_N)] for n in names}
    seconds = [time.perf_counter() - start]
    radius = SUBMODEL_RADIUS_ELEMENTS * size
    centers = well_shaped_hot_spots(base[names[0]], separation_m=radius)
    if half:
        centers = [_on_positive_side(c, part.mirror_plane) for c in centers]
    spots, local, current = centers, size, None
    with ball_mesher(part, centers, radius, mirror=half) as mesher:
        for _ in range(MAX_LEVELS):
            ball_radius = BALL_RADIUS_ELEMENTS * local
            local /= 2
            refinements = [Refinement(_coordinates(s), ball_radius, local) for s in spots]
            ball = mesher.mesh(refinements, size, order=2 if order == 2 else 1)
            quality.require_valid(quality.link_quality(ball))
            current = solve_submodel(
                ball,
                fields,
                order=order,
                trusted_margin_m=TRUSTED_MARGIN_ELEMENTS * size,
                solver=settings.solver,
            )
            release_free_memory()  # the previous level's arrays
            for n in names:
                levels[n].append((local, current[n].dofs, current[n].peak_Pa_per_N))
            seconds.append(time.perf_counter() - start)
            moved = [_change(levels[n]) for n in names]
            if progress is not None:
                progress(
                    f"stress level {len(levels[names[0]]) - 1}: local element {local * 1e3:.2g} mm at {len(spots)} hot "
                    f"spot(s), sub-model of {current[names[0]].dofs} DOFs, peak "
                    + ", ".join(f"{n} {levels[n][-1][2] * 1e3 / 1e6:.4g} MPa/kN" for n in names)
                    + f", change {max(moved) * 100:.2g} %"
                )
            if max(moved) <= tolerance and len(levels[names[0]]) > MIN_SUBMODEL_LEVELS:
                break
            spots = submodel_hot_spots(current[names[0]], separation_m=ball_radius)
    message = _quality_near(ball, np.asarray(current[names[0]].location_m), size)
    if message:
        warnings.warn(f"stress study's finest mesh: {message}", FemWarning, stacklevel=2)
    elapsed = time.perf_counter() - start
    return {
        n: _estimate(levels[n], base[n], current[n], tolerance, elapsed / len(names), tuple(seconds)) for n in names
    }


def _quality_near(ball, point: np.ndarray, distance_m: float) -> str | None:
    """The sub-model mesh's quality warning if one of its poor tets (fem.quality) has its centroid
    within `distance_m` of `point` (the peak); poor tets elsewhere do not touch the reported stress."""
    poor = quality.radius_ratios(ball.points_m, ball.tets) < quality.POOR_QUALITY_THRESHOLD
    if not poor.any():
        return None
    centroids = ball.points_m[:, ball.tets[:, poor]].mean(axis=1)
    if np.min(np.linalg.norm(centroids - point.reshape(3, 1), axis=0)) > distance_m:
        return None
    return quality.quality_warning(quality.link_quality(ball))


def _drives(base: dict[str, LinkSolution] | None, names: list[str], half: bool, size_m: float) -> bool:
    """Whether the given base solutions can drive the sub-model: every material's, on the half or
    the whole link as the study cuts its balls, no coarser than `size_m`."""
    if base is None or any(n not in base for n in names):
        return False
    solution = base[names[0]]
    return solution.mirrored == half and solution.mesh_size_m <= size_m * (1 + 1e-9)


def well_shaped_hot_spots(solution: LinkSolution, separation_m: float) -> list[np.ndarray]:
    """`hot_spots` of a global solution whose stress is averaged at its DOFs over the well-shaped
    cells only: a curved cell kept nearly folded (the k studies keep some for the rounds' volume,
    fem.link.closest_to_cad) carries a spurious stress that would otherwise draw the sub-model."""
    from . import problem
    from .link import _curved_jacobian_ratio

    mesh, basis = solution.basis.mesh, solution.basis
    if mesh.affine:
        return hot_spots(solution, separation_m=separation_m)
    well_shaped = _curved_jacobian_ratio(mesh) >= MIN_CURVED_JACOBIAN_RATIO
    local = basis.elem.doflocs.T
    lam, mu = solution.material.lame_Pa
    displacement = solution.displacement_m.T.ravel()
    vm = problem.von_mises_Pa(problem.displacement_gradients(basis, displacement, local), lam, mu)
    dofs = basis.element_dofs.T[well_shaped].ravel()
    counts = np.bincount(dofs, minlength=basis.N)
    stress = np.bincount(dofs, vm[well_shaped].ravel(), basis.N) / np.maximum(counts, 1)
    stress[counts == 0] = 0.0
    return _spots(problem.dof_locations(basis), np.where(solution.away_from_clamp_at_dofs, stress, 0.0), separation_m)


def submodel_hot_spots(solution, separation_m: float) -> list[np.ndarray]:
    """`hot_spots` of a sub-model's solution, over its trusted DOFs."""
    from . import problem

    stress = np.where(solution.trusted_at_dofs, solution.von_mises_at_dofs_Pa, 0.0)
    return _spots(problem.dof_locations(solution.basis), stress, separation_m)


def _spots(
    points: np.ndarray,
    stress: np.ndarray,
    separation_m: float,
    fraction: float = HOT_SPOT_FRACTION,
    max_spots: int = MAX_HOT_SPOTS,
) -> list[np.ndarray]:
    """Points (3, n) where `stress` (n,) is within `fraction` of its peak, highest first, at least
    `separation_m` apart, at most `max_spots`."""
    peak = stress.max()
    if not peak > 0:
        raise FemError("no stress away from the clamped bore: nothing to refine")
    spots: list[np.ndarray] = []
    for i in np.argsort(-stress):
        if stress[i] < fraction * peak or len(spots) == max_spots:
            break
        if all(np.linalg.norm(points[:, i] - s) > separation_m for s in spots):
            spots.append(points[:, i].copy())
    return spots


def _coordinates(point: np.ndarray) -> tuple[float, float, float]:
    return tuple(float(x) for x in point)


def _on_positive_side(point: np.ndarray, plane) -> np.ndarray:
    """A hot spot of a whole-link solution moved to the meshed half (its mirror image) if needed."""
    return plane.reflect(point) if plane.distance_m(point) < 0 else point


def _change(levels: list[tuple[float, int, float]]) -> float:
    """The larger of the last two changes of the peak, relative to the finest: the peak at element
    nodes moves by 1-2 % from level to level even at fine levels on the default link (the hot
    region is a ridge along the pocket's fillet, refined at up to MAX_HOT_SPOTS balls), so one
    small change alone can be a coincidence (measured: 14.08 -> 14.04, 0.3 %, from a 3.4 mm global)."""
    peaks = [peak for _, _, peak in levels[-3:]]
    return max(abs(b - a) for a, b in zip(peaks, peaks[1:])) / peaks[-1]


def _estimate(
    levels,
    global_solution: LinkSolution,
    submodel: SubModelSolution,
    tolerance: float,
    seconds: float,
    level_seconds: tuple[float, ...],
) -> StressEstimate:
    change = _change(levels)
    return StressEstimate(
        peak_Pa_per_N=levels[-1][2],
        rel_change=change,
        converged=change <= tolerance,
        tolerance=tolerance,
        location_m=submodel.location_m,
        clamp_distance_m=global_solution.clamp_exclusion_radius_m,
        levels=tuple(levels),
        global_solution=global_solution,
        submodel=submodel,
        timing_s=seconds,
        level_seconds=level_seconds,
    )


__all__ = ["StressEstimate", "hot_spots", "stress_study"]
