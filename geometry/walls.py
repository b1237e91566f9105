"""Thin walls of a solid, found on its CAD faces: two parallel planar faces facing each other across
the material a small distance apart (the sides of a channel's web, a pocket's floor over the far
face, a flange).

For each pair of planar faces whose outward normals are opposite, each lying behind the other
(material between them, not a gap between two lugs), and whose planes are closer than the largest
thickness asked for, the smaller face is sampled on a grid of its parameters; a sample counts if
its foot on the other face's plane lies on that face (gmsh's `isInside` on the trimmed face). The
wall is the pair, its thickness the planes' distance and its area the smaller face's area times
the fraction of samples that count. Each face's outward side is found once, by asking whether a
point just off its centre along gmsh's normal is inside the solid.

Curved walls, a tube or the ring of material between a hole and the round outside it (a lug's end
round a bore): a concave cylindrical face (a hole's, geometry.bores) inside a convex one whose axis
is parallel and whose radius is larger. The hole's face is sampled as above; a sample counts where
the convex face lies radially out from it (about the convex face's axis, away from the hole's axis:
the material side) and its foot there lies on that trimmed face; the wall's thickness is the least
radial distance among the samples that count (the thinnest point, where an off-centre hole comes
nearest the round), its area the hole face's area times their fraction. Walls between two holes, or
between a hole and a planar face, are not found.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import gmsh
import numpy as np

from geometry.bores import Cylinder, face_cylinder

# Normals within ~2.6 degrees of parallel: CAD walls are drawn parallel, to round-off.
_PARALLEL_COS = 0.999
_SAMPLES = 9  # per parameter direction on the smaller face (81 points)
# A pair is a wall where at least this fraction of the smaller face's samples lie across the
# material from the other face (a few samples at a corner are not a wall).
_MIN_OVERLAP = 0.25
# A ring wall's foot lies on the convex face where its closest point on the face is within this
# fraction of the radius (round-off of the projection).
_ON_FACE_TOL = 1e-6
# The point probing a face's outward side lies this fraction of the face's size off its centre.
_PROBE_FRACTION = 1e-4


@dataclass(frozen=True)
class Wall:
    """Two faces a thickness apart across the material (metres, m^2): planar, or a hole's face and
    a convex round outside it."""

    faces: tuple[int, int]  # the smaller face (a ring's hole face) first: its size field covers the wall
    thickness_m: float
    area_m2: float  # of the smaller face that lies across the wall from the other


@dataclass(frozen=True)
class _Plane:
    tag: int
    point: np.ndarray
    normal: np.ndarray  # outward
    area_m2: float
    box: np.ndarray  # (2, 3) min, max
    samples: np.ndarray  # (n, 3) points on the trimmed face


def thin_walls(volumes: list[int], max_thickness_m: float, exclude: Sequence[int] = ()) -> list[Wall]:
    """The walls of the solid (`volumes` in the current gmsh model) thinner than `max_thickness_m`;
    faces in `exclude` (a mirror half's cut face: the wall goes on past it) are not wall faces."""
    faces = [tag for tag in _boundary_faces(volumes) if tag not in set(exclude)]
    bounds = {tag: _plane_bounds(tag) for tag in faces if gmsh.model.getType(2, tag) == "Plane"}
    planes: dict[int, _Plane] = {}  # sampled and oriented only where a pair may be a wall (isInside is slow)
    walls = []
    tags = list(bounds)
    for i, a in enumerate(tags):
        for b in tags[i + 1 :]:
            if not _may_be_wall(bounds[a], bounds[b], max_thickness_m):
                continue
            for tag in (a, b):
                if tag not in planes:
                    planes[tag] = _plane(tag, volumes)
            wall = _wall(planes[a], planes[b], max_thickness_m)
            if wall is not None:
                walls.append(wall)
    rounds = [r for r in (_round(tag) for tag in faces if gmsh.model.getType(2, tag) != "Plane") if r is not None]
    holes = [r for r in rounds if r.concave]
    for outer in (r for r in rounds if not r.concave):
        for hole in holes:
            wall = _ring_wall(hole, outer, max_thickness_m)
            if wall is not None:
                walls.append(wall)
    return walls


def _boundary_faces(volumes: list[int]) -> list[int]:
    faces = gmsh.model.getBoundary([(3, v) for v in volumes], combined=False, oriented=False)
    return sorted({tag for _, tag in faces})


@dataclass(frozen=True)
class _PlaneBounds:
    point: np.ndarray  # on the face's plane
    normal: np.ndarray  # unit, either side
    box: np.ndarray  # (2, 3) min, max


def _plane_bounds(tag: int) -> _PlaneBounds:
    (umin, vmin), (umax, vmax) = gmsh.model.getParametrizationBounds(2, tag)
    middle = [0.5 * (umin + umax), 0.5 * (vmin + vmax)]
    normal = np.asarray(gmsh.model.getNormal(tag, middle))
    box = np.asarray(gmsh.model.getBoundingBox(2, tag)).reshape(2, 3)
    return _PlaneBounds(np.asarray(gmsh.model.getValue(2, tag, middle)), normal / np.linalg.norm(normal), box)


def _may_be_wall(a: _PlaneBounds, b: _PlaneBounds, max_thickness_m: float) -> bool:
    """Whether two planar faces can be a wall's sides, whatever their outward sides: parallel,
    their planes closer than `max_thickness_m`, their boxes that near."""
    gap = abs(float((b.point - a.point) @ a.normal))
    return (
        abs(float(a.normal @ b.normal)) >= _PARALLEL_COS
        and gap < max_thickness_m
        and not (np.any(a.box[0] > b.box[1] + gap) or np.any(b.box[0] > a.box[1] + gap))
    )


def _plane(tag: int, volumes: list[int]) -> _Plane:
    points = _samples(tag)
    (umin, vmin), (umax, vmax) = gmsh.model.getParametrizationBounds(2, tag)
    normal = np.asarray(gmsh.model.getNormal(tag, [0.5 * (umin + umax), 0.5 * (vmin + vmax)]))
    normal /= np.linalg.norm(normal)
    area = float(gmsh.model.occ.getMass(2, tag))
    point = points[len(points) // 2] if len(points) else np.asarray(gmsh.model.getValue(2, tag, [umin, vmin]))
    probe = point + _PROBE_FRACTION * np.sqrt(area) * normal
    if any(gmsh.model.isInside(3, v, list(probe)) > 0 for v in volumes):
        normal = -normal  # gmsh's normal pointed into the material
    box = np.asarray(gmsh.model.getBoundingBox(2, tag)).reshape(2, 3)
    return _Plane(tag, point, normal, area, box, points)


@dataclass(frozen=True)
class _Round:
    tag: int
    cylinder: Cylinder
    concave: bool  # a hole's face: the material outside the radius
    box: np.ndarray  # (2, 3) min, max


def _round(tag: int) -> _Round | None:
    found = face_cylinder(tag)
    if found is None:
        return None
    box = np.asarray(gmsh.model.getBoundingBox(2, tag)).reshape(2, 3)
    return _Round(tag, found[0], found[1], box)


def _ring_wall(hole: _Round, outer: _Round, max_thickness_m: float) -> Wall | None:
    """The wall between a hole's face and a convex face round it (parallel axes), or None."""
    a, b = hole.cylinder, outer.cylinder
    if abs(float(a.axis @ b.axis)) < _PARALLEL_COS or a.radius_m >= b.radius_m:
        return None
    offset = float(b.distance_to_axis(a.point_m[None])[0])
    if not 0 < b.radius_m - a.radius_m - offset < max_thickness_m:  # the hole inside the round, near it
        return None
    if np.any(hole.box[0] > outer.box[1]) or np.any(outer.box[0] > hole.box[1]):
        return None
    points = _samples(hole.tag)
    if len(points) == 0:
        return None
    rel = points - b.point_m
    along = rel @ b.axis
    radial = rel - np.outer(along, b.axis)
    rho = np.linalg.norm(radial, axis=1)
    out_of_hole = points - a.point_m
    out_of_hole -= np.outer(out_of_hole @ a.axis, a.axis)
    material_side = np.sum(radial * out_of_hole, axis=1) > 0
    keep = material_side & (rho > 0)
    if not np.any(keep):
        return None
    feet = b.point_m + np.outer(along[keep], b.axis) + radial[keep] * (b.radius_m / rho[keep])[:, None]
    # gmsh's isInside(2, ...) on a cylinder's point is not trimmed (every point on its cylinder
    # counted, measured); its closest point on the face is: a foot on the face is its own
    on_face = np.asarray(
        [
            np.linalg.norm(gmsh.model.getClosestPoint(2, outer.tag, list(foot))[0] - foot) < _ON_FACE_TOL * b.radius_m
            for foot in feet
        ],
        bool,
    )
    fraction = np.count_nonzero(on_face) / len(points)
    if fraction < _MIN_OVERLAP:
        return None
    thickness = float(np.min(b.radius_m - rho[keep][on_face]))
    if not 0 < thickness < max_thickness_m:
        return None
    return Wall((hole.tag, outer.tag), thickness, fraction * float(gmsh.model.occ.getMass(2, hole.tag)))


def _wall(a: _Plane, b: _Plane, max_thickness_m: float) -> Wall | None:
    if float(a.normal @ b.normal) > -_PARALLEL_COS:
        return None
    thickness = -float((b.point - a.point) @ a.normal)  # b behind a: material between them
    if not 0 < thickness < max_thickness_m:
        return None
    if np.any(a.box[0] > b.box[1] + thickness) or np.any(b.box[0] > a.box[1] + thickness):
        return None
    small, large = (a, b) if a.area_m2 <= b.area_m2 else (b, a)
    points = small.samples
    if len(points) == 0:
        return None
    feet = points - ((points - large.point) @ large.normal)[:, None] * large.normal
    fraction = gmsh.model.isInside(2, large.tag, feet.ravel().tolist()) / len(points)
    if fraction < _MIN_OVERLAP:
        return None
    return Wall((small.tag, large.tag), thickness, fraction * small.area_m2)


def _samples(tag: int) -> np.ndarray:
    """Points on the trimmed face on a grid of its parameters (inset from the bounds)."""
    (umin, vmin), (umax, vmax) = gmsh.model.getParametrizationBounds(2, tag)
    t = (np.arange(_SAMPLES) + 0.5) / _SAMPLES
    u, v = np.meshgrid(umin + t * (umax - umin), vmin + t * (vmax - vmin))
    uv = np.column_stack([u.ravel(), v.ravel()]).ravel().tolist()
    points = np.asarray(gmsh.model.getValue(2, tag, uv)).reshape(-1, 3)
    inside = [gmsh.model.isInside(2, tag, list(uv[2 * k : 2 * k + 2]), parametric=True) > 0 for k in range(len(points))]
    return points[np.asarray(inside, bool)]
