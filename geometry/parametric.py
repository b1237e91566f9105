"""Build the parametric link in the current gmsh model (OpenCASCADE, model units = metres)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import gmsh

from geometry.dimensions import LinkDimensions, _lug_fillet_centre_m
from geometry.errors import GeometryError

# Entity look-up by bounding box, as a fraction of the pitch: OpenCASCADE pads boxes by its
# tolerance (~1e-7 m), and no other edge of the link lies within this distance of a wanted one.
BOX_TOLERANCE = 1e-4


@dataclass(frozen=True)
class LinkFeatures:
    """How the bores are modelled, to imitate what CAD exporters produce (same part, other faces).

    split_bores: each bore made of two half-cylinder faces (split by the plane y = bore centre).
    bspline_bores: each bore made of two rational B-spline half faces (exact circles) instead of
        analytic cylinders.
    bore_edge_break_m: if > 0, the top edges of both bores get a chamfer and the bottom edges a
        fillet of this size (cones and tori around the bore).
    """

    split_bores: bool = False
    bspline_bores: bool = False
    bore_edge_break_m: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.bore_edge_break_m) and self.bore_edge_break_m >= 0):
            raise GeometryError(
                f"LinkFeatures.bore_edge_break_m={self.bore_edge_break_m!r}: expected a length >= 0 in metres"
            )
        if self.bspline_bores and self.bore_edge_break_m > 0:
            # OpenCASCADE finds no chamfer for the B-spline bore edges.
            raise GeometryError(f"{self}: expected bore_edge_break_m = 0 with bspline_bores")


def add_link(dims: LinkDimensions, features: LinkFeatures = LinkFeatures()) -> int:
    """Add the link solid to the current model and return its volume tag."""
    occ = gmsh.model.occ
    half_pitch = dims.pitch_m / 2
    height = dims.body_height_m
    parts = [
        (
            3,
            occ.addBox(
                -dims.body_length_m / 2, -dims.body_width_m / 2, 0, dims.body_length_m, dims.body_width_m, height
            ),
        )
    ]
    for x in (-half_pitch, half_pitch):
        parts.append((3, occ.addCylinder(x, 0, 0, 0, 0, height, dims.lug_radius_m)))
        parts.append((3, occ.addBox(min(0.0, x), -dims.lug_radius_m, 0, abs(x), 2 * dims.lug_radius_m, height)))
    if dims.lug_fillet_radius_m > 0:
        parts += _lug_neck_fillets(dims)
    body, _ = occ.fuse(parts[:1], parts[1:])
    # Tools overshoot the faces they cut through so no coplanar faces are left to the boolean.
    overshoot = 0.1 * height
    tools = [(3, _pocket_tool(dims, overshoot))]
    for x in (-half_pitch, half_pitch):
        tools += _bore_tool(x, dims.bore_radius_m, -overshoot, height + 2 * overshoot, features)
    link, _ = occ.cut(body, tools)
    occ.synchronize()
    if len(link) != 1:
        raise GeometryError(f"LinkDimensions {dims}: expected one solid, the boolean operations gave {len(link)}")
    volume = link[0][1]
    if features.bore_edge_break_m > 0:
        volume = _break_bore_edges(volume, dims, features.bore_edge_break_m)
    return volume


def _lug_neck_fillets(dims: LinkDimensions) -> list[tuple[int, int]]:
    """Material of the four lug-neck fillets (to be fused with the body), built from planes and
    cylinders so that the solid stays analytic (OpenCASCADE's rolling-ball fillet is a B-spline
    approximation, 1.5e-7 off in volume): a prism over the quadrilateral lug axis (or the foot below
    the centre) - fillet centre - end face, less the fillet's cylinder. Its edges cross both circles at right angles, and what of it
    is not fillet lies inside the body (see `dimensions.lug_fillet_area_m2`)."""
    occ = gmsh.model.occ
    fx, fy = _lug_fillet_centre_m(dims)
    c, a, rho, height = dims.pitch_m / 2, dims.body_length_m / 2, dims.lug_fillet_radius_m, dims.body_height_m
    inside = a - rho  # a little way into the body, behind its end face
    # The fillet's tangent point on the lug outline lies on the line from its centre to the lug's
    # bore axis (half-disc part) or straight below its centre (tongue side, a short fillet).
    foot = c if rho > c - a else fx
    pieces = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            corners = [(sx * foot, 0.0), (sx * fx, sy * fy), (sx * inside, sy * fy), (sx * inside, 0.0)]
            points = [occ.addPoint(x, y, 0) for x, y in corners]
            lines = [occ.addLine(p, q) for p, q in zip(points, points[1:] + points[:1])]
            face = occ.addPlaneSurface([occ.addCurveLoop(lines)])
            prism = [dt for dt in occ.extrude([(2, face)], 0, 0, height) if dt[0] == 3]
            cutter = occ.addCylinder(sx * fx, sy * fy, -0.1 * height, 0, 0, 1.2 * height, rho)
            piece, _ = occ.cut(prism, [(3, cutter)])
            pieces += piece
    return pieces


def _pocket_tool(dims: LinkDimensions, overshoot: float) -> int:
    """The recess as an end mill leaves it: vertical corners and floor edges rounded (convex on the tool)."""
    occ = gmsh.model.occ
    floor = dims.web_thickness_m
    tool = occ.addBox(
        -dims.recess_length_m / 2,
        -dims.recess_width_m / 2,
        floor,
        dims.recess_length_m,
        dims.recess_width_m,
        dims.body_height_m - floor + overshoot,
    )
    occ.synchronize()
    if dims.pocket_corner_radius_m > 0:
        vertical = _tool_edges(tool, lambda box: box[5] - box[2] > 0.5 * dims.body_height_m)
        tool = occ.fillet([tool], vertical, [dims.pocket_corner_radius_m])[0][1]
        occ.synchronize()
    if dims.pocket_floor_radius_m > 0:
        tol = BOX_TOLERANCE * dims.pitch_m
        bottom = _tool_edges(tool, lambda box: abs(box[2] - floor) < tol and abs(box[5] - floor) < tol)
        tool = occ.fillet([tool], bottom, [dims.pocket_floor_radius_m])[0][1]
        occ.synchronize()
    return tool


def _tool_edges(tool: int, keep) -> list[int]:
    """Curves of a tool volume whose bounding box (xmin, ymin, zmin, xmax, ymax, zmax) passes `keep`."""
    faces = gmsh.model.getBoundary([(3, tool)], combined=False, oriented=False)
    curves = {abs(c) for _, c in gmsh.model.getBoundary(faces, combined=False, oriented=False)}
    return sorted(c for c in curves if keep(gmsh.model.getBoundingBox(1, c)))


def _bore_tool(x: float, radius: float, z0: float, length: float, features: LinkFeatures) -> list[tuple[int, int]]:
    occ = gmsh.model.occ
    if features.bspline_bores:
        loops = [_nurbs_circle_loop(x, radius, z) for z in (z0, z0 + length)]
        return [dt for dt in occ.addThruSections(loops, makeSolid=True, makeRuled=True) if dt[0] == 3]
    if features.split_bores:
        halves = [occ.addCylinder(x, 0, z0, 0, 0, length, radius, angle=math.pi) for _ in range(2)]
        occ.rotate([(3, halves[1])], x, 0, 0, 0, 0, 1, math.pi)
        return [(3, h) for h in halves]
    return [(3, occ.addCylinder(x, 0, z0, 0, 0, length, radius))]


def _nurbs_circle_loop(cx: float, radius: float, z: float) -> int:
    """A circle of two exact rational quadratic half arcs (weights 1, sqrt(2)/2, 1, ...)."""
    occ = gmsh.model.occ
    w = math.sqrt(2) / 2

    def point(deg: float, r: float) -> int:
        return occ.addPoint(cx + r * math.cos(math.radians(deg)), r * math.sin(math.radians(deg)), z)

    start, middle = point(0, radius), point(180, radius)
    arcs = []
    for a, b, base in ((start, middle, 0), (middle, start, 180)):
        poles = [a, point(base + 45, radius / w), point(base + 90, radius), point(base + 135, radius / w), b]
        arcs.append(occ.addBSpline(poles, degree=2, weights=[1, w, 1, w, 1], knots=[0, 1, 2], multiplicities=[3, 2, 3]))
    return occ.addCurveLoop(arcs)


def _break_bore_edges(volume: int, dims: LinkDimensions, size: float) -> int:
    """Chamfer the bores' top edges and fillet their bottom edges."""
    occ = gmsh.model.occ
    top = _bore_end_edges(dims, dims.body_height_m)
    top_faces = []
    for c in top:
        faces, _ = gmsh.model.getAdjacencies(1, c)
        top_faces.append(next(int(s) for s in faces if gmsh.model.getType(2, int(s)) == "Plane"))
    volume = occ.chamfer([volume], top, top_faces, [size] * len(top))[0][1]
    occ.synchronize()
    # Chamfering renumbers the entities: look the bottom edges up afterwards.
    volume = occ.fillet([volume], _bore_end_edges(dims, 0.0), [size])[0][1]
    occ.synchronize()
    return volume


def _bore_end_edges(dims: LinkDimensions, z: float) -> list[int]:
    """Tags of the curves bounding the bores' ends in the plane z (one or two arcs per bore)."""
    r = dims.bore_radius_m
    tol = 1e-6 * dims.pitch_m
    return [
        c
        for x in (-dims.pitch_m / 2, dims.pitch_m / 2)
        for _, c in gmsh.model.getEntitiesInBoundingBox(
            x - r - tol, -r - tol, z - tol, x + r + tol, r + tol, z + tol, dim=1
        )
    ]
