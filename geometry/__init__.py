"""Geometry stage: one chain link from a STEP file (or the built-in parametric link) to a tetrahedral
mesh with its two pin bores found and tagged (`LinkMesh`); in a file with other holes or several
solids, the pin bores and the link body are chosen first (`inspect_part`, `LinkSource`)."""

from geometry.assembly import LinkSource, PartSummary, inspect_part
from geometry.bores import BoreOverride
from geometry.dimensions import (
    CALIBRATED_BODY_VOLUME_M3,
    DEFAULT_HARDWARE_MASS_KG,
    DEFAULT_LINK,
    NEST_MASS_KG,
    LinkDimensions,
    nominal_volume_m3,
)
from geometry.errors import GeometryError
from geometry.example import EXAMPLE_STEP
from geometry.link_mesh import Bore, LinkMesh
from geometry.load import load_link, mesh_part
from geometry.parametric import LinkFeatures
from geometry.part import Part, PartScale, as_part, resolve_part
from geometry.pin_pair import BoreChoice
from geometry.step_io import write_step
from geometry.vtu import write_vtu

__all__ = [
    "Bore",
    "BoreChoice",
    "BoreOverride",
    "CALIBRATED_BODY_VOLUME_M3",
    "DEFAULT_HARDWARE_MASS_KG",
    "DEFAULT_LINK",
    "EXAMPLE_STEP",
    "GeometryError",
    "LinkDimensions",
    "LinkFeatures",
    "LinkMesh",
    "LinkSource",
    "NEST_MASS_KG",
    "Part",
    "PartScale",
    "PartSummary",
    "as_part",
    "inspect_part",
    "load_link",
    "mesh_part",
    "nominal_volume_m3",
    "resolve_part",
    "write_step",
    "write_vtu",
]
