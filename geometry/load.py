"""`load_link`: a CAD file (or the built-in link) to a `LinkMesh` with its two bores tagged."""

from __future__ import annotations

import math
import os
from pathlib import Path

import gmsh
import numpy as np

from geometry.assembly import LinkSource, as_link_source, pick_body
from geometry.bores import BoreOverride, bores_from_override
from geometry.dimensions import DEFAULT_LINK, LinkDimensions
from geometry.errors import GeometryError
from geometry.link_mesh import LinkMesh
from geometry.meshing import mesh_volumes, split_at_loaded_half
from geometry.parametric import add_link
from geometry.session import gmsh_model
from geometry.step_io import import_step
from geometry.symmetry import keep_positive_half, symmetry_plane

#: Default element size as a fraction of the part's bounding-box diagonal (4.2 mm on the default
#: link: a mesh of a few seconds whose P2 stiffness is within about 1 %).
DEFAULT_SIZE_FRACTION = 1 / 40
#: Refuse meshes above this many tetrahedra (estimated from volume and size): about 10 GB to solve.
MAX_TETS = 3_000_000


def load_link(
    source: str | os.PathLike | LinkSource | LinkDimensions | None = None,
    *,
    mesh_size_m: float | None = None,
    order: int = 1,
    bore_refinement: float = 0.4,
    bores: BoreOverride | None = None,
    mirror: bool = False,
) -> LinkMesh:
    """Mesh one link: a STEP file (any length unit), the built-in parametric link if None, or the
    parametric link with other `LinkDimensions` (a design study's geometry variant).

    source: a path, or a `LinkSource` (a path with the user's choice of pin bores and link body). In a
        file of several solids only the link body is meshed (geometry.assembly).
    mesh_size_m: element size away from the bores in metres (None: the part's bounding-box
        diagonal / 40). bore_refinement: element size at the bores as a fraction of mesh_size_m.
    order: 1 for linear tetrahedra; 2 also fills `tets10` (curved quadratic tetrahedra whose
        mid-edge nodes lie on the CAD surfaces). bores: manual bores instead of detection (one solid).
    mirror: if the link is mirror symmetric about the plane through both bore axes (checked, see
        geometry.symmetry), mesh only its half on the positive side of that plane
        (`LinkMesh.mirror_plane` says so); otherwise, or if False, the whole link.
    """
    if order not in (1, 2):
        raise GeometryError(f"order={order!r}: expected 1 or 2")
    if not (isinstance(bore_refinement, (int, float)) and 0 < bore_refinement <= 1):
        raise GeometryError(f"bore_refinement={bore_refinement!r}: expected a fraction in (0, 1]")
    name = source_name(source)
    with gmsh_model("link"):
        volumes = [add_link(parametric_dimensions(source))] if is_parametric(source) else import_step(name)
        if bores is not None:
            if len(volumes) != 1:
                raise GeometryError(f"{name}: holds {len(volumes)} solids; expected exactly one solid link")
            fixed, loaded = bores_from_override(volumes, bores, name)
        else:
            link_source = LinkSource(Path(name)) if is_parametric(source) else as_link_source(source)
            body, pins = pick_body(volumes, link_source, name)
            fixed, loaded = pins.fixed, pins.loaded
            _keep_only(volumes, body)
            volumes = [body]
        cad_volume_m3 = sum(gmsh.model.occ.getMass(3, v) for v in volumes)
        size = _checked_mesh_size(mesh_size_m, cad_volume_m3, name)
        plane = symmetry_plane(volumes, fixed.bore, loaded.bore) if mirror else None
        if plane is not None:
            volumes = keep_positive_half(volumes, plane)
        volumes = split_at_loaded_half(volumes, fixed.bore, loaded.bore)
        try:
            arrays = mesh_volumes(volumes, fixed, loaded, mesh_size_m=size, bore_size_m=bore_refinement * size, order=order,
                                  mirror_plane=plane)
        except Exception as exc:  # gmsh reports a failed mesh as a bare Exception
            if type(exc) is not Exception:
                raise
            raise GeometryError(f"{name}: gmsh could not mesh it at {size * 1e3:.3g} mm elements ({exc}); expected a size "
                                "that resolves its smallest holes and walls: pass a smaller --mesh-size MM") from exc
    return LinkMesh(
        points_m=arrays.points_m,
        tets=arrays.tets,
        fixed_bore_facets=arrays.fixed_bore_facets,
        loaded_bore_facets=arrays.loaded_bore_facets,
        fixed_bore=fixed.bore,
        loaded_bore=loaded.bore,
        cad_volume_m3=float(cad_volume_m3),
        mesh_size_m=size,
        source=name,
        tets10=arrays.tets10,
        mirror_plane=plane,
        mirror_facets=arrays.mirror_facets,
    )


def _keep_only(volumes: list[int], body: int) -> None:
    """Remove every solid but the link body (its hardware is not meshed)."""
    others = [(3, v) for v in volumes if v != body]
    if others:
        gmsh.model.occ.remove(others, recursive=True)
        gmsh.model.occ.synchronize()
def is_parametric(source) -> bool:
    """The source is the built-in parametric link (None) or a `LinkDimensions` variant of it."""
    return source is None or isinstance(source, LinkDimensions)


def parametric_dimensions(source: LinkDimensions | None) -> LinkDimensions:
    return DEFAULT_LINK if source is None else source


def source_name(source) -> str:
    """How a link source is named in messages and in `LinkMesh.source`."""
    if source is None:
        return "default"
    return f"parametric {source}" if isinstance(source, LinkDimensions) else os.fspath(source)


def _checked_mesh_size(mesh_size_m: float | None, volume_m3: float, name: str) -> float:
    """The element size to mesh with. Refusals name the library's argument (metres) and the command
    lines' --mesh-size (mm), which reaches here as one mesh level's size."""
    xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(-1, -1)
    extents = np.array([xmax - xmin, ymax - ymin, zmax - zmin])
    if mesh_size_m is None:
        return float(np.linalg.norm(extents) * DEFAULT_SIZE_FRACTION)
    if not (isinstance(mesh_size_m, (int, float)) and math.isfinite(mesh_size_m) and mesh_size_m > 0):
        raise GeometryError(f"mesh_size_m={mesh_size_m!r}: expected a positive element size in metres "
                            "(on the command line: a positive --mesh-size in mm)")
    if mesh_size_m > extents.max():
        raise GeometryError(
            f"mesh_size_m={mesh_size_m!r}: larger than {name} ({1e3 * extents.max():.4g} mm across); expected an "
            "element size in metres (on the command line: a smaller --mesh-size in mm)"
        )
    regular_tet_m3 = mesh_size_m**3 / (6 * math.sqrt(2))
    if volume_m3 / regular_tet_m3 > MAX_TETS:
        raise GeometryError(
            f"mesh_size_m={mesh_size_m!r}: would give about {volume_m3 / regular_tet_m3:.3g} tetrahedra for {name}; "
            f"expected at most {MAX_TETS:.3g} (a larger size; on the command line: a larger --mesh-size in mm)"
        )
    return float(mesh_size_m)
