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
    link_source: object = None  # geometry.assembly.LinkSource: --geometry with --bores/--pitch/--bore-radius/--body
    hardware_material: str | None = None  # --hardware-material: ids for the STEP file's hardware solids
    hardware_from_step: bool = False  # --hardware-from-step: hardware mass from those solids, not --hardware-mass
    # the chain model (issue #11): see dynamics.clearance_sim
    model: str = "auto"
    pin_clearance_m: float = 94e-6  # dynamics.clearance.DEFAULT_PIN_CLEARANCE_M
    span_damping: str = "global"
    rayleigh: tuple[float, float] | None = None
    tensioner_rate_N_per_m: float | None = None
    tensioner_mass_kg: float | None = None
    tensioner_damping_N_s_per_m: float | None = None
    # the built-in link's dimensions when `geometry` is None (None: DEFAULT_LINK); a study varies them
    link: LinkDimensions | None = None
