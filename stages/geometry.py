"""The geometry stage: the link body and its pin bores chosen before any meshing."""

from __future__ import annotations

from dataclasses import replace

from stages.config import RunConfig
from stages.progress import Progress


def inspect_geometry(cfg: RunConfig, progress: Progress) -> RunConfig:
    """Pick the link body and its pin bores before any meshing (a part that cannot be a link is
    refused in about the import's time), print the choice, and measure the hardware solids; with
    --hardware-from-step their mass replaces --hardware-mass."""
    from fem import load_materials
    from fem.materials import get_material
    from geometry.assembly import inspect_part
    from geometry.options import hardware_densities, hardware_masses_kg

    summary = inspect_part(cfg.link_source)
    for line in summary.lines():
        progress(line.strip())
    library = load_materials(cfg.materials_file)
    densities = hardware_densities(cfg.hardware_material, summary, lambda m: get_material(m, library).density_kg_per_m3)
    if densities is None:
        return cfg
    mass_kg = sum(hardware_masses_kg(summary, densities))
    used = ("replaces --hardware-mass" if cfg.hardware_from_step
            else f"for information: the chain uses --hardware-mass {cfg.hardware_mass_kg:g} kg without --hardware-from-step")
    progress(f"hardware in the STEP file: {len(summary.hardware)} solids, {mass_kg:.4f} kg ({used})")
    return replace(cfg, hardware_mass_kg=mass_kg) if cfg.hardware_from_step else cfg
