"""`ball_mesher`: the part inside balls (a stress sub-model's domain), meshed fine at its centre.

The ball is cut out of the link's solid (or of its mirror half) by OpenCASCADE; the faces the cut
makes lie on the ball's sphere and are returned apart (`cut_facets`): there the sub-model takes
its displacements from a global solution (fem.submodel). Faces on the pin bores and on the mirror
plane that fall inside the ball are returned as well, with the same meaning as in a `LinkMesh`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import gmsh
import numpy as np

from geometry.bores import boundary_faces, faces_on_bore
from geometry.errors import GeometryError
from geometry.meshing import _TET, Refinement, _ball, _facets, _has_flat_tets, _mesh_arrays, split_at_loaded_half
from geometry.part import Part
from geometry.session import gmsh_model
from geometry.symmetry import faces_on_plane, keep_positive_half

# A face is on the cut sphere where its sample points are within this fraction of the ball's radius
# of the sphere (OpenCASCADE places them on it to its 1e-7 m tolerance).
ON_SPHERE_TOLERANCE = 1e-6
_SAMPLES = 5
_SKEW_AXIS, _SKEW_ANGLE = (0.3, 0.5, 0.8), 0.7  # per parameter direction of a face, to tell the cut faces


@dataclass(frozen=True)
class BallMesh:
    """The part inside a ball, meshed: arrays as in `geometry.link_mesh.LinkMesh` (metres)."""

    points_m: np.ndarray  # (3, n)
    tets: np.ndarray  # (4, n_tets)
    tets10: np.ndarray | None  # (10, n_tets) meshio order, or None for order 1
    fixed_bore_facets: np.ndarray  # (3, n) possibly empty: the clamped bore's triangles inside the ball
    loaded_bore_facets: np.ndarray  # (3, n) possibly empty
    mirror_facets: np.ndarray  # (3, n) possibly empty: on the mirror plane of a half
    cut_facets: np.ndarray  # (3, n) on the ball's sphere: where the sub-model is driven
    centers_m: np.ndarray  # (k, 3): the balls' centres
    radius_m: float  # every ball's
    cad_volume_m3: float  # of the part inside the balls (the half's, if mirrored)


@contextlib.contextmanager
def ball_mesher(part: Part, centers_m, radius_m: float, *, mirror: bool = False) -> Iterator[BallMesher]:
    """The part (its positive half if `mirror`) inside the balls of `radius_m` about `centers_m`
    (k, 3), cut once and meshed as often as asked (`BallMesher.mesh`) while the context is open
    (it holds gmsh, geometry.session)."""
    centers = np.atleast_2d(np.asarray(centers_m, dtype=float))
    fixed, loaded = part.pins.fixed, part.pins.loaded
    plane = part.mirror_plane if mirror else None
    with gmsh_model("balls"):
        volumes = part.load_body_brep()
        if plane is not None:
            volumes = keep_positive_half(volumes, plane)
        volumes = split_at_loaded_half(volumes, fixed.bore, loaded.bore)
        occ = gmsh.model.occ
        spheres = [_sphere(c, radius_m) for c in centers]
        if len(spheres) > 1:
            spheres, _ = occ.fuse(spheres[:1], spheres[1:])
        pieces, _ = occ.intersect([(3, v) for v in volumes], spheres)
        occ.synchronize()
        volumes = sorted(tag for dim, tag in pieces if dim == 3)
        if not volumes:
            raise GeometryError(f"{part.name}: the balls at {centers * 1e3} mm hold no material")
        faces = {
            "fixed": faces_on_bore(volumes, fixed.bore),
            "loaded": faces_on_bore(volumes, loaded.bore),
            "mirror": faces_on_plane(volumes, plane) if plane is not None else [],
            "cut": [f for f in boundary_faces(volumes) if any(_on_sphere(f, c, radius_m) for c in centers)],
        }
        if not faces["cut"]:
            raise GeometryError(f"{part.name}: the balls hold the whole part; expected a cut")
        yield BallMesher(faces, centers, float(radius_m), float(sum(occ.getMass(3, v) for v in volumes)))


@dataclass(frozen=True)
class BallMesher:
    """The cut balls in the open gmsh model of `ball_mesher`."""

    faces: dict[str, list[int]]
    centers_m: np.ndarray
    radius_m: float
    cad_volume_m3: float

    def mesh(self, refinements: Sequence[Refinement], size_m: float, order: int = 2) -> BallMesh:
        """Elements of `size_m`, finer in the `refinements` balls (graded over one more radius)."""
        gmsh.model.mesh.clear()
        field = gmsh.model.mesh.field
        for tag in field.list():
            field.remove(tag)
        balls = [_ball(r, size_m) for r in refinements]
        if balls:
            smallest = field.add("Min")
            field.setNumbers(smallest, "FieldsList", balls)
            field.setAsBackgroundMesh(smallest)
        for option in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{option}", 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size_m)
        gmsh.option.setNumber("Mesh.Algorithm3D", 10)
        gmsh.option.setNumber("General.NumThreads", 1)  # the same mesh on every run (geometry.meshing)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.model.mesh.generate(3)
        if _has_flat_tets():
            gmsh.model.mesh.optimize("")
        if order == 2:
            gmsh.model.mesh.setOrder(2)
        arrays = _mesh_arrays(self.faces["fixed"], self.faces["loaded"], order)
        index_of_tag = _index_of_tag(order)
        return BallMesh(
            points_m=arrays.points_m,
            tets=arrays.tets,
            tets10=arrays.tets10,
            fixed_bore_facets=arrays.fixed_bore_facets,
            loaded_bore_facets=arrays.loaded_bore_facets,
            mirror_facets=_facets(self.faces["mirror"], index_of_tag, order),
            cut_facets=_facets(self.faces["cut"], index_of_tag, order),
            centers_m=self.centers_m,
            radius_m=self.radius_m,
            cad_volume_m3=self.cad_volume_m3,
        )


def _sphere(center: np.ndarray, radius_m: float) -> tuple[int, int]:
    """An OpenCASCADE sphere turned about a skew axis before it is placed: its seam and poles off the
    part's axis-aligned faces and edges (a sphere as made, its poles on the default link's faces,
    made the intersection empty at some radii, measured)."""
    occ = gmsh.model.occ
    sphere = (3, occ.addSphere(0.0, 0.0, 0.0, radius_m))
    occ.rotate([sphere], 0.0, 0.0, 0.0, *_SKEW_AXIS, _SKEW_ANGLE)
    occ.translate([sphere], *center)
    return sphere


def _index_of_tag(order: int) -> np.ndarray:
    """gmsh node tag -> index into the mesh arrays' points (numbered as geometry.meshing._mesh_arrays does)."""
    node_tags, _, _ = gmsh.model.mesh.getNodes()
    _, tet_nodes = gmsh.model.mesh.getElementsByType(_TET[order])
    used = np.unique(np.asarray(tet_nodes, dtype=np.int64))
    index_of_tag = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    index_of_tag[used] = np.arange(len(used))
    return index_of_tag


def _on_sphere(face: int, center: np.ndarray, radius_m: float) -> bool:
    umin, vmin, umax, vmax = _bounds(face)
    u, v = np.meshgrid(np.linspace(umin, umax, _SAMPLES), np.linspace(vmin, vmax, _SAMPLES))
    params = np.column_stack([u.ravel(), v.ravel()]).ravel()
    # on the face's underlying surface (for a cut face: the whole sphere)
    points = np.asarray(gmsh.model.getValue(2, face, params)).reshape(-1, 3)
    distance = np.linalg.norm(points - center, axis=1)
    return bool(np.max(np.abs(distance - radius_m)) <= ON_SPHERE_TOLERANCE * radius_m + 1e-9)


def _bounds(face: int) -> tuple[float, float, float, float]:
    low, high = gmsh.model.getParametrizationBounds(2, face)
    return low[0], low[1], high[0], high[1]
