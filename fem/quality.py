"""Shape quality of a tetrahedral mesh: the radius ratio of each tet, and what the FEA makes of it.

Radius ratio q = 3 r_in / r_circ (inscribed over circumscribed sphere radius, scaled so that the
regular tetrahedron has q = 1); it tends to 0 for every kind of degenerate tet (slivers with four
nearly coplanar vertices, needles, caps), unlike the edge-length ratio, which misses slivers
(four well-spaced vertices near one plane). It is gmsh's default quality measure ("gamma"), so numbers are comparable
with gmsh's own reports. It ignores vertex order: scikit-fem accepts tets of either orientation
(its own structured meshes mix them), so a sign says nothing about tangling here.

What the tool does with it:
- q below DEGENERATE_QUALITY anywhere (a numerically flat tet): the stiffness matrix is singular
  or dominated by round-off, so `require_valid` raises FemError;
- min q below POOR_QUALITY_THRESHOLD: `quality_warning` gives a one-line warning. Elasticity on a
  few slivers still passes the patch test (a linear field is reproduced whatever the shape), but
  the element's condition number grows like 1/q^2, stresses there are unreliable and iterative
  solvers (AMG-CG) are the first to fail.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from geometry.link_mesh import part_size_m

from .errors import FemError

# gmsh's optimised HXT meshes of the sharp-cornered default link had min q of 0.21-0.33 (measured
# at 3.8-12 mm elements); the filleted one has 0.18 / 0.14 at 4.5 / 6 mm, but 0.08 at 12 mm, where
# the elements meet its 1 mm pocket-floor fillet (so coarse meshes of it warn); moving one vertex of a good mesh to a tenth of its distance from the centroid of the
# opposite face gives q = 0.05. 0.1 separates the two with a margin on both sides.
POOR_QUALITY_THRESHOLD = 0.1
# Measured on a bar whose exact solution is linear (tests/test_fea_failure_slivers.py): with one
# tet flattened to q = 5e-14 PARDISO and SuperLU still reproduce EA/L to 1e-12, AMG-CG stops
# converging below q ~ 5e-13, and an exactly flat tet makes PARDISO fail with a zero pivot.
DEGENERATE_QUALITY = 1e-12
QUALITY_WARNING_PREFIX = "mesh quality"


@dataclass(frozen=True)
class MeshQuality:
    """Radius-ratio summary of a mesh (1 = regular tetrahedron, 0 = flat)."""

    worst: float  # minimum radius ratio over all tets
    worst_tet: int  # index (column of `tets`) of the worst tet
    threshold: float
    below_threshold: int  # number of tets with q < threshold
    degenerate: int  # number of numerically flat tets (q < DEGENERATE_QUALITY)
    n_tets: int


def radius_ratios(points_m: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """q = 3 r_in / r_circ per tet, in [0, 1] (see the module doc)."""
    points_m = np.asarray(points_m, dtype=float)
    tets = np.asarray(tets)
    if points_m.ndim != 2 or points_m.shape[0] != 3:
        raise FemError(f"points_m: expected shape (3, n_points), got {points_m.shape}")
    if tets.ndim != 2 or tets.shape[0] < 4 or tets.shape[1] == 0:
        raise FemError(f"tets: expected shape (4, n_tets) with n_tets > 0, got {tets.shape}")
    a, b, c, d = (points_m[:, tets[i]].T for i in range(4))
    u, v, w = b - a, c - a, d - a
    vxw, wxu, uxv = np.cross(v, w), np.cross(w, u), np.cross(u, v)
    six_volume = np.einsum("ij,ij->i", u, vxw)
    # Circumcentre offset from a: (|u|^2 v x w + |v|^2 w x u + |w|^2 u x v) / (2 u . v x w).
    numerator = (
        np.einsum("ij,ij->i", u, u)[:, None] * vxw
        + np.einsum("ij,ij->i", v, v)[:, None] * wxu
        + np.einsum("ij,ij->i", w, w)[:, None] * uxv
    )
    twice_area_sum = (
        np.linalg.norm(uxv, axis=1)
        + np.linalg.norm(vxw, axis=1)
        + np.linalg.norm(wxu, axis=1)
        + np.linalg.norm(np.cross(c - b, d - b), axis=1)
    )
    # r_in = 3 V / S = six_volume / (2 S) = six_volume / twice_area_sum;
    # r_circ = |numerator| / |2 six_volume|, so q = 6 six_volume^2 / (twice_area_sum |numerator|).
    with np.errstate(divide="ignore", invalid="ignore"):
        q = 6.0 * six_volume**2 / (twice_area_sum * np.linalg.norm(numerator, axis=1))
    return np.where(np.isfinite(q), q, 0.0)


def mesh_quality(points_m: np.ndarray, tets: np.ndarray, threshold: float = POOR_QUALITY_THRESHOLD) -> MeshQuality:
    """Worst radius ratio and the number of tets below `threshold` (vertices of `tets` only)."""
    if not 0 < threshold < 1:
        raise FemError(f"threshold={threshold!r}: expected a radius ratio in (0, 1)")
    q = radius_ratios(points_m, tets)
    worst = int(np.argmin(q))
    return MeshQuality(
        worst=float(q[worst]),
        worst_tet=worst,
        threshold=float(threshold),
        below_threshold=int(np.count_nonzero(q < threshold)),
        degenerate=int(np.count_nonzero(q < DEGENERATE_QUALITY)),
        n_tets=int(q.size),
    )


def link_quality(link, threshold: float = POOR_QUALITY_THRESHOLD) -> MeshQuality:
    """`mesh_quality` of a geometry.LinkMesh (its straight-sided tets)."""
    return mesh_quality(link.points_m, link.tets, threshold)


def require_valid(quality: MeshQuality) -> None:
    """FemError if any tet is numerically flat (q < DEGENERATE_QUALITY): no FE answer is meaningful then."""
    if quality.degenerate:
        raise FemError(
            f"mesh: {quality.degenerate} of {quality.n_tets} tetrahedra are flat (radius ratio below "
            f"{DEGENERATE_QUALITY:g}, worst {quality.worst:.2g} at tet {quality.worst_tet}); expected a valid mesh"
        )


def quality_warning(quality: MeshQuality) -> str | None:
    """One-line warning when some tets are below the threshold, else None."""
    if quality.below_threshold == 0:
        return None
    return (
        f"{QUALITY_WARNING_PREFIX}: {quality.below_threshold} of {quality.n_tets} tetrahedra have radius ratio below "
        f"{quality.threshold:g} (worst {quality.worst:.3g} at tet {quality.worst_tet}); stresses there are "
        f"unreliable, consider remeshing"
    )


# A wall counts if it covers at least this fraction of the part's surface (a few facets at a
# chamfer or a fillet's foot are not a wall); it is "thinner than the elements" below this
# fraction of the element size: a P2 element then has no node inside the wall's thickness.
WALL_AREA_FRACTION = 0.01
THIN_WALL_ELEMENT_FRACTION = 0.5
# the mesh measures a wall's thickness from its boundary facets' centroids, within a few percent of
# the CAD's (the built-in link's rails: 2.54 against 2.535 mm)
REFINED_WALL_MATCH = 0.95
# Facets count as the two sides of one wall when their outward normals are within ~25 degrees of
# opposite and one lies across the material from the other.
OPPOSITE_NORMALS_COS = -0.9


def boundary_facets(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary triangles (3, n) of a tet mesh (4, m), with the vertex opposite each one (n,)."""
    faces = np.hstack([tets[[1, 2, 3]], tets[[0, 2, 3]], tets[[0, 1, 3]], tets[[0, 1, 2]]])
    opposite = np.concatenate([tets[0], tets[1], tets[2], tets[3]])
    _, index, counts = np.unique(np.sort(faces, axis=0), axis=1, return_index=True, return_counts=True)
    once = index[counts == 1]
    return faces[:, once], opposite[once]


def thinnest_wall_m(points_m: np.ndarray, tets: np.ndarray, search_radius_m: float, mirror_plane=None) -> float:
    """Thickness of the thinnest wall (m) covering >= WALL_AREA_FRACTION of the surface; inf if
    no wall is thinner than `search_radius_m`.

    The local thickness at a boundary facet is the distance, along its inward normal, to the
    nearest facet facing the other way across the material (within search_radius_m). On the half
    of a mirrored link (`mirror_plane`, a geometry.link_mesh.MirrorPlane) a wall that ends on the
    plane goes on in the other half: it is twice as thick as seen from the half.
    """
    from scipy.spatial import cKDTree

    tri, opposite = boundary_facets(np.asarray(tets))
    a, b, c = (points_m[:, tri[i]].T for i in range(3))
    normal = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(normal, axis=1)
    normal /= 2 * area[:, None]
    centroid = (a + b + c) / 3
    outward = np.sign(np.einsum("ij,ij->i", normal, centroid - points_m[:, opposite].T))
    normal *= outward[:, None]
    pairs = cKDTree(centroid).query_pairs(search_radius_m, output_type="ndarray")
    i, j = np.concatenate([pairs[:, 0], pairs[:, 1]]), np.concatenate([pairs[:, 1], pairs[:, 0]])
    facing = np.einsum("ij,ij->i", normal[i], normal[j]) < OPPOSITE_NORMALS_COS
    i, j = i[facing], j[facing]
    offset = centroid[j] - centroid[i]
    depth = -np.einsum("ij,ij->i", offset, normal[i])
    if mirror_plane is not None:
        on_plane = mirror_plane.on_plane(points_m[:, tri], part_size_m(points_m)).all(axis=0)
        depth = np.where(on_plane[i] | on_plane[j], 2 * depth, depth)
    lateral = np.linalg.norm(offset + depth[:, None] * normal[i], axis=1)
    across = (depth > 0) & (lateral < np.maximum(depth, np.sqrt(area[i])))
    thickness = np.full(len(area), np.inf)
    np.minimum.at(thickness, i[across], depth[across])
    order = np.argsort(thickness)
    covered = np.cumsum(area[order]) / area.sum()
    k = int(np.searchsorted(covered, WALL_AREA_FRACTION))
    return float(thickness[order[min(k, len(order) - 1)]])


def thin_wall_warning(link, refined_down_to_m: float = math.inf) -> str | None:
    """One-line warning when a wall of the link (a geometry.LinkMesh) is thinner than its elements.
    `refined_down_to_m`: the thinnest wall the mesh's size fields refined (geometry.meshing: one
    element through its thickness): a wall the mesh finds at that thickness or above is that wall
    (or a thicker one), meshed finely enough."""
    size = float(link.mesh_size_m)
    wall = thinnest_wall_m(
        link.points_m, link.tets, search_radius_m=THIN_WALL_ELEMENT_FRACTION * size, mirror_plane=link.mirror_plane
    )
    if not wall < THIN_WALL_ELEMENT_FRACTION * size or wall >= REFINED_WALL_MATCH * refined_down_to_m:
        return None
    return (
        f"mesh: a wall about {wall * 1e3:.3g} mm thick is thinner than half the {size * 1e3:.3g} mm elements; "
        f"k and stresses in it are unreliable, pass a smaller mesh size (--mesh-size)"
    )
