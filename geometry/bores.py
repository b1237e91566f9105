"""Find the holes of a solid (concave cylindrical surfaces) among which the pin bores are chosen.

A hole may be one cylinder face or several (exporters split bores into halves), analytic or
B-spline; chamfers (cones), fillets (tori) and the rounded lug ends around it (convex cylinders on
the same axis) are not part of it. Each boundary face is sampled on a grid of its parameters; a
face is a cylinder candidate if gmsh types it 'Cylinder' or if a cylinder fits its sample points
and normals. Candidates on one axis with one radius are grouped; a group is a hole if the material
lies outside the radius (the face's outward normals point to the axis: not a boss). A hole whose faces go all the way round the axis is full (a
bore, a screw hole, a counterbore); one that reaches half way round or more is open (a half bore);
less is a concave fillet and not a hole. Which two full holes carry the pins: geometry.pin_pair.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gmsh
import numpy as np

from geometry.errors import GeometryError
from geometry.link_mesh import Bore

_ANGULAR_BINS = 12  # a bore's faces must reach every 30 degree sector around the axis
_SAMPLES_EDGE = 17  # points per edge for the part's outline (a quarter arc sampled every 5.6 degrees)
_SAMPLES_U, _SAMPLES_V = 48, 5  # u samples closer than one sector even on a half-cylinder face
_FIT_TOL = 1e-4  # relative radius scatter of a fitted cylinder (B-spline bores fit to ~1e-15)
_SAME_BORE_TOL = 1e-3  # relative: two faces on one bore share axis and radius to this
# Concave cylinders reaching at least this many sectors but not all are open bores (a half bore
# reaches 6 or 7); concave fillets span a quarter turn (3 or 4 sectors) and are left out.
_OPEN_BORE_SECTORS = 6
# Face types that are never cylinders: skipped without sampling, which keeps the search fast on
# parts of thousands of faces.
_NOT_CYLINDERS = frozenset({"Plane", "Cone", "Torus", "Sphere"})


@dataclass(frozen=True)
class BoreOverride:
    """Bores given by hand for parts where detection fails or is ambiguous (metres).

    fixed_axis_point_m and loaded_axis_point_m are points on the axes of the fixed and the loaded
    bore, `axis` their common direction, `radius_m` their radius. The bore surfaces are the faces of
    the solid that lie on these cylinders.
    """

    fixed_axis_point_m: tuple[float, float, float]
    loaded_axis_point_m: tuple[float, float, float]
    axis: tuple[float, float, float]
    radius_m: float

    def __post_init__(self) -> None:
        vectors = (self.fixed_axis_point_m, self.loaded_axis_point_m, self.axis)
        if any(np.shape(v) != (3,) or not np.all(np.isfinite(v)) for v in vectors):
            raise GeometryError(f"{self}: expected finite 3-vectors for the axis points and the axis")
        if not (math.isfinite(self.radius_m) and self.radius_m > 0):
            raise GeometryError(f"BoreOverride.radius_m={self.radius_m!r}: expected a positive radius in metres")
        axis = _unit(np.asarray(self.axis, float), "BoreOverride.axis")
        offset = np.subtract(self.loaded_axis_point_m, self.fixed_axis_point_m)
        if np.linalg.norm(offset - np.dot(offset, axis) * axis) <= 2 * self.radius_m:
            raise GeometryError(f"{self}: expected the two bore axes more than two radii apart")


@dataclass(frozen=True)
class Cylinder:
    point_m: np.ndarray  # (3,) a point on the axis
    axis: np.ndarray  # (3,) unit vector
    radius_m: float

    def distance_to_axis(self, points: np.ndarray) -> np.ndarray:
        rel = points - self.point_m
        return np.linalg.norm(rel - np.outer(rel @ self.axis, self.axis), axis=1)

    def same_as(self, other: Cylinder, tol: float = _SAME_BORE_TOL) -> bool:
        return (
            abs(abs(float(self.axis @ other.axis)) - 1) < tol**2
            and abs(self.radius_m - other.radius_m) < tol * self.radius_m
            and float(self.distance_to_axis(other.point_m[None])[0]) < tol * self.radius_m
        )


@dataclass(frozen=True)
class DetectedBore:
    bore: Bore
    faces: tuple[int, ...]  # gmsh surface tags of the bore's cylindrical surface


@dataclass(frozen=True)
class Holes:
    """The concave cylinders of a solid: full round holes, and open ones (a half bore, a slot end),
    with points on the solid's edges (how far the part reaches in any direction)."""

    full: tuple[DetectedBore, ...]
    open: tuple[tuple[DetectedBore, float], ...]  # (hole, the angle its faces span around the axis, degrees)
    outline_m: np.ndarray  # (n, 3) points along every edge of the solid

    def reach_m(self, direction: np.ndarray) -> tuple[float, float]:
        """The part's extent along a unit direction: (min, max) of the outline's projections."""
        s = self.outline_m @ direction
        return float(s.min()), float(s.max())


def find_holes(volumes: list[int]) -> Holes:
    """Every concave cylinder of the solid, grouped by axis and radius (one entry per radius and axis)."""
    groups: list[tuple[Cylinder, list[int], list[np.ndarray]]] = []
    for face in boundary_faces(volumes):
        if gmsh.model.getType(2, face) in _NOT_CYLINDERS:
            continue
        points, normals = _face_samples(face)
        cylinder = _analytic_cylinder(face) or fit_cylinder(points, normals)
        if cylinder is None or not _concave(cylinder, points, normals):
            continue
        for group_cylinder, faces, samples in groups:
            if group_cylinder.same_as(cylinder):
                faces.append(face)
                samples.append(points)
                break
        else:
            groups.append((cylinder, [face], [points]))
    full, open_ = [], []
    for cylinder, faces, samples in groups:
        points = np.vstack(samples)
        sectors = _sectors_reached(cylinder, points)
        if sectors < _OPEN_BORE_SECTORS:
            continue
        hole = DetectedBore(_bore_from_samples(cylinder, points), tuple(faces))
        if sectors == _ANGULAR_BINS:
            full.append(hole)
        else:
            open_.append((hole, _span_deg(cylinder, points)))
    return Holes(tuple(full), tuple(open_), _edge_samples(volumes))


def bores_from_override(volumes: list[int], override: BoreOverride, source: str) -> tuple[DetectedBore, DetectedBore]:
    """The two bores given by `override`, with their faces and extent taken from the solid."""
    axis = _canonical(_unit(np.asarray(override.axis, float), "BoreOverride.axis"))
    found = []
    for name, point in (("fixed", override.fixed_axis_point_m), ("loaded", override.loaded_axis_point_m)):
        cylinder = Cylinder(np.asarray(point, float), axis, float(override.radius_m))
        faces, samples = faces_on_cylinder(volumes, cylinder)
        if not faces:
            raise GeometryError(
                f"{source}: no face lies on the {name} bore of {override}; expected the bore surface there"
            )
        found.append(DetectedBore(_bore_from_samples(cylinder, np.vstack(samples)), tuple(faces)))
    return found[0], found[1]


def order_pair(a: DetectedBore, b: DetectedBore, source: str) -> tuple[DetectedBore, DetectedBore]:
    """(fixed, loaded): the fixed bore has the lower coordinate along the pitch line's main axis."""
    if abs(abs(float(a.bore.axis @ b.bore.axis)) - 1) > _SAME_BORE_TOL**2:
        raise GeometryError(
            f"{source}: the two pin bores are not parallel (axes {a.bore.axis}, {b.bore.axis}); expected parallel pins"
        )
    offset = b.bore.center_m - a.bore.center_m
    offset = offset - (offset @ a.bore.axis) * a.bore.axis
    main = int(np.argmax(np.abs(offset)))
    return (a, b) if offset[main] > 0 else (b, a)


def faces_on_bore(volumes: list[int], bore: Bore) -> list[int]:
    """Surface tags of the solid's faces lying on the bore's cylinder, within its length."""
    faces, _ = faces_on_cylinder(volumes, Cylinder(bore.center_m, bore.axis, bore.radius_m), bore)
    return faces


def faces_on_cylinder(
    volumes: list[int], cylinder: Cylinder, within: Bore | None = None
) -> tuple[list[int], list[np.ndarray]]:
    faces, samples = [], []
    tol = _SAME_BORE_TOL * cylinder.radius_m
    for face in boundary_faces(volumes):
        points, _ = _face_samples(face)
        if np.max(np.abs(cylinder.distance_to_axis(points) - cylinder.radius_m)) > tol:
            continue
        if within is not None:
            along = (points - within.center_m) @ within.axis
            if np.max(np.abs(along)) > within.length_m / 2 + tol:
                continue
        faces.append(face)
        samples.append(points)
    return faces, samples


def face_cylinder(face: int) -> tuple[Cylinder, bool] | None:
    """The cylinder a face lies on (analytic or fitted to its samples) and whether the face is
    concave (a hole's: the material outside the radius), or None for a face on no cylinder."""
    if gmsh.model.getType(2, face) in _NOT_CYLINDERS:
        return None
    points, normals = _face_samples(face)
    cylinder = _analytic_cylinder(face) or fit_cylinder(points, normals)
    return None if cylinder is None else (cylinder, _concave(cylinder, points, normals))


def fit_cylinder(points: np.ndarray, normals: np.ndarray) -> Cylinder | None:
    """The cylinder through sampled surface points with these normals, or None if none fits.

    A cylinder's normals are all perpendicular to its axis, so the axis is the direction the normals
    do not span; the points projected along it then lie on a circle.
    """
    _, s, vt = np.linalg.svd(normals, full_matrices=False)
    if s[1] < 1e-3 * s[0] or s[2] > 1e-3 * s[0]:  # planar (normals span a line) or doubly curved
        return None
    axis = vt[2]
    basis = np.linalg.svd(np.eye(3) - np.outer(axis, axis))[0][:, :2]
    xy = points @ basis
    # Kasa fit: x^2 + y^2 = 2 a x + 2 b y + c, linear least squares in (a, b, c).
    design = np.column_stack([2 * xy, np.ones(len(xy))])
    (a, b, c), *_ = np.linalg.lstsq(design, (xy**2).sum(axis=1), rcond=None)
    radius_sq = c + a * a + b * b
    if radius_sq <= 0:
        return None
    radius = math.sqrt(radius_sq)
    distances = np.linalg.norm(xy - [a, b], axis=1)
    if np.max(np.abs(distances - radius)) > _FIT_TOL * radius:
        return None
    centre = basis @ np.array([a, b])
    return Cylinder(centre, _canonical(axis), radius)


def _analytic_cylinder(face: int) -> Cylinder | None:
    if gmsh.model.getType(2, face) != "Cylinder":
        return None
    _, reals = gmsh.model.getEntityProperties(2, face)
    return Cylinder(
        np.array(reals[:3]), _canonical(_unit(np.array(reals[3:6]), f"surface {face} axis")), float(reals[6])
    )


def boundary_faces(volumes: list[int]) -> list[int]:
    """Surface tags of the solid's boundary (faces shared by two of its volumes left out)."""
    faces = gmsh.model.getBoundary([(3, v) for v in volumes], combined=True, oriented=False, recursive=False)
    return sorted({abs(tag) for _, tag in faces})


def boundary_edges(volumes: list[int]) -> list[int]:
    """Curve tags of the edges of the solid's boundary faces."""
    edges = gmsh.model.getBoundary([(2, f) for f in boundary_faces(volumes)], combined=False, oriented=False)
    return sorted({abs(tag) for _, tag in edges})


def _edge_samples(volumes: list[int]) -> np.ndarray:
    """Points along every edge of the solid: a prismatic part reaches its extremes on its edges."""
    blocks = []
    for tag in boundary_edges(volumes):
        lo, hi = gmsh.model.getParametrizationBounds(1, tag)
        blocks.append(np.reshape(gmsh.model.getValue(1, tag, np.linspace(lo[0], hi[0], _SAMPLES_EDGE)), (-1, 3)))
    return np.vstack(blocks)


def _face_samples(face: int) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = gmsh.model.getParametrizationBounds(2, face)
    u = np.linspace(lo[0], hi[0], _SAMPLES_U)
    v = np.linspace(lo[1], hi[1], _SAMPLES_V)
    uv = np.column_stack([np.repeat(u, len(v)), np.tile(v, len(u))]).ravel()
    points = np.reshape(gmsh.model.getValue(2, face, uv), (-1, 3))
    normals = np.reshape(gmsh.model.getNormal(face, uv), (-1, 3))
    return points, normals


def _sectors_reached(cylinder: Cylinder, points: np.ndarray) -> int:
    """How many of the 30 degree sectors around the axis the points reach (12: all the way round)."""
    basis = np.linalg.svd(np.eye(3) - np.outer(cylinder.axis, cylinder.axis))[0][:, :2]
    xy = (points - cylinder.point_m) @ basis
    sectors = np.floor((np.arctan2(xy[:, 1], xy[:, 0]) + math.pi) / (2 * math.pi) * _ANGULAR_BINS)
    return len(np.unique(np.clip(sectors, 0, _ANGULAR_BINS - 1)))


def _span_deg(cylinder: Cylinder, points: np.ndarray) -> float:
    """The angle the points cover around the axis: a full turn less the widest gap between them."""
    basis = np.linalg.svd(np.eye(3) - np.outer(cylinder.axis, cylinder.axis))[0][:, :2]
    xy = (points - cylinder.point_m) @ basis
    angles = np.sort(np.arctan2(xy[:, 1], xy[:, 0]))
    gaps = np.diff(np.append(angles, angles[0] + 2 * math.pi))
    return math.degrees(2 * math.pi - float(gaps.max()))


def _concave(cylinder: Cylinder, points: np.ndarray, normals: np.ndarray) -> bool:
    """A hole's face, not a boss's: its outward normals point toward the axis (into the hole).

    gmsh gives OpenCASCADE faces' normals as the face is oriented in the solid's shell, i.e. out of
    the material (checked against isInside probes on every part of the tests, sewn files included).
    isInside itself, the first test here, cost 4-20 ms a call: minutes on a part with hundreds of holes.
    """
    rel = points - cylinder.point_m
    radial = rel - np.outer(rel @ cylinder.axis, cylinder.axis)
    return bool(np.mean(np.sum(radial * normals, axis=1) < 0) > 0.5)


def _bore_from_samples(cylinder: Cylinder, points: np.ndarray) -> Bore:
    along = (points - cylinder.point_m) @ cylinder.axis
    lo, hi = float(along.min()), float(along.max())
    return Bore(
        center_m=cylinder.point_m + (lo + hi) / 2 * cylinder.axis,
        axis=cylinder.axis,
        radius_m=cylinder.radius_m,
        length_m=hi - lo,
    )


def _canonical(axis: np.ndarray) -> np.ndarray:
    """The axis direction with its largest component positive, so parallel bores agree in sign."""
    return axis if axis[np.argmax(np.abs(axis))] > 0 else -axis


def _unit(v: np.ndarray, name: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not (math.isfinite(n) and n > 0):
        raise GeometryError(f"{name}={v}: expected a non-zero direction")
    return v / n
