"""The FEA stage: stiffness, mass and stress per material, cached on disk."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from fem.errors import FemError
from settings import RunConfig
from stages.geometry import resolve_run_part
from stages.progress import Progress

if TYPE_CHECKING:  # importing geometry pulls in gmsh
    from fem.settings import FeaSettings
    from geometry.part import Part


@dataclass(frozen=True)
class MaterialFea:
    """What the dynamics and the outputs need of one material's FEA (SI)."""

    material: str
    stiffness_N_per_m: float
    stiffness_rel_error_estimate: float
    body_mass_kg: float
    body_volume_m3: float
    pitch_m: float
    bore_radius_m: float
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
    """The run's FEA settings: its --mesh-size (the finest level) and --order, FeaSettings' defaults
    for the rest. `concurrent_levels`: see fem.stiffness_studies."""
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


def _fea_record(name: str, material, study, stress) -> dict:
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
        "peak_von_mises_converged_Pa_per_N": stress.peak_Pa_per_N,
        "peak_von_mises_converged_rel_change": stress.rel_change,
        "safety_factor_stress": stress.description,
        "yield_strength_Pa": material.yield_strength_Pa,
        "dofs": fine.dofs,
        "mesh_size_m": fine.mesh_size_m,
        "timing_s": study.timing_s,
        "warnings": [],
    }


def _solve_fea(
    part: Part,
    settings: FeaSettings,
    materials: list,
    stiffness_tolerance: float | None,
    progress: Progress,
    solved_levels: dict | None,
) -> tuple[dict, dict]:
    """FEA studies of the materials not in the cache: fixed levels, or refined to a k tolerance
    (reusing the levels in `solved_levels`, see fem.adaptive); then the peak stress converged by
    local refinement from the finest level (fem.stress). Returns (stiffness, stress) per material."""
    from fem import stiffness_studies
    from fem.adaptive import stiffnesses_to_tolerance
    from fem.stress import stress_study

    source = part.name if part.is_step else "built-in default link"
    if stiffness_tolerance is None:
        progress(f"FEA {', '.join(m.name for m in materials)}: {source}, P{settings.order}, 2 mesh levels")
        studies = stiffness_studies(part, materials, settings, progress=progress)
    else:
        progress(
            f"FEA {', '.join(m.name for m in materials)}: {source}, P{settings.order}, refining to a k error <= "
            f"{100 * stiffness_tolerance:.2g} %"
        )
        studies = stiffnesses_to_tolerance(
            part, materials, stiffness_tolerance, settings, progress=progress, solved=solved_levels
        )
    finest = {name: study.finest for name, study in studies.items()}
    stresses = stress_study(
        part,
        materials,
        settings,
        base_mesh_size_m=next(iter(finest.values())).mesh_size_m,
        base=finest,
        progress=progress,
    )
    return studies, stresses


def run_fea(
    cfg: RunConfig,
    progress: Progress,
    stiffness_tolerance: float | None = None,
    solved_levels: dict | None = None,
    concurrent_levels: bool = True,
    part: Part | None = None,
) -> dict[str, MaterialFea]:
    """Stiffness, mass and stress per material, from the cache when nothing they depend on changed.
    `concurrent_levels`: see fem.stiffness_studies (False where every core already runs a task).
    `part`: the run's part (stages.geometry.inspect_geometry); None resolves it here."""
    import warnings

    from fem import load_materials, render_deformed
    from fem.cache import FeaCache, cache_key
    from fem.errors import FemWarning
    from fem.heap import release_free_memory

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
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FemWarning)
        studies, stresses = (
            _solve_fea(part, settings, missing, stiffness_tolerance, progress, solved_levels) if missing else ({}, {})
        )
    release_free_memory()  # the levels' freed arrays, before the dynamics and the figures
    cautions = list(dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, FemWarning)))
    for message in cautions:
        print(f"pipeline.py: warning: {message}", file=sys.stderr)
    for material in missing:
        name, study = material.name, studies[material.name]
        stored = {**_fea_record(name, material, study, stresses[name]), "warnings": cautions}
        progress(
            f"FEA {name}: k = {study.stiffness_N_per_m:.5g} N/m "
            f"(estimated error {100 * study.stiffness_rel_error_estimate:.2g} %)"
        )
        if images[name] is not None:
            images[name].parent.mkdir(parents=True, exist_ok=True)
            render_deformed(study.finest, images[name], title=f"{name}: k = {study.stiffness_N_per_m:.4g} N/m")
        cache.store(keys[name], stored)
        out[name] = MaterialFea(**stored, cached=False, image=images[name])
    return {name: out[name] for name in cfg.materials}
