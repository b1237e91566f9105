"""`mesh_part`: a resolved `Part` to a `LinkMesh` with its two bores tagged (`load_link`: from a CAD
file or the built-in link, resolved on the way)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

import gmsh
import numpy as np

from geometry.bores import BoreOverride
from geometry.errors import GeometryError
from geometry.link_mesh import LinkMesh, MirrorPlane
from geometry.meshing import mesh_volumes, split_at_loaded_half
from geometry.part import Part, as_part
from geometry.session import gmsh_model, taken_model
from geometry.symmetry import keep_positive_half

#: Default element size as a fraction of the part's bounding-box diagonal (4.2 mm on the default
#: link: a mesh of a few seconds whose P2 stiffness is within about 1 %).
DEFAULT_SIZE_FRACTION = 1 / 40
#: Refuse meshes above this many tetrahedra (estimated from volume and size): about 10 GB to solve.
MAX_TETS = 3_000_000


def load_link(
    source=None,
    *,
    mesh_size_m: float | None = None,
    order: int = 1,
    bore_refinement: float = 0.4,
    bores: BoreOverride | None = None,
    mirror: bool = False,
) -> LinkMesh:
    """Mesh one link: a `Part` (geometry.part), or what `resolve_part` resolves: a STEP file (any
    length unit), the built-in parametric link if None, or the parametric link with other
    `LinkDimensions` (a design study's geometry variant).

    source: a `Part`, a path, or a `LinkSource` (a path with the user's choice of pin bores and link
        body). In a file of several solids only the link body is meshed (geometry.assembly).
    mesh_size_m: element size away from the bores in metres (None: the part's bounding-box
        diagonal / 40). bore_refinement: element size at the bores as a fraction of mesh_size_m.
    order: 1 for linear tetrahedra; 2 also fills `tets10` (curved quadratic tetrahedra whose
        mid-edge nodes lie on the CAD surfaces). bores: manual bores instead of detection (one solid;
        not with a `Part`, whose bores are chosen).
    mirror: if the link is mirror symmetric about the plane through both bore axes (checked, see
        geometry.symmetry), mesh only its half on the positive side of that plane
        (`LinkMesh.mirror_plane` says so); otherwise, or if False, the whole link.
    """
    _check_mesh_options(order, bore_refinement)
    part = as_part(source, bores=bores, symmetry=mirror)
    return mesh_part(part, mesh_size_m=mesh_size_m, order=order, bore_refinement=bore_refinement, mirror=mirror)


def mesh_part(
    part: Part,
    *,
    mesh_size_m: float | None = None,
    order: int = 1,
    bore_refinement: float = 0.4,
    mirror: bool = False,
    wall_reference_m: float | None = None,
) -> LinkMesh:
    """Mesh a resolved part (see `load_link` for the options): its body is loaded into a fresh gmsh
    model from the part's own copy, with the bores chosen at resolution. `wall_reference_m`: the
    size thin walls are judged against (a study's finest size, so that every level refines the
    same walls alike; geometry.meshing.THIN_WALL_FRACTION); None: no thin-wall fields (the mesh as
    `load_link` makes it)."""
    _check_mesh_options(order, bore_refinement)
    if mirror and not part.symmetry_checked:
        raise GeometryError(
            f"mirror=True: {part.name} was resolved with symmetry=False; expected a part resolved "
            "with its symmetry checked (resolve_part(..., symmetry=True))"
        )
    name = part.name
    fixed, loaded = part.pins.fixed, part.pins.loaded
    plane = part.mirror_plane if mirror else None
    with _body_model(part, plane) as volumes:
        size = _checked_mesh_size(mesh_size_m, part.volume_m3, name)
        volumes = split_at_loaded_half(volumes, fixed.bore, loaded.bore)
        try:
            arrays = mesh_volumes(
                volumes,
                fixed,
                loaded,
                mesh_size_m=size,
                bore_size_m=bore_refinement * size,
                order=order,
                mirror_plane=plane,
                wall_reference_m=wall_reference_m,
            )
        except Exception as exc:  # gmsh reports a failed mesh as a bare Exception
            if type(exc) is not Exception:
                raise
            raise GeometryError(
                f"{name}: gmsh could not mesh it at {size * 1e3:.3g} mm elements ({exc}); expected a size "
                "that resolves its smallest holes and walls: pass a smaller --mesh-size MM"
            ) from exc
    return LinkMesh(
        points_m=arrays.points_m,
        tets=arrays.tets,
        fixed_bore_facets=arrays.fixed_bore_facets,
        loaded_bore_facets=arrays.loaded_bore_facets,
        fixed_bore=fixed.bore,
        loaded_bore=loaded.bore,
        cad_volume_m3=float(part.volume_m3),
        mesh_size_m=size,
        source=name,
        tets10=arrays.tets10,
        mirror_plane=plane,
        mirror_facets=arrays.mirror_facets,
    )


@contextlib.contextmanager
def _body_model(part: Part, plane: MirrorPlane | None) -> Iterator[list[int]]:
    """A gmsh model holding the part's body, or its half on the positive side of `plane`: the half
    its measurement kept (`Part.measure_keeping_half`), else the body loaded afresh; its solids."""
    if plane is not None:
        with taken_model(part.half_model_name) as half:
            if half is not None:
                yield half
                return
    with gmsh_model("link"):
        volumes = part.load_body()
        yield volumes if plane is None else keep_positive_half(volumes, plane)


def _check_mesh_options(order: int, bore_refinement: float) -> None:
    if order not in (1, 2):
        raise GeometryError(f"order={order!r}: expected 1 or 2")
    if not (isinstance(bore_refinement, (int, float)) and 0 < bore_refinement <= 1):
        raise GeometryError(f"bore_refinement={bore_refinement!r}: expected a fraction in (0, 1]")


def _checked_mesh_size(mesh_size_m: float | None, volume_m3: float, name: str) -> float:
    """The element size to mesh with. Refusals name the library's argument (metres) and the command
    lines' --mesh-size (mm), which reaches here as one mesh level's size."""
    xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(-1, -1)
    extents = np.array([xmax - xmin, ymax - ymin, zmax - zmin])
    if mesh_size_m is None:
        return float(np.linalg.norm(extents) * DEFAULT_SIZE_FRACTION)
    if not (isinstance(mesh_size_m, (int, float)) and math.isfinite(mesh_size_m) and mesh_size_m > 0):
        raise GeometryError(
            f"mesh_size_m={mesh_size_m!r}: expected a positive element size in metres "
            "(on the command line: a positive --mesh-size in mm)"
        )
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
