"""The geometry stage: the part resolved once (link body and pin bores chosen) before any meshing."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from settings import RunConfig
from stages.progress import Progress

if TYPE_CHECKING:  # importing geometry pulls in gmsh
    from geometry.part import Part


def part_source(cfg: RunConfig):
    """What the run's part is resolved from: the STEP file with its part options, or else the built-in
    parametric link's dimensions (None: the default link; a study varies them)."""
    if cfg.link_source is not None:
        return cfg.link_source
    return cfg.geometry if cfg.geometry is not None else cfg.link


def resolve_run_part(cfg: RunConfig) -> Part:
    """The run's `Part`, resolved once (geometry.part.resolve_part); every FEA stage takes it."""
    from geometry.part import resolve_part

    return resolve_part(part_source(cfg))


def inspect_geometry(cfg: RunConfig, progress: Progress) -> tuple[RunConfig, Part]:
    """Resolve the part: pick the link body and its pin bores before any meshing (a part that cannot
    be a link is refused in about the import's time); for a STEP file print the choice and measure
    the hardware solids; with --hardware-from-step their mass replaces --hardware-mass."""
    from fem import load_materials
    from fem.materials import get_material
    from geometry.options import hardware_densities, hardware_masses_kg

    part = resolve_run_part(cfg)
    if not part.is_step:
        return cfg, part
    summary = part.summary
    for line in summary.lines():
        progress(line.strip())
    library = load_materials(cfg.materials_file)
    densities = hardware_densities(cfg.hardware_material, summary, lambda m: get_material(m, library).density_kg_per_m3)
    if densities is None:
        return cfg, part
    mass_kg = sum(hardware_masses_kg(summary, densities))
    used = (
        "replaces --hardware-mass"
        if cfg.hardware_from_step
        else f"for information: the chain uses --hardware-mass {cfg.hardware_mass_kg:g} kg without --hardware-from-step"
    )
    progress(f"hardware in the STEP file: {len(summary.hardware)} solids, {mass_kg:.4f} kg ({used})")
    return (replace(cfg, hardware_mass_kg=mass_kg) if cfg.hardware_from_step else cfg), part
