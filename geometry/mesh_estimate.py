"""How many unknowns a mesh of the part will have, estimated before meshing it.

gmsh fills the part with tetrahedra of the size its size field asks for (geometry.meshing): about
one tetrahedron per s^3 of volume and one boundary triangle per s^2 of surface, s the local size.
The estimate integrates the same size field over the part: the far size everywhere, and around
each pin bore and each small hole the refined zone the field puts there (its near size within half
a radius of the hole's faces, graded to the far size), the zone's volume growing with the distance
from the hole's axis as round a cylinder:

    P2 unknowns = VOLUME_COEF * integral(dV / s^3) + AREA_COEF * integral(dA / s^2)

Thin walls (planar, rings round holes) refined by their own field
(geometry.meshing.THIN_WALL_FRACTION) add their material and their two faces at the wall's size. A mirror half is half the part plus the face it
gets on the mirror plane, at the far size: without that face the half's real / estimate on the
built-in link was 0.005-0.065 above the whole's at 3-9 mm, with it within 0.022 of it (measured).

The two coefficients are fitted to the built-in link's meshes (whole at 3, 4.5, 6, 9 and 15 mm;
its mirror half at 2.25-11.25 mm) and checked, not fitted, on the corpus parts' default levels
(docs/performance.md, "FEA: unknowns before meshing"): real / estimate 0.85-1.04 there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.meshing import (
    BORE_FIELD_INNER_RADII,
    BORE_FIELD_OUTER_RADII,
    SIZE_GRADIENT,
    SMALL_HOLE_SIZE_FRACTION,
    THIN_WALL_FRACTION,
    UNEQUAL_BORES_TOL,
    thin_wall_size,
)

# Least squares in relative error over the built-in link's meshes (module docstring).
VOLUME_COEF = 4.503
AREA_COEF = 32.14
# P2 nodes per vertex of a tetrahedral mesh: 6.1-6.4 on the corpus' meshes (vertices + edges).
P2_NODES_PER_VERTEX = 6.4
_ZONE_SAMPLES = 400


@dataclass(frozen=True)
class Hole:
    """A round hole of the part: its radius and the area of its faces (metres)."""

    radius_m: float
    area_m2: float


@dataclass(frozen=True)
class WallFeature:
    """A thin wall of the part (geometry.walls): its thickness and the area across it (metres)."""

    thickness_m: float
    area_m2: float


@dataclass(frozen=True)
class MeshFeatures:
    """What the estimate needs of the part, measured at resolution (SI)."""

    volume_m3: float
    area_m2: float  # the whole boundary
    pin_bores: tuple[Hole, Hole]
    small_holes: tuple[Hole, ...]  # every other full hole
    walls: tuple[WallFeature, ...] = ()  # thin walls (geometry.measure.WALL_SEARCH_DIAGONALS)
    mirror_cut_area_m2: float = 0.0  # the face a mirror half gets on its plane (none: 0)


def estimated_dofs(
    features: MeshFeatures,
    mesh_size_m: float,
    bore_size_m: float,
    order: int,
    half: bool,
    wall_reference_m: float | None = None,
) -> float:
    """Estimated unknowns (3 per node) of the part meshed at `mesh_size_m` (`bore_size_m` at the pin
    bores), with elements of `order`; `half`: a mirror half (half the part); `wall_reference_m`: the
    size its thin walls are refined against (geometry.meshing; None: not refined)."""
    per_volume, per_area = _size_field_integrals(features, mesh_size_m, bore_size_m)
    if wall_reference_m is not None:
        wall_volume, wall_area = _wall_integrals(features.walls, mesh_size_m, wall_reference_m)
        per_volume, per_area = per_volume + wall_volume, per_area + wall_area
    dofs = VOLUME_COEF * per_volume + AREA_COEF * per_area
    if half:  # half the part, and the cut face it gets on the mirror plane at the far size
        dofs = dofs / 2 + AREA_COEF * features.mirror_cut_area_m2 / mesh_size_m**2
    if order == 1:
        dofs /= P2_NODES_PER_VERTEX
    return dofs


def _size_field_integrals(features: MeshFeatures, h: float, bore_size: float) -> tuple[float, float]:
    """(integral of s^-3 dV, integral of s^-2 dA) of the meshing's size field s over the part."""
    per_volume = features.volume_m3 / h**3
    per_area = features.area_m2 / h**2
    large = max(b.radius_m for b in features.pin_bores)
    zones = []
    for bore in features.pin_bores:
        if abs(bore.radius_m - large) <= UNEQUAL_BORES_TOL * large:
            ramp = (BORE_FIELD_OUTER_RADII - BORE_FIELD_INNER_RADII) * large
            zones.append((bore, bore_size, BORE_FIELD_INNER_RADII * large, (h - bore_size) / ramp))
        else:  # a smaller pin bore: its own hole field, sized by its radius
            zones.append((bore, bore_size * bore.radius_m / large, 0.5 * bore.radius_m, SIZE_GRADIENT))
    for hole in features.small_holes:
        size = SMALL_HOLE_SIZE_FRACTION * hole.radius_m
        zones.append((hole, size, 0.5 * hole.radius_m, SIZE_GRADIENT))
    for hole, near, inner, slope in zones:
        if near >= h:
            continue
        d = np.linspace(0.0, inner + (h - near) / slope, _ZONE_SAMPLES)
        s = np.minimum(h, np.where(d < inner, near, near + slope * (d - inner)))
        growth = 1 + d / hole.radius_m  # the zone round a cylinder widens with the distance from it
        per_volume += hole.area_m2 * float(np.trapezoid(growth * (s**-3 - h**-3), d))
        per_area += hole.area_m2 * (near**-2 - h**-2)
    return per_volume, per_area


def _wall_integrals(walls: tuple[WallFeature, ...], h: float, reference_m: float) -> tuple[float, float]:
    """The thin walls' share of the integrals: each wall's material (area x thickness) and its two
    faces at the wall's size instead of h (the grading round the wall's edges left out)."""
    per_volume = per_area = 0.0
    for wall in walls:
        if wall.thickness_m >= THIN_WALL_FRACTION * reference_m:
            continue
        s = thin_wall_size(wall.thickness_m, h, reference_m)
        per_volume += wall.area_m2 * wall.thickness_m * (s**-3 - h**-3)
        per_area += 2 * wall.area_m2 * (s**-2 - h**-2)
    return per_volume, per_area
