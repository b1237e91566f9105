"""The settings of one design run (SI), as the command line or a study point gives them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # importing geometry pulls in gmsh, which parsing options does not need
    from geometry.dimensions import LinkDimensions


@dataclass(frozen=True)
class RunConfig:
    geometry: Path | None
    materials: tuple[str, ...]
    materials_file: Path | None
    links: int
    rpm: float
    cams: tuple[str, ...]
    friction: float
    damping: float
    preload_N: float
    solver: str
    preset: str | None
    out: Path
    images: bool
    quiet: bool
    mesh_size_m: float | None
    order: int
    hardware_mass_kg: float
    nest_mass_kg: float
    cache_dir: Path
    steady_state: bool
    samples_per_degree: int
    tolerance: float | None
    rpm_sweep: str | None
    settling_band_m: float
    station: str | None
    # the built-in link's dimensions when `geometry` is None (None: DEFAULT_LINK); a study varies them
    link: LinkDimensions | None = None
