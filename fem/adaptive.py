"""Link stiffness to a requested accuracy: refine the mesh until the Richardson estimate is small enough.

`stiffness_to_tolerance` solves the link at mesh sizes h0, h0/r, h0/r^2, ... (r = 4/3: each level
has about r^3 = 2.4x the DOFs of the one before), one solve per new level, and after every level
from the second on extrapolates k from the last two levels (`richardson.extrapolate`, the same
bound `stiffness_study` reports; a third level's pair check would keep the pre-asymptotic coarse
start in the estimate). It stops at the first level whose estimated relative error of
the extrapolated k is <= the tolerance. Before meshing a level it predicts that level's DOFs from
the growth between the last two; a level above `max_dofs` (or a mesh size geometry refuses) ends
the refinement with a FemError that states the best estimate reached, so a caller never waits for
a solve the machine cannot afford.

A caller that may tighten the tolerance later (the pipeline does, once it has measured how much a
k error moves the vibration metrics) passes the same `solved` dict to both calls: the levels are
deterministic (same start, same ratio), so the second call reuses the first one's solutions and
meshes and solves only the new, finer levels. Across runs the dict is kept on disk as its
`SolvedLevel`s (`level_records` / `solved_levels_from`, stored by stages.fea in the FEA cache): a
later run's passes read their levels from it, and the one level whose fields the stress study and
the images need, the finest of the pass whose k the run keeps, is solved again for them
(`with_finest_fields`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, fields, replace

from .errors import FemError
from .link import LinkSolution, analyse_link, fallback_note
from .materials import Material
from .richardson import extrapolate, rate_bracket
from .settings import FeaSettings, settings_with
from .study import StiffnessEstimate, estimate_from_levels

REFINEMENT_RATIO = 4 / 3
# Start at the part's bounding-box diagonal / 14 (12 mm on the default link: about 11k P2 DOFs,
# 1 s): three such levels already give k to a few per cent there, and coarser meshes no longer
# resolve the link's rails (k then stops behaving like C h^p).
START_SIZE_FRACTION = 1 / 14
# About 20 s and 3 GB for a P2 solve with PARDISO on 2 cores (field notes: 381k DOFs, 25 s).
DEFAULT_MAX_DOFS = 400_000
MIN_LEVELS = 2  # the error bound needs two levels (see richardson)


@dataclass(frozen=True)
class SolvedLevel:
    """What is kept of a level's LinkSolution across runs: what the estimate (estimate_from_levels) and
    the pipeline's stiffness record (stages.fea) read of a level, not its mesh and fields (SI)."""

    order: int
    stiffness_N_per_m: float
    dofs: int
    whole_link_dofs: int
    mesh_size_m: float
    mass_kg: float
    volume_m3: float
    pitch_m: float
    bore_radius_m: float
    peak_von_mises_Pa_per_N: float
    peak_von_mises_away_from_clamp_Pa_per_N: float
    timing_s: dict
    solver_fallback: str | None = None

    @classmethod
    def of(cls, solution) -> SolvedLevel:
        """A LinkSolution's (or a SolvedLevel's own) kept values, as Python numbers (JSON)."""
        kept = {f.name: getattr(solution, f.name) for f in fields(cls)}
        numbers = {
            name: (int if name in _INTEGERS else float)(value) for name, value in kept.items() if name in _NUMBERS
        }
        timing = {stage: float(seconds) for stage, seconds in solution.timing_s.items()}
        return cls(**{**kept, **numbers, "timing_s": timing})


_INTEGERS = ("order", "dofs", "whole_link_dofs")
_NUMBERS = tuple(f.name for f in fields(SolvedLevel) if f.name not in ("timing_s", "solver_fallback"))


def level_records(solved: dict) -> dict:
    """A `solved` dict as JSON-able records (each level a SolvedLevel's fields, the mesh times as they are)."""
    return {key: value if isinstance(value, float) else asdict(SolvedLevel.of(value)) for key, value in solved.items()}


def solved_levels_from(records: dict) -> dict:
    """`level_records`' inverse: a `solved` dict whose levels are SolvedLevels. A record that is
    neither (a file written by something else) is a FemError naming its key."""
    solved = {}
    for key, value in records.items():
        try:
            solved[key] = value if isinstance(value, float) else SolvedLevel(**value)
        except TypeError:
            raise FemError(f"level {key!r}: expected SolvedLevel's fields or a mesh time, got {value!r:.80}") from None
    return solved


def with_finest_fields(
    source,
    settings: FeaSettings,
    materials: Sequence[Material],
    estimates: dict[str, StiffnessEstimate],
    progress: Callable[[str], None] | None = None,
) -> dict[str, StiffnessEstimate]:
    """The estimates (of `materials`, by name) with a finest level that carries its fields (the stress
    study and the images start from them): a finest level read from an earlier run (a SolvedLevel) is
    meshed and solved again, once for all such materials; the estimate's numbers stay its own."""
    import geometry

    kept = {name: est for name, est in estimates.items() if isinstance(est.finest, SolvedLevel)}
    if not kept:
        return estimates
    by_name = {m.name: m for m in materials}
    h = next(iter(kept.values())).finest.mesh_size_m
    part = geometry.as_part(source, symmetry=False)
    link = geometry.mesh_part(part, mesh_size_m=h, order=settings.mesh_order, bore_refinement=settings.bore_refinement)
    out = dict(estimates)
    for name, estimate in kept.items():
        solution = analyse_link(
            link, by_name[name], order=settings.order, load_N=settings.load_N, solver=settings.solver
        )
        out[name] = replace(estimate, finest=solution)
    if progress is not None:
        progress(f"FEA level of {h * 1e3:.3g} mm solved again for its fields (an earlier run kept its k only)")
    return out


def bounding_diagonal_m(source) -> float:
    """Diagonal of the link's CAD bounding box in metres, hardware solids included (a `geometry.Part`,
    or a source it resolves: a STEP path, None or `LinkDimensions` for the parametric link)."""
    from geometry.part import as_part

    return as_part(source, symmetry=False).geometry.all_solids_diagonal_m


class ToleranceNotReached(FemError):
    """The tolerance needs a level beyond `max_dofs` (`over_dofs`) or a size geometry refuses: the
    message says which; `best_rel_error` is the finest levels' estimate (None: fewer than MIN_LEVELS
    solved), a tolerance a second call with the same solved levels meets without solving anything new."""

    def __init__(self, message: str, best_rel_error: float | None, over_dofs: bool):
        super().__init__(message)
        self.best_rel_error = best_rel_error
        self.over_dofs = over_dofs


def _check(rel_tolerance: float, start_mesh_size_m: float | None, max_dofs: int, ratio: float) -> None:
    if not (isinstance(rel_tolerance, (int, float)) and math.isfinite(rel_tolerance) and 0 < rel_tolerance < 1):
        raise FemError(f"rel_tolerance={rel_tolerance!r}: expected a relative error in (0, 1), e.g. 0.01")
    if start_mesh_size_m is not None and not (math.isfinite(start_mesh_size_m) and start_mesh_size_m > 0):
        raise FemError(f"start_mesh_size_m={start_mesh_size_m!r}: expected a positive element size in metres")
    if not (isinstance(max_dofs, int) and max_dofs > 0):
        raise FemError(f"max_dofs={max_dofs!r}: expected a positive integer")
    if not (isinstance(ratio, (int, float)) and 1.05 <= ratio <= 2):
        raise FemError(f"ratio={ratio!r}: expected a mesh-size ratio between levels in [1.05, 2]")


def stiffness_to_tolerance(
    source,
    material: Material,
    rel_tolerance: float,
    settings: FeaSettings | None = None,
    *,
    start_mesh_size_m: float | None = None,
    progress: Callable[[str], None] | None = None,
    max_dofs: int = DEFAULT_MAX_DOFS,
    ratio: float = REFINEMENT_RATIO,
    **changes,
) -> StiffnessEstimate:
    """k of the link (a `geometry.Part`, or a source it resolves; None = built-in default) with
    estimated relative error <= rel_tolerance.

    Levels are solved coarse to fine, mesh size divided by `ratio` each time, starting at
    `start_mesh_size_m` (None: bounding-box diagonal x START_SIZE_FRACTION). `progress`, if given,
    receives one line per level. Raises FemError when the next level would exceed `max_dofs`
    DOFs (or geometry refuses its size) before the tolerance is met. settings: `FeaSettings` (None:
    the defaults; its order, curved, load, solver and bore refinement are used, not its mesh sizes);
    keyword `changes` replace its fields.
    """
    if not isinstance(material, Material):
        raise FemError(f"material: expected a fem.Material, got {type(material).__name__}")
    return stiffnesses_to_tolerance(
        source,
        [material],
        rel_tolerance,
        settings,
        start_mesh_size_m=start_mesh_size_m,
        progress=progress,
        max_dofs=max_dofs,
        ratio=ratio,
        **changes,
    )[material.name]


def stiffnesses_to_tolerance(
    source,
    materials: Sequence[Material],
    rel_tolerance: float,
    settings: FeaSettings | None = None,
    *,
    start_mesh_size_m: float | None = None,
    progress: Callable[[str], None] | None = None,
    max_dofs: int = DEFAULT_MAX_DOFS,
    ratio: float = REFINEMENT_RATIO,
    solved: dict | None = None,
    **changes,
) -> dict[str, StiffnessEstimate]:
    """`stiffness_to_tolerance` for several materials (keyed by name), meshing each level once.

    Refinement goes on until every material's estimate meets the tolerance (Poisson's ratio
    changes k(h) a little, so one material may need a level more than another). `solved`, if given,
    is read for level solutions already computed and receives the new ones (keyed by everything a
    solution depends on, so a dict shared between different settings is still safe); its levels may
    be SolvedLevels read from an earlier run, and an estimate whose finest level is one has it as its
    `finest` (`with_finest_fields` solves it again where its fields are needed).
    """
    import geometry

    if not materials or not all(isinstance(m, Material) for m in materials):
        raise FemError(f"materials: expected a non-empty sequence of fem.Material, got {materials!r}")
    _check(rel_tolerance, start_mesh_size_m, max_dofs, ratio)
    fea = settings_with(settings, changes)
    order, solver, load_N = fea.order, fea.solver, fea.load_N
    part = geometry.as_part(source, symmetry=False)
    h = START_SIZE_FRACTION * bounding_diagonal_m(part) if start_mesh_size_m is None else float(start_mesh_size_m)
    mesh_time = 0.0  # of every level the estimates rest on, earlier passes' included
    known = {} if solved is None else solved
    settings_key = (part.fingerprint, repr(part.origin), order, solver, fea.curved, load_N, fea.bore_refinement)
    sizes: list[float] = []
    solutions: dict[str, list[LinkSolution]] = {m.name: [] for m in materials}
    first = solutions[materials[0].name]
    while True:
        if len(first) >= 2:
            predicted = first[-1].dofs * first[-1].dofs / first[-2].dofs
            if predicted > max_dofs:
                raise _unreached(
                    rel_tolerance,
                    sizes,
                    solutions,
                    f"the next level (h = {h * 1e3:.3g} mm) would have about {predicted:.3g} DOFs, above max_dofs = {max_dofs}",
                )
        level_start = time.perf_counter()
        level = (*settings_key, f"{h:.12e}")
        keys = {m.name: repr((*level, m)) for m in materials}  # strings: the dict is kept on disk across runs
        mesh_seconds = repr((*level, "mesh seconds"))
        if any(key not in known for key in keys.values()):
            try:
                # No thin-wall fields (no wall_reference_m): the finest size is not known in advance,
                # and walls judged level by level were refined on the coarse levels only, which
                # broke the monotone refinement (the built-in link: 42,612 DOFs at 12 mm, 41,475 at 9).
                link = geometry.mesh_part(
                    part, mesh_size_m=h, order=fea.mesh_order, bore_refinement=fea.bore_refinement
                )
            except geometry.GeometryError as exc:
                if not sizes:
                    raise
                raise _unreached(
                    rel_tolerance, sizes, solutions, f"geometry refused the next level: {exc}", False
                ) from None
            known[mesh_seconds] = time.perf_counter() - level_start
        mesh_time += known[mesh_seconds]
        reused = "solved in an earlier pass"
        for material in materials:
            solution = known.get(keys[material.name])
            if solution is None:
                reused = None
                solution = analyse_link(link, material, order=order, load_N=load_N, solver=solver)
                known[keys[material.name]] = solution
            elif reused and isinstance(solution, SolvedLevel):
                reused = "solved in an earlier run"
            previous = solutions[material.name]
            if previous and solution.dofs <= previous[-1].dofs:
                raise FemError(
                    f"mesh_size_m={h:.4g}: refining gave {solution.dofs} DOFs, not more than {previous[-1].dofs}; the mesh does not follow the size"
                )
            previous.append(solution)
        sizes.append(h)
        errors = {name: _error(sols) for name, sols in solutions.items()}
        if progress is not None:
            ks = ", ".join(f"{name} {sols[-1].stiffness_N_per_m:.6e}" for name, sols in solutions.items())
            worst = None if None in errors.values() else max(errors.values())
            progress(
                f"FEA level {len(sizes)}: h = {h * 1e3:.3g} mm, {first[-1].dofs} DOFs, k (N/m) {ks}, "
                f"estimated error {f'n/a (needs {MIN_LEVELS} levels)' if worst is None else f'{worst:.2e}'}, "
                + (reused or f"{time.perf_counter() - level_start:.1f} s")
                + fallback_note(first[-1])
            )
        if None not in errors.values() and max(errors.values()) <= rel_tolerance:
            break
        if first[-1].dofs > max_dofs:
            raise _unreached(
                rel_tolerance,
                sizes,
                solutions,
                f"this level already has {first[-1].dofs} DOFs, above max_dofs = {max_dofs}",
            )
        h /= ratio
    return {
        name: estimate_from_levels(sizes, sols, mesh_time / len(materials), fit_last=MIN_LEVELS, order=order)
        for name, sols in solutions.items()
    }


def _error(solutions: list[LinkSolution]) -> float | None:
    if len(solutions) < MIN_LEVELS:
        return None
    last = solutions[-MIN_LEVELS:]
    return extrapolate(
        [s.stiffness_N_per_m for s in last], [s.whole_link_dofs for s in last], rate_bracket(last[-1].order)
    ).rel_error_estimate


def _unreached(
    rel_tolerance: float, sizes: list[float], solutions: dict[str, list[LinkSolution]], why: str, over_dofs: bool = True
) -> ToleranceNotReached:
    errors = [_error(sols) for sols in solutions.values()]
    error = None if None in errors else max(errors)
    reached = (
        f"fewer than {MIN_LEVELS} levels solved"
        if error is None
        else f"best estimated error {error:.2e} at h = {sizes[-1] * 1e3:.3g} mm"
    )
    return ToleranceNotReached(
        f"rel_tolerance={rel_tolerance:g} not reached: {why} ({reached}); expected a looser tolerance or a larger max_dofs",
        error,
        over_dofs,
    )
