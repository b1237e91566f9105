"""The part measured in gmsh (`Part.geometry`): the body and its pin bores chosen, its sizes, holes,
thin walls and mirror symmetry. A module of its own so that resolving a part (`geometry.part`, which
`pipeline.py`'s own process does) imports neither gmsh nor the searches."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import gmsh

from geometry.assembly import LinkSource, PartSummary, hardware_solids, pick_body
from geometry.bores import bores_from_override
from geometry.dimensions import LinkDimensions
from geometry.errors import GeometryError
from geometry.link_mesh import MirrorPlane
from geometry.mesh_estimate import Hole, MeshFeatures, WallFeature
from geometry.parametric import add_link
from geometry.part import Part, PartGeometry, PartScale
from geometry.pin_pair import PinBores
from geometry.session import gmsh_model, keep_model
from geometry.step_io import import_step_bytes, model_brep_bytes
from geometry.symmetry import faces_on_plane, keep_positive_half, symmetry_plane
from geometry.walls import thin_walls

# The unknowns estimate knows the thin walls up to this fraction of the part's diagonal thick:
# those refined on levels whose finest size is up to 0.2 diagonals (geometry.meshing's
# THIN_WALL_FRACTION), far coarser than any default (at most pitch / 25, under 0.04 diagonals) or a
# useful --mesh-size. Finding them takes 0.1-0.5 s on the corpus parts that resolve.
WALL_SEARCH_DIAGONALS = 0.1


def measure(part: Part, keep_half: bool = False) -> PartGeometry:
    """Load the part into a gmsh model of its own, choose the body and its pin bores (or take the
    manual ones), measure the hardware, then, as each mesh level sees the model (the body alone),
    the body's volume and size and its symmetry. `keep_half`: see `Part.measure_keeping_half`."""
    name, data, bores = part.name, part.step_bytes, part.bores
    with gmsh_model(part.half_model_name):
        volumes = [add_link(part.origin)] if data is None else import_step_bytes(data, name)
        all_solids_diagonal_m = _model_diagonal_m()
        if bores is not None:
            if len(volumes) != 1:
                raise GeometryError(f"{name}: holds {len(volumes)} solids; expected exactly one solid link")
            fixed, loaded = bores_from_override(volumes, bores, name)
            body, pins = volumes[0], PinBores(fixed, loaded, f"given by {bores}", ())
        else:
            body, pins = pick_body(volumes, part.origin if data is not None else LinkSource(Path(name)), name)
        summary = PartSummary(
            source=str(part.origin) if data is not None else name,
            n_solids=len(volumes),
            body_index=volumes.index(body) + 1,
            body_volume_m3=float(gmsh.model.occ.getMass(3, body)),
            pins=pins,
            hardware=hardware_solids(volumes, body),
        )
        keep_only(volumes, body)
        body_brep = model_brep_bytes()
        volume_m3 = float(gmsh.model.occ.getMass(3, body))
        diagonal_m = _model_diagonal_m()
        plane = symmetry_plane([body], pins.fixed.bore, pins.loaded.bore) if part.symmetry_checked else None
        features = _mesh_features(body, volume_m3, pins, diagonal_m)
        if plane is not None:  # last: the half replaces the body in the model
            half = keep_positive_half([body], plane)
            features = replace(features, mirror_cut_area_m2=_cut_face_area_m2(half, plane))
            if keep_half:
                keep_model(part.half_model_name, half)
    return PartGeometry(
        summary=summary,
        scale=_scale(pins, None if data is not None else part.origin),
        volume_m3=volume_m3,
        diagonal_m=diagonal_m,
        all_solids_diagonal_m=all_solids_diagonal_m,
        mirror_plane=plane,
        mesh_features=features,
        body_brep=body_brep,
    )


def _mesh_features(body: int, volume_m3: float, pins: PinBores, diagonal_m: float) -> MeshFeatures:
    """The body's volume, boundary area, holes' face areas and thin walls, from the current gmsh model."""
    boundary = gmsh.model.getBoundary([(3, body)], oriented=False)

    def hole(detected) -> Hole:
        return Hole(detected.bore.radius_m, sum(gmsh.model.occ.getMass(2, face) for face in detected.faces))

    return MeshFeatures(
        volume_m3=volume_m3,
        area_m2=sum(gmsh.model.occ.getMass(2, face) for _, face in boundary),
        pin_bores=(hole(pins.fixed), hole(pins.loaded)),
        small_holes=tuple(hole(ignored.hole) for ignored in pins.ignored),
        walls=tuple(
            WallFeature(wall.thickness_m, wall.area_m2)
            for wall in thin_walls([body], WALL_SEARCH_DIAGONALS * diagonal_m)
        ),
    )


def _cut_face_area_m2(half: list[int], plane: MirrorPlane) -> float:
    """Area of the face a mirror half (`keep_positive_half`) has on its plane."""
    return sum(gmsh.model.occ.getMass(2, face) for face in faces_on_plane(half, plane))


def keep_only(volumes: list[int], body: int) -> None:
    """Remove every solid but the link body (its hardware is not meshed)."""
    others = [(3, v) for v in volumes if v != body]
    if others:
        gmsh.model.occ.remove(others, recursive=True)
        gmsh.model.occ.synchronize()


def _scale(pins: PinBores, dims: LinkDimensions | None) -> PartScale:
    """The parametric link's nominal pitch and bore (no other holes); a STEP part's chosen bores."""
    if dims is not None:
        return PartScale(dims.pitch_m, dims.bore_radius_m, math.inf)
    holes = [h.hole.bore.radius_m for h in pins.ignored]
    return PartScale(
        pins.pitch_m, float(max(pins.fixed.bore.radius_m, pins.loaded.bore.radius_m)), min(holes, default=math.inf)
    )


def _model_diagonal_m() -> float:
    xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(-1, -1)
    return math.dist((xmin, ymin, zmin), (xmax, ymax, zmax))
