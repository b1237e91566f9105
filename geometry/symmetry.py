"""The link's plane of mirror symmetry through both bore axes, and the half of the link on one side.

A pin-loaded link whose solid is mirror symmetric about the plane holding both bore axes has a
load case with the same symmetry (clamp on the whole fixed bore, bearing pressure symmetric about
the load direction, which lies in the plane), so its solution is symmetric too: half the link,
with the normal displacement held at zero on the plane, gives the whole link's k and stresses at
about half the unknowns (the default link's stiffness study: 4.90 to 3.20 s with its finest level
on the half, `benchmarks/bench_fea_time_to_k.py`).

Symmetry is accepted only where it is checked, and only for a plane normal to a coordinate axis
(so that the condition on the plane is one displacement component held): every face and every
edge of the solid must have a mirror image of the same area or length with its centroid at the
mirror image of the centroid, and the solid's centroid must lie on the plane. That rejects a
screw hole, a flat or a chamfer on one side only, at the cost of a few OpenCASCADE property queries
(an OpenCASCADE boolean of the solid with its mirror image would be exact, but took 0.8 s on the
default link in an exploratory run).
"""

from __future__ import annotations

import gmsh
import numpy as np

from geometry.bores import boundary_edges, boundary_faces
from geometry.link_mesh import Bore, MirrorPlane

#: Centroids, areas and lengths must match their mirror images to this fraction of the part's size
#: (OpenCASCADE's geometry is exact to ~1e-7 m on parts of ~0.1 m).
MATCH_TOLERANCE = 1e-6
#: Bounds OpenCASCADE's padding of bounding boxes (its 1e-7 tolerance, in metres here).
BOX_PADDING_M = 1e-6
#: The plane's normal must be a coordinate axis to this tolerance (cosine) to be used.
AXIS_TOLERANCE = 1e-9


def bore_plane(fixed: Bore, loaded: Bore) -> MirrorPlane | None:
    """The plane through both (parallel) bore axes, if its normal is a coordinate axis; else None."""
    axis = np.asarray(fixed.axis, float) / np.linalg.norm(fixed.axis)
    if np.linalg.norm(np.cross(axis, loaded.axis)) > AXIS_TOLERANCE * np.linalg.norm(loaded.axis):
        return None
    across = loaded.center_m - fixed.center_m
    normal = np.cross(axis, across - (across @ axis) * axis)
    if not np.linalg.norm(normal) > 0:
        return None
    normal /= np.linalg.norm(normal)
    index = int(np.argmax(np.abs(normal)))
    if abs(normal[index]) < 1 - AXIS_TOLERANCE:
        return None
    return MirrorPlane(offset_m=float(fixed.center_m[index]), axis=index)


def symmetry_plane(volumes: list[int], fixed: Bore, loaded: Bore) -> MirrorPlane | None:
    """The plane through both bore axes if the solid is mirror symmetric about it, else None."""
    plane = bore_plane(fixed, loaded)
    return plane if plane is not None and is_mirror_symmetric(volumes, plane) else None


def _model_size_m() -> float:
    """The diagonal of the current model's bounding box."""
    xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(-1, -1)
    return float(np.linalg.norm([xmax - xmin, ymax - ymin, zmax - zmin]))


def is_mirror_symmetric(volumes: list[int], plane: MirrorPlane) -> bool:
    """Every face and edge of the solid has its mirror image, and the centroid lies on the plane."""
    occ = gmsh.model.occ
    tolerance = MATCH_TOLERANCE * _model_size_m()
    volume = sum(occ.getMass(3, v) for v in volumes)
    centroid = sum(np.array(occ.getCenterOfMass(3, v)) * occ.getMass(3, v) for v in volumes) / volume
    if abs(plane.distance_m(centroid)) > tolerance:
        return False
    return _entities_mirrored(2, boundary_faces(volumes), plane, tolerance) and _entities_mirrored(
        1, boundary_edges(volumes), plane, tolerance
    )


def _entities_mirrored(dim: int, tags: list[int], plane: MirrorPlane, distance_tol: float) -> bool:
    """Each entity has one of the same size (area, length) whose centroid is its centroid's image."""
    occ = gmsh.model.occ
    centroids = np.array([occ.getCenterOfMass(dim, t) for t in tags]).T  # (3, n)
    sizes = np.array([occ.getMass(dim, t) for t in tags])
    gap = np.linalg.norm(plane.reflect(centroids)[:, :, None] - centroids[:, None, :], axis=0)  # (image, entity)
    same_size = np.abs(sizes[:, None] - sizes[None, :]) <= MATCH_TOLERANCE * np.maximum(sizes[:, None], sizes[None, :])
    return bool(((gap <= distance_tol) & same_size).any(axis=1).all())


def keep_positive_half(volumes: list[int], plane: MirrorPlane) -> list[int]:
    """Replace the solid by its part on the positive side of the plane; the new volume tags."""
    occ = gmsh.model.occ
    xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(-1, -1)
    pad = 0.01 * _model_size_m()
    low, high = np.array([xmin, ymin, zmin]) - pad, np.array([xmax, ymax, zmax]) + pad
    low[plane.axis] = plane.offset_m
    box = occ.addBox(*low, *(high - low))
    pieces, _ = occ.intersect([(3, v) for v in volumes], [(3, box)])
    occ.synchronize()
    return sorted(tag for dim, tag in pieces if dim == 3)


def faces_on_plane(volumes: list[int], plane: MirrorPlane) -> list[int]:
    """Boundary faces of the solid lying in the plane."""
    # OpenCASCADE pads bounding boxes by its tolerance (1e-7 model units, here metres)
    tolerance = MATCH_TOLERANCE * _model_size_m() + BOX_PADDING_M
    found = []
    for tag in boundary_faces(volumes):
        box = np.array(gmsh.model.getBoundingBox(2, tag))
        if (
            abs(box[plane.axis] - plane.offset_m) <= tolerance
            and abs(box[3 + plane.axis] - plane.offset_m) <= tolerance
        ):
            found.append(tag)
    return found
