"""Geometry stage: one chain link from a STEP file (or the built-in parametric link) to a tetrahedral
mesh with its two pin bores found and tagged (`LinkMesh`); in a file with other holes or several
solids, the pin bores and the link body are chosen first (`inspect_part`, `LinkSource`).

The names below are imported on first use (PEP 562 `__getattr__`), as in `fem`: `pipeline.py`'s own
process resolves the part and reads the part options (`geometry.part`, `geometry.options`,
`geometry.errors`) but meshes nothing, and importing every module here (gmsh, the meshing, the
searches) took 0.13-0.19 CPU s of its start-up.
"""

from lazy_imports import lazy_exports

_MODULE_OF = {
    "LinkSource": "assembly",
    "PartSummary": "assembly",
    "inspect_part": "assembly",
    "BoreOverride": "bores",
    "CALIBRATED_BODY_VOLUME_M3": "dimensions",
    "DEFAULT_HARDWARE_MASS_KG": "dimensions",
    "DEFAULT_LINK": "dimensions",
    "NEST_MASS_KG": "dimensions",
    "LinkDimensions": "dimensions",
    "nominal_volume_m3": "dimensions",
    "GeometryError": "errors",
    "EXAMPLE_STEP": "example",
    "Bore": "link_mesh",
    "LinkMesh": "link_mesh",
    "load_link": "load",
    "mesh_part": "load",
    "LinkFeatures": "parametric",
    "Part": "part",
    "PartScale": "part",
    "as_part": "part",
    "resolve_part": "part",
    "BoreChoice": "pin_pair",
    "write_step": "step_io",
    "write_vtu": "vtu",
}

__all__ = sorted(_MODULE_OF)
__getattr__, __dir__ = lazy_exports(__name__, _MODULE_OF)
