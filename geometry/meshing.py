"""Tetrahedral meshing of the link in the current gmsh model, refined at the bores.

The loaded bore is first split by the plane through its axis normal to the load direction
(`occ.fragment` of the solid with that plane), so the loaded half of the bore is a set of CAD faces
of its own and no surface triangle straddles the edge of the bearing-pressure patch (straddling
triangles make the stiffness move non-monotonically under refinement). The solid then consists of
two volumes meshed conformingly as one mesh.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import gmsh
import numpy as np

from geometry.bores import DetectedBore, faces_on_bore, find_holes
from geometry.errors import GeometryError
from geometry.link_mesh import Bore, MirrorPlane
from geometry.symmetry import faces_on_plane
from geometry.walls import thin_walls

# gmsh's tet10 numbers the last two mid-edge nodes (edges 2-3 and 1-3) the other way round from
# VTK/meshio "tetra10" (edges 1-3 and 2-3).
_GMSH_TO_MESHIO_TET10 = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]
_TET = {1: 4, 2: 11}  # gmsh element type of the tetrahedron of each order
_TRIANGLE = {1: 2, 2: 9}
DISTANCE_SAMPLING = 20
# Elements at a hole other than the pin bores (screw, grease holes) at most this many times its
# radius, graded to the size elsewhere: ~6 elements round the hole, enough for gmsh's volume
# mesher (it failed at elements 2.2x a screw hole's radius) and for curved P2 cells that follow
# the hole. Only there: one global size from the smallest hole gave the 400 mm arm bar (r 1.05 mm
# screw holes) 305,012 tets and no answer within 300 s.
SMALL_HOLE_SIZE_FRACTION = 1.0
# A tet of radius ratio below this is flat to round-off (fem.quality.DEGENERATE_QUALITY is 1e-12);
# one seen from HXT on a sample part with small-hole fields at 8 mm elements.
FLAT_TET_QUALITY = 1e-9
# Two pin bores whose radii differ by more than this fraction are sized each for itself.
UNEQUAL_BORES_TOL = 0.01
# The pin bores' field: their size within this many radii of the bore faces (the bearing and clamp
# stress concentrations), graded to the far size by the outer distance.
BORE_FIELD_INNER_RADII = 0.5
BORE_FIELD_OUTER_RADII = 2.5
# Grading from a small hole's size to the far size: the size grows by at most this much per unit
# distance (a gentle gradient keeps the tets' shape).
SIZE_GRADIENT = 0.5
# A thin wall (geometry.walls: planar, or the ring round a hole) thinner than this fraction of the
# reference size h_f (the finest size a study asks for, kept where the memory budget coarsens the
# levels) is refined on every level: there a P2 element of the level's size would have no node
# inside the wall (fem.quality's thin-wall warning). On a level of size h_f a wall of thickness t
# gets elements of max(t, 4 t^2 / h_f): one through the thickness (a P2 node in the middle) under a
# quarter of h_f, growing to h_f at half of it, so that the size is continuous in t (a design
# study's variants of a wall get no jump in k). Every level gets the same fraction of its own size,
# so the levels stay alike and Richardson's h = DOFs^(-1/3) stays their mesh parameter (a fixed size
# in the wall, as at small holes, would leave the wall's error out of the levels' difference, and
# the budget could not coarsen it). Walls at or above half the finest size are meshed as before: the
# built-in link's 2.535 mm side rails at 4.5 mm (refining them on its 6 mm level alone widened its
# estimate from 0.85 to 0.91 %, measured).
THIN_WALL_FRACTION = 0.5


@dataclass(frozen=True)
class Refinement:
    """A ball in which the element size is at most `size_m` (e.g. around a stress hot spot)."""

    center_m: tuple[float, float, float]
    radius_m: float
    size_m: float


_REFINEMENTS: contextvars.ContextVar[tuple[Refinement, ...]] = contextvars.ContextVar("refinements", default=())


@contextlib.contextmanager
def refined(balls: Sequence[Refinement]) -> Iterator[None]:
    """Meshes made inside this context (e.g. by `geometry.load_link`) are also refined in `balls`.

    The FEA asks for this to converge a peak stress (refine where it is, mesh again) without the
    loading API carrying a size field.
    """
    token = _REFINEMENTS.set(tuple(balls))
    try:
        yield
    finally:
        _REFINEMENTS.reset(token)


@dataclass(frozen=True)
class MeshArrays:
    points_m: np.ndarray  # (3, n_nodes)
    tets: np.ndarray  # (4, n_tets)
    tets10: np.ndarray | None  # (10, n_tets) meshio order, or None for order 1
    fixed_bore_facets: np.ndarray  # (3, n)
    loaded_bore_facets: np.ndarray  # (3, n)
    mirror_facets: np.ndarray | None = None  # (3, n) on the mirror plane, if meshing a half


def split_at_loaded_half(volumes: list[int], fixed: Bore, loaded: Bore) -> list[int]:
    """Cut the solid by the plane through the loaded bore's axis normal to the load direction."""
    occ = gmsh.model.occ
    axis = loaded.axis
    direction = loaded.center_m - fixed.center_m
    direction = direction - (direction @ axis) * axis
    direction /= np.linalg.norm(direction)
    xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(-1, -1)
    half = np.linalg.norm([xmax - xmin, ymax - ymin, zmax - zmin])
    plane = occ.addRectangle(-half, -half, 0, 2 * half, 2 * half)
    frame = np.column_stack([axis, np.cross(direction, axis), direction, loaded.center_m])
    occ.affineTransform([(2, plane)], frame.ravel().tolist())
    pieces, _ = occ.fragment([(3, v) for v in volumes], [(2, plane)])
    occ.synchronize()
    for _, surface in gmsh.model.getEntities(2):
        if len(gmsh.model.getAdjacencies(2, surface)[0]) == 0:  # the plane outside the solid
            occ.remove([(2, surface)], recursive=True)
    occ.synchronize()
    return sorted(tag for dim, tag in pieces if dim == 3)


def mesh_volumes(
    volumes: list[int],
    fixed: DetectedBore,
    loaded: DetectedBore,
    *,
    mesh_size_m: float,
    bore_size_m: float,
    order: int,
    mirror_plane: MirrorPlane | None = None,
    wall_reference_m: float | None = None,
) -> MeshArrays:
    """Mesh the volumes with tetrahedra of `order`; size `bore_size_m` at the bores, `mesh_size_m` away.
    With a `mirror_plane` (the volumes are a half link) the facets on that plane are returned too.
    Thin walls are refined relative to `wall_reference_m` (THIN_WALL_FRACTION; None: not refined)."""
    fixed_faces = faces_on_bore(volumes, fixed.bore)
    loaded_faces = faces_on_bore(volumes, loaded.bore)
    mirror_faces = faces_on_plane(volumes, mirror_plane) if mirror_plane is not None else None
    if mirror_plane is not None and not mirror_faces:
        raise GeometryError(f"the half link has no face on its mirror plane {mirror_plane.name}; expected the cut face")
    small_holes = small_hole_fields(volumes, (fixed, loaded), mesh_size_m)
    pin_faces, pin_radius, smaller_pin = _pin_bore_fields(fixed, fixed_faces, loaded, loaded_faces, bore_size_m)
    small_holes += smaller_pin
    if wall_reference_m is not None:
        small_holes += thin_wall_fields(volumes, mesh_size_m, wall_reference_m, mirror_faces or ())
    _refine_near(pin_faces, mesh_size_m, bore_size_m, pin_radius, small_holes)
    gmsh.option.setNumber("Mesh.Algorithm3D", 10)  # HXT: 4-6x faster than Delaunay here
    # One thread: HXT then gives the same mesh on every run (with two it did not, and it was no
    # faster on these ~40k-tet meshes).
    gmsh.option.setNumber("General.NumThreads", 1)
    # Surfaces of a half link by MeshAdapt (1), of a whole one by gmsh's default Frontal-Delaunay (6):
    # in exploratory runs on the default link's half, Frontal-Delaunay meshed the cut 1 mm pocket
    # fillets as strips of flat triangles, and 40-140 tets of radius ratio ~3e-4 followed at every
    # size from 3 to 8 mm; MeshAdapt left none below 0.1 at 3-4.5 mm (tests/test_fem_mirror.py
    # checks the default level).
    gmsh.option.setNumber("Mesh.Algorithm", 1 if mirror_plane is not None else 6)
    gmsh.model.mesh.generate(3)
    if _has_flat_tets():  # HXT can leave a sliver of zero volume: optimise, else mesh by Delaunay
        gmsh.model.mesh.optimize("")
        if _has_flat_tets():
            gmsh.model.mesh.clear()
            gmsh.option.setNumber("Mesh.Algorithm3D", 1)
            gmsh.model.mesh.generate(3)
    if order == 2:
        gmsh.model.mesh.setOrder(2)  # mid-edge nodes placed on the CAD surfaces
    return _mesh_arrays(fixed_faces, loaded_faces, order, mirror_faces)


def _has_flat_tets() -> bool:
    """Whether the linear mesh holds a numerically flat tetrahedron (gmsh's radius ratio "gamma"
    below FLAT_TET_QUALITY): the FEA refuses such a mesh (fem.quality.require_valid)."""
    tags, _ = gmsh.model.mesh.getElementsByType(_TET[1])
    return len(tags) > 0 and float(np.min(gmsh.model.mesh.getElementQualities(tags, "gamma"))) < FLAT_TET_QUALITY


def _pin_bore_fields(
    fixed: DetectedBore, fixed_faces: list[int], loaded: DetectedBore, loaded_faces: list[int], bore_size_m: float
) -> tuple[list[int], float, list[FaceRefinement]]:
    """(faces, radius) of the pin-bore refinement at `bore_size_m`, and for two unequal bores (given
    by --bores) the smaller one's own refinement, its size scaled by its radius: each bore is
    sized for itself, the larger one does not set the size at the smaller."""
    r_fixed, r_loaded = fixed.bore.radius_m, loaded.bore.radius_m
    if abs(r_fixed - r_loaded) <= UNEQUAL_BORES_TOL * max(r_fixed, r_loaded):
        return fixed_faces + loaded_faces, min(r_fixed, r_loaded), []
    (large_faces, r_large), (small_faces, r_small) = sorted(
        [(fixed_faces, r_fixed), (loaded_faces, r_loaded)], key=lambda fr: -fr[1]
    )
    return large_faces, r_large, [FaceRefinement(tuple(small_faces), 0.5 * r_small, bore_size_m * r_small / r_large)]


@dataclass(frozen=True)
class FaceRefinement:
    """Element size `size_m` within `reach_m` of some faces (a small hole's, a smaller pin bore's:
    half its radius; a thin wall's smaller face: the wall's thickness), graded to the far size."""

    faces: tuple[int, ...]
    reach_m: float
    size_m: float


def small_hole_fields(volumes: list[int], pins: Sequence[DetectedBore], size_far: float) -> list[FaceRefinement]:
    """The holes other than the pin bores that need elements finer than `size_far`
    (SMALL_HOLE_SIZE_FRACTION x their radius)."""
    refinements = []
    for hole in find_holes(volumes).full:
        size = SMALL_HOLE_SIZE_FRACTION * hole.bore.radius_m
        if size < size_far and not any(_same_axis(hole, pin) for pin in pins):
            refinements.append(FaceRefinement(hole.faces, 0.5 * hole.bore.radius_m, size))
    return refinements


def thin_wall_size(thickness_m: float, size_far: float, reference_m: float) -> float:
    """Element size in a thin wall of this thickness on a level of `size_far` whose walls are
    judged against `reference_m` (THIN_WALL_FRACTION)."""
    relative = thickness_m / reference_m
    return size_far * min(1.0, max(relative, (relative / THIN_WALL_FRACTION) ** 2))


def thin_wall_fields(
    volumes: list[int], size_far: float, reference_m: float, cut_faces: Sequence[int] = ()
) -> list[FaceRefinement]:
    """The thin walls (planar, rings round holes) thinner than THIN_WALL_FRACTION x `reference_m`,
    each refined from its smaller face (a ring's hole face): within a wall's thickness of that face lies the wall's material across from it.
    A mirror half's `cut_faces` are no wall's side (the part goes on past them)."""
    return [
        FaceRefinement(wall.faces[:1], wall.thickness_m, thin_wall_size(wall.thickness_m, size_far, reference_m))
        for wall in thin_walls(volumes, THIN_WALL_FRACTION * reference_m, exclude=cut_faces)
    ]


def _same_axis(a: DetectedBore, b: DetectedBore) -> bool:
    rel = a.bore.center_m - b.bore.center_m
    off_axis = rel - (rel @ b.bore.axis) * b.bore.axis
    return (
        abs(abs(float(a.bore.axis @ b.bore.axis)) - 1) < 1e-6
        and float(np.linalg.norm(off_axis)) < 1e-3 * b.bore.radius_m
    )


def _hole_field(hole: FaceRefinement, size_far: float) -> int:
    """Distance + Threshold: `hole.size_m` within `hole.reach_m` of the faces, growing by
    SIZE_GRADIENT per unit distance to the far size."""
    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "SurfacesList", list(hole.faces))
    field.setNumber(distance, "Sampling", DISTANCE_SAMPLING)
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", hole.size_m)
    field.setNumber(threshold, "SizeMax", size_far)
    field.setNumber(threshold, "DistMin", hole.reach_m)
    field.setNumber(threshold, "DistMax", hole.reach_m + (size_far - hole.size_m) / SIZE_GRADIENT)
    return threshold


def _refine_near(
    faces: list[int], size_far: float, size_near: float, radius: float, small_holes: Sequence[FaceRefinement] = ()
) -> None:
    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "SurfacesList", faces)
    # Points per face direction to measure distance from: 20 on a bore puts them 0.3 radii apart,
    # fine for a threshold over 0.5-2.5 radii; 60 tripled the 1D meshing time (measured).
    field.setNumber(distance, "Sampling", DISTANCE_SAMPLING)
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", size_near)
    field.setNumber(threshold, "SizeMax", size_far)
    field.setNumber(threshold, "DistMin", BORE_FIELD_INNER_RADII * radius)
    field.setNumber(threshold, "DistMax", BORE_FIELD_OUTER_RADII * radius)
    extra = [_ball(ball, size_far) for ball in _REFINEMENTS.get()] + [_hole_field(h, size_far) for h in small_holes]
    if extra:
        smallest = field.add("Min")
        field.setNumbers(smallest, "FieldsList", [threshold, *extra])
        threshold = smallest
    field.setAsBackgroundMesh(threshold)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size_far)


def _ball(ball: Refinement, size_far: float) -> int:
    """A gmsh Ball field: `ball.size_m` inside, graded to the far size over one more radius."""
    field = gmsh.model.mesh.field
    tag = field.add("Ball")
    for name, value in zip(("XCenter", "YCenter", "ZCenter"), ball.center_m):
        field.setNumber(tag, name, float(value))
    field.setNumber(tag, "Radius", ball.radius_m)
    field.setNumber(tag, "Thickness", ball.radius_m)
    field.setNumber(tag, "VIn", ball.size_m)
    field.setNumber(tag, "VOut", size_far)
    return tag


def _mesh_arrays(
    fixed_faces: list[int], loaded_faces: list[int], order: int, mirror_faces: list[int] | None = None
) -> MeshArrays:
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    _, tet_nodes = gmsh.model.mesh.getElementsByType(_TET[order])
    n_nodes_per_tet = 4 if order == 1 else 10
    tets_by_tag = np.asarray(tet_nodes, dtype=np.int64).reshape(-1, n_nodes_per_tet)
    used = np.unique(tets_by_tag)
    index_of_tag = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    index_of_tag[used] = np.arange(len(used))
    position = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    position[node_tags.astype(np.int64)] = np.arange(len(node_tags))
    points = np.asarray(coords).reshape(-1, 3)[position[used]].T
    cells = index_of_tag[tets_by_tag]
    tets10 = cells[:, _GMSH_TO_MESHIO_TET10].T.copy() if order == 2 else None
    return MeshArrays(
        points_m=np.ascontiguousarray(points),
        tets=np.ascontiguousarray(cells[:, :4].T),
        tets10=tets10,
        fixed_bore_facets=_facets(fixed_faces, index_of_tag, order),
        loaded_bore_facets=_facets(loaded_faces, index_of_tag, order),
        mirror_facets=_facets(mirror_faces, index_of_tag, order) if mirror_faces else None,
    )


def _facets(faces: list[int], index_of_tag: np.ndarray, order: int) -> np.ndarray:
    n_nodes_per_triangle = 3 if order == 1 else 6
    if not faces:  # e.g. a stress sub-model's ball that holds no bore (geometry.ball_mesh)
        return np.zeros((3, 0), dtype=np.int64)
    blocks = []
    for face in faces:
        _, nodes = gmsh.model.mesh.getElementsByType(_TRIANGLE[order], tag=face)
        blocks.append(np.asarray(nodes, dtype=np.int64).reshape(-1, n_nodes_per_triangle)[:, :3])
    return np.ascontiguousarray(index_of_tag[np.vstack(blocks)].T)
