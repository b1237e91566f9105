"""The FEA stage: stiffness, mass and stress per material, cached on disk."""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, fields
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

from fem.errors import FemError
from settings import RunConfig
from stages.geometry import resolve_run_part
from stages.progress import Progress

if TYPE_CHECKING:  # importing geometry pulls in gmsh
    from fem.settings import FeaSettings
    from geometry.part import Part
    from stages.beside import Beside


@dataclass(frozen=True)
class MaterialStiffness:
    """What the chain needs of one material's FEA (SI): known once the stiffness levels are solved,
    before the stress study (which `pipeline.py` runs beside the dynamics, see `start_fea`)."""

    material: str
    stiffness_N_per_m: float
    stiffness_rel_error_estimate: float
    body_mass_kg: float
    body_volume_m3: float
    pitch_m: float
    bore_radius_m: float


@dataclass(frozen=True)
class MaterialFea(MaterialStiffness):
    """What the dynamics and the outputs need of one material's FEA (SI)."""

    peak_von_mises_Pa_per_N: float
    peak_von_mises_away_from_clamp_Pa_per_N: float
    peak_von_mises_converged_Pa_per_N: float  # converged by local refinement (fem.stress): the design stress
    peak_von_mises_converged_rel_change: float  # its last change under refinement (estimated error)
    safety_factor_stress: str  # which stress the yield safety factor uses, in words
    yield_strength_Pa: float
    dofs: int
    mesh_size_m: float
    timing_s: dict
    warnings: list
    cached: bool
    image: Path | None


def fea_settings(cfg: RunConfig, concurrent_levels: bool = True) -> FeaSettings:
    """The run's FEA settings: its --mesh-size (the finest level), --order and --max-memory,
    FeaSettings' defaults for the rest. `concurrent_levels`: see fem.stiffness_studies."""
    from fem.settings import FeaSettings

    return FeaSettings.with_finest(
        cfg.mesh_size_m, order=cfg.order, concurrent_levels=concurrent_levels, max_memory_gb=cfg.max_memory_gb
    )


def fea_cache_settings(cfg: RunConfig, settings: FeaSettings, material, stiffness_tolerance: float | None) -> dict:
    """What the FEA result depends on besides the part's fingerprint: the cache key's settings."""
    from dataclasses import asdict

    key = {
        "material": asdict(material),
        "mesh_size_m": cfg.mesh_size_m,
        "max_memory_gb": settings.max_memory_gb,  # a budget that coarsens the default sizes changes k
        "order": settings.order,
        "stiffness_tolerance": stiffness_tolerance,
        "stress_tolerance": settings.stress_tolerance,
    }
    if cfg.link_source is not None and (cfg.link_source.bores.given or cfg.link_source.body is not None):
        key["part"] = repr((cfg.link_source.bores, cfg.link_source.body))  # another pair: another link
    return key


def _stiffness_record(name: str, study) -> dict:
    """A material's cache record as far as the stiffness levels give it (its stress fields follow)."""
    fine = study.finest
    return {
        "material": name,
        "stiffness_N_per_m": study.stiffness_N_per_m,
        "stiffness_rel_error_estimate": study.stiffness_rel_error_estimate,
        "body_mass_kg": fine.mass_kg,
        "body_volume_m3": fine.volume_m3,
        "pitch_m": fine.pitch_m,
        "bore_radius_m": fine.bore_radius_m,
        "peak_von_mises_Pa_per_N": fine.peak_von_mises_Pa_per_N,
        "peak_von_mises_away_from_clamp_Pa_per_N": fine.peak_von_mises_away_from_clamp_Pa_per_N,
        "dofs": fine.dofs,
        "mesh_size_m": fine.mesh_size_m,
        "timing_s": study.timing_s,
    }


def _fea_record(stiffness: dict, material, stress: StressAnswer, cautions: list[str]) -> dict:
    """The whole cache record, its keys in MaterialFea's order."""
    record = {
        **stiffness,
        "peak_von_mises_converged_Pa_per_N": stress.peak_Pa_per_N,
        "peak_von_mises_converged_rel_change": stress.rel_change,
        "safety_factor_stress": stress.description,
        "yield_strength_Pa": material.yield_strength_Pa,
        "warnings": cautions,
    }
    return {f.name: record[f.name] for f in fields(MaterialFea) if f.name in record}


@dataclass(frozen=True)
class StressAnswer:
    """What the outputs keep of a material's stress study (fem.stress.StressEstimate), small enough
    to come back from the process that ran it."""

    peak_Pa_per_N: float
    rel_change: float
    description: str


def _solve_stiffness(
    part: Part,
    settings: FeaSettings,
    materials: list,
    stiffness_tolerance: float | None,
    progress: Progress,
    solved_levels: dict | None,
    max_dofs: int,
) -> dict:
    """Stiffness studies of the materials not in the cache: fixed levels, or refined to a k tolerance
    (reusing the levels in `solved_levels`, see fem.adaptive) on levels of at most `max_dofs` DOFs."""
    from fem import stiffness_studies
    from fem.adaptive import stiffnesses_to_tolerance
    from fem.study import planned_mesh_sizes

    source = part.name if part.is_step else "built-in default link"
    if stiffness_tolerance is None:
        n_levels = len(planned_mesh_sizes(part, settings)[0])
        progress(f"FEA {', '.join(m.name for m in materials)}: {source}, P{settings.order}, {n_levels} mesh levels")
        return stiffness_studies(part, materials, settings, progress=progress)
    progress(
        f"FEA {', '.join(m.name for m in materials)}: {source}, P{settings.order}, refining to a k error <= "
        f"{100 * stiffness_tolerance:.2g} %"
    )
    return stiffnesses_to_tolerance(
        part, materials, stiffness_tolerance, settings, progress=progress, solved=solved_levels, max_dofs=max_dofs
    )


def _fea_steps(
    part: Part,
    settings: FeaSettings,
    materials: list,
    stiffness_tolerance: float | None,
    solved_levels: dict | None,
    images: dict,
    progress: Progress,
    max_dofs: int,
    draw_here: bool = True,
) -> Iterator[tuple[dict, list[str]] | tuple[list, list[str]]]:
    """The FEA of the materials not in the cache, in two steps, each with the FemWarnings' messages
    it raised: first each material's stiffness record (all the chain needs), then its converged
    stress (StressAnswer), the deformed images rendered where asked for. Run here or in a process
    beside the run (stages.beside), the same code either way. Without `draw_here`, a step between
    the two hands over the images' `fem.render.Drawing`s (and no messages) for the caller to draw."""
    import warnings

    from fem.adaptive import with_finest_fields
    from fem.errors import FemWarning
    from fem.heap import release_free_memory
    from fem.render import Picture, render_pictures
    from fem.stress import stress_study

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FemWarning)
        studies = _solve_stiffness(part, settings, materials, stiffness_tolerance, progress, solved_levels, max_dofs)
    release_free_memory()  # the levels' threads' freed arrays
    yield {name: _stiffness_record(name, study) for name, study in studies.items()}, _messages(caught)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FemWarning)
        studies = with_finest_fields(part, settings, materials, studies, progress)  # levels of an earlier run
    refit_messages = _messages(caught)
    pictures = [
        Picture(study.finest, images[name], f"{name}: k = {study.stiffness_N_per_m:.4g} N/m")
        for name, study in studies.items()
        if images[name] is not None
    ]
    if not draw_here:
        yield [picture.drawing() for picture in pictures], []
        pictures = []
    finest = {name: study.finest for name, study in studies.items()}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FemWarning)
        stresses = stress_study(
            part,
            materials,
            settings,
            base_mesh_size_m=next(iter(finest.values())).mesh_size_m,
            base=finest,
            progress=progress,
        )
    render_pictures(pictures)
    del studies, finest, pictures
    release_free_memory()  # the levels' arrays, before the dynamics and the figures
    answers = {name: StressAnswer(s.peak_Pa_per_N, s.rel_change, s.description) for name, s in stresses.items()}
    yield answers, refit_messages + _messages(caught)


def stored_levels(cfg: RunConfig, part: Part) -> dict:
    """The FEA levels earlier --tolerance runs solved on this part (fem.adaptive's `solved` dict, from
    the FEA cache): a pass reads its levels from it instead of solving them again. A levels file that
    cannot be read (cut short, or not levels) is ignored with a warning: its levels are solved again."""
    from fem.cache import FeaCache

    return _readable_levels(FeaCache(cfg.cache_dir), _levels_key(part), "its levels are solved again")


def store_levels(cfg: RunConfig, part: Part, levels: dict) -> None:
    """Add `levels` (stored_levels' and this run's) to the levels kept in the FEA cache for later runs:
    under the entry's lock, so that runs sharing the cache keep each other's levels (a level's key
    names everything it depends on, so two runs' levels under one key are the same level)."""
    from fem.adaptive import level_records
    from fem.cache import FeaCache

    cache, key = FeaCache(cfg.cache_dir), _levels_key(part)
    with cache.levels_locked(key):
        kept = _readable_levels(cache, key, "replaced by this run's levels")
        cache.store_levels(key, level_records({**kept, **levels}))


def _readable_levels(cache, key: str, instead: str) -> dict:
    """The levels kept under `key`, or none (with a warning that says `instead`) where their file
    cannot be read."""
    from fem.adaptive import solved_levels_from

    try:
        return solved_levels_from(cache.load_levels(key))
    except FemError as exc:
        _print_cautions([f"FEA cache: {exc}; ignored, {instead}"])
        return {}


def _levels_key(part: Part) -> str:
    """One record of solved levels per part: each level's own key names its settings (fem.adaptive)."""
    from fem.cache import cache_key

    return cache_key(part.fingerprint, {"solved levels": True})


# The images' process draws beside the dynamics and the stress study, every core busy (docs/
# performance.md, The whole job), and ends when they are drawn. Measured in a fork of a process
# holding the run's modules, frozen as the run's (benchmarks/bench_images.py; the default run's
# two images, 2026-11-27):
# - Mesa's software rasteriser draws in this process's thread instead of starting one thread per
#   core (llvmpipe's LP_NUM_THREADS; read when VTK first opens its display, after this is set):
#   1.85 against 2.07 CPU s (medians of 5 alternating, load 7.3-9.2), the PNGs the same byte for byte;
# - no cyclic garbage collection: the drawing (pyvista's import included) set off 191 collections,
#   0.06-0.07 CPU s, in a process of a few seconds whose memory is given back when it ends.
DRAWING_ENVIRONMENT = {"LP_NUM_THREADS": "0"}


def _draw_steps(drawings: list) -> Iterator[None]:
    """The deformed images drawn (fem.render.draw_pictures), as one step of a process beside (see
    DRAWING_ENVIRONMENT)."""
    import gc
    import os

    for name, value in DRAWING_ENVIRONMENT.items():
        os.environ.setdefault(name, value)  # a user's own setting kept
    gc.disable()
    from fem.render import draw_pictures

    draw_pictures(drawings)
    yield None


def _start_drawing(drawings: list) -> Beside:
    """A process forked from this one that draws the deformed images: it has the outputs' modules
    (matplotlib, which pyvista imports) already, and the FEA's process ends after the stress study.
    The run's objects are frozen out of the collector's sight for the fork (as the figure workers',
    reporting.drawing), so that the child's collections do not copy their pages."""
    import gc

    from stages.beside import Beside

    gc.freeze()
    try:
        return Beside(partial(_draw_steps, drawings), "the deformed images", start_method="fork")
    finally:
        gc.unfreeze()


# What the FEA's process imports before its work (stages.fea._fea_steps and what it calls first),
# for a process started before the run knows that it needs one (`waiting_fea_process`); the part's
# measurement and meshing (gmsh) named too: `geometry` imports them on first use only
FEA_MODULES = (
    "stages.fea",
    "fem.adaptive",
    "fem.heap",
    "fem.render",
    "fem.stress",
    "fem.study",
    "geometry.load",
    "geometry.measure",
)


def waiting_fea_process() -> Beside | None:
    """A process for the FEA beside the run, started now, before the command line is read: its
    interpreter's start-up and FEA_MODULES' imports (about 1.3 CPU s) run on the core that this
    process's start-up leaves idle, and the FEA starts when `start_fea(..., process=...)` hands it
    its steps. It starts 0.13-0.15 CPU s into the run instead of 0.5-0.56 for a process spawned by
    `start_fea` (after the settings' checks, the part and the cache lookups: numpy, gmsh and the
    part's modules); the stiffness was ready 25.9 instead of 28.0 s after the launch (medians of 5
    alternating, benchmarks/bench_startup.py, load 4.4-6.6, 2026-11-27). A run that needs no FEA
    beside (every material cached, --serial, --tolerance) cancels it (or it ends with this
    process); None where this process may not start one (processes.may_start_children)."""
    from processes import may_start_children
    from stages.beside import Beside

    return Beside.waiting("the FEA", FEA_MODULES) if may_start_children() else None


def _messages(caught) -> list[str]:
    from fem.errors import FemWarning

    return list(dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, FemWarning)))


def _print_cautions(messages: list[str]) -> None:
    for message in messages:
        print(f"pipeline.py: warning: {message}", file=sys.stderr)


class FeaInProgress:
    """A run's FEA under way: `stiffness` (what the chain needs; waits for the stiffness levels where
    they run beside) and `result()` (the complete records; waits for the stress study where it runs
    beside), see `start_fea`. As a context manager, a failure inside stops the process beside:
    nothing waits for it."""

    def __init__(
        self,
        stiffness: Callable[[], dict[str, MaterialStiffness]],
        finish: Callable[[], dict[str, MaterialFea]],
        beside,
        helpers: list | None = None,
    ):
        self._stiffness_of = stiffness
        self._stiffness: dict[str, MaterialStiffness] | None = None
        self._finish = finish
        self._beside = beside
        self._helpers = helpers if helpers is not None else []  # processes started on its behalf (the images')
        self._result: dict[str, MaterialFea] | None = None

    @property
    def stiffness(self) -> dict[str, MaterialStiffness]:
        if self._stiffness is None:
            self._stiffness = self._stiffness_of()
        return self._stiffness

    @classmethod
    def done(cls, fea: dict[str, MaterialFea]) -> FeaInProgress:
        """An FEA already complete (the --tolerance passes run it whole)."""
        return cls(lambda: dict(fea), lambda: fea, None)

    @property
    def beside(self) -> bool:
        """Whether the stress study runs in a process beside this one."""
        return self._beside is not None

    def result(self) -> dict[str, MaterialFea]:
        if self._result is None:
            self.stiffness  # noqa: B018 (the steps come in order)
            self._result = self._finish()
        return self._result

    def cancel(self) -> None:
        for process in [self._beside, *self._helpers]:
            if process is not None:
                process.cancel()

    def __enter__(self) -> FeaInProgress:
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is not None:
            self.cancel()
        return False


def start_fea(
    cfg: RunConfig,
    progress: Progress,
    stiffness_tolerance: float | None = None,
    solved_levels: dict | None = None,
    concurrent_levels: bool = True,
    part: Part | None = None,
    beside: bool = False,
    stress_later: bool = False,
    process: Beside | None = None,
) -> FeaInProgress:
    """Stiffness, mass and stress per material, from the cache when nothing they depend on changed.
    Without `beside`, everything is solved here before it returns. With `beside`, it returns once a
    process of its own (stages.beside) is started on the FEA: `FeaInProgress.stiffness` waits for
    the stiffness levels (what the chain needs), and the process goes on with the stress study and
    the deformed images while the caller runs the dynamics; `FeaInProgress.result()` waits for them.
    The records are stored in the cache when complete.
    `concurrent_levels`: see fem.stiffness_studies (False where every core already runs a task).
    `part`: the run's part (stages.geometry.inspect_geometry); None resolves it here.
    `stress_later` (without `beside`): the stress study and the images wait for `result()`, which a
    caller that may not need them never calls (the --tolerance pass a second pass replaces); nothing
    is stored in the cache then.
    `process`: a process started for the FEA already (`waiting_fea_process`): handed the FEA's steps
    where they run beside, else cancelled here (every material cached, or without `beside`)."""
    from fem import load_materials
    from fem.cache import FeaCache, cache_key
    from processes import may_fork_children, may_start_children
    from stages.beside import Beside

    library = load_materials(cfg.materials_file)
    unknown = [m for m in cfg.materials if m not in library]
    if unknown:
        raise FemError(f"--materials: unknown material {unknown[0]!r}; expected one of {', '.join(library)}")
    cache = FeaCache(cfg.cache_dir)
    if part is None:
        part = resolve_run_part(cfg)
    settings = fea_settings(cfg, concurrent_levels)
    # the parametric link is keyed by its dimensions (the default link's key is unchanged)
    keys = {
        name: cache_key(part.fingerprint, fea_cache_settings(cfg, settings, library[name], stiffness_tolerance))
        for name in cfg.materials
    }
    images = {name: cache.image_path(key) if cfg.images else None for name, key in keys.items()}
    out: dict[str, MaterialFea] = {}
    for name, key in keys.items():
        stored = cache.load(key)
        if stored is not None and (images[name] is None or images[name].exists()):
            progress(f"FEA {name}: cached result (k = {stored['stiffness_N_per_m']:.5g} N/m)")
            out[name] = MaterialFea(**stored, cached=True, image=images[name])
    missing = [library[name] for name in cfg.materials if name not in out]
    beside = beside and bool(missing) and may_start_children()
    if process is not None and not beside:
        process.cancel()  # no FEA to run beside: it ends now, not with the run
        process = None
    if not missing:
        return FeaInProgress.done(out)
    # the images drawn by a process forked from this one, beside the dynamics (see _start_drawing)
    draw_beside = beside and any(images[m.name] is not None for m in missing) and may_fork_children()
    steps = partial(
        _fea_steps,
        part,
        settings,
        missing,
        stiffness_tolerance,
        solved_levels,
        images,
        progress,
        cfg.max_fea_dofs,
        draw_here=not draw_beside,
    )
    if beside:
        if process is None:
            process = Beside(steps, "the FEA")
        else:
            process.hand(steps, "the FEA")
        progress(f"FEA: in process {process.pid}, beside the dynamics and the figures from the stiffness on")
        next_step = process.next
    elif stress_later:  # the stiffness at `stiffness`, the stresses only at `result()`
        process, next_step = None, steps().__next__
    else:  # both steps now: the levels' arrays are freed before the dynamics and the figures
        process, next_step = None, iter(list(steps())).__next__
    records: dict[str, dict] = {}
    cautions: list[str] = []
    drawing: list[Beside] = []

    def stiffness() -> dict[str, MaterialStiffness]:
        step, step_cautions = next_step()
        if draw_beside:
            drawings, _ = next_step()
            drawing.append(_start_drawing(drawings))
        records.update(step)
        cautions.extend(step_cautions)
        _print_cautions(cautions)
        for name, record in records.items():
            progress(
                f"FEA {name}: k = {record['stiffness_N_per_m']:.5g} N/m "
                f"(estimated error {100 * record['stiffness_rel_error_estimate']:.2g} %)"
            )
        fields_of = [f.name for f in fields(MaterialStiffness)]
        return {
            name: out[name] if name in out else MaterialStiffness(**{f: records[name][f] for f in fields_of})
            for name in cfg.materials
        }

    def finish() -> dict[str, MaterialFea]:
        stresses, stress_cautions = next_step()
        if process is not None:
            process.close()
        for images_drawn in drawing:
            images_drawn.close()
        _print_cautions([c for c in stress_cautions if c not in cautions])
        every = list(dict.fromkeys(cautions + stress_cautions))
        for material in missing:
            name = material.name
            stored = _fea_record(records[name], material, stresses[name], every)
            cache.store(keys[name], stored)
            out[name] = MaterialFea(**stored, cached=False, image=images[name])
        return {name: out[name] for name in cfg.materials}

    return FeaInProgress(stiffness, finish, process, drawing)


def run_fea(
    cfg: RunConfig,
    progress: Progress,
    stiffness_tolerance: float | None = None,
    solved_levels: dict | None = None,
    concurrent_levels: bool = True,
    part: Part | None = None,
) -> dict[str, MaterialFea]:
    """Stiffness, mass and stress per material (`start_fea`, every part of it in this process)."""
    return start_fea(cfg, progress, stiffness_tolerance, solved_levels, concurrent_levels, part).result()
