"""The part, resolved once per run: `resolve_part` turns what the user named (a STEP file with its part
options, or the built-in parametric link) into a `Part` that everything downstream takes.

"Resolved once" means: per run, the STEP file is read from disk once (`resolve_part`; the bytes are
kept and the content fingerprint, the FEA cache's key, is theirs), and the link body and its pin
bores are chosen once (fixed bore first), the hardware solids, the body's volume and size measured
and its mirror symmetry about the plane through the bore axes checked once (`Part.geometry`, on
first use: a run whose FEA is all in the cache never needs it for the parametric link). No meshing:
a STEP part that cannot be a link is refused in about the import's time.

Each mesh level still loads the body into a fresh gmsh model (`Part.load_body`): gmsh keeps one
global model and meshing consumes it (the solid is cut at the loaded bore and, for a mirror half,
at the plane). The level loads it from the part's own copy (the STEP bytes kept at resolution, or
the parametric link's dimensions) and takes the body by its number: nothing is read from disk and
nothing is detected or chosen again. The body's OpenCASCADE BREP text, written by the measurement,
would be cheaper to load (0.01 CPU s), but the round trip is not exact (the default link's volume
moved by 2e-16 relative, and its coarse level's mesh enough to move k by 0.13 % and widen its
estimate from 0.85 to 0.95 %, measured), so the stiffness levels keep the meshes the part's own
copy gives; the stress study's sub-model, whose answer carries a 3-4 % estimate, loads the BREP
text (`Part.load_body_brep`).
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import gmsh

from geometry.assembly import LinkSource, PartSummary, as_link_source, hardware_solids, pick_body
from geometry.bores import BoreOverride, bores_from_override
from geometry.dimensions import DEFAULT_LINK, LinkDimensions
from geometry.errors import GeometryError
from geometry.link_mesh import MirrorPlane
from geometry.mesh_estimate import Hole, MeshFeatures, WallFeature
from geometry.parametric import add_link
from geometry.pin_pair import PinBores
from geometry.session import gmsh_model, keep_model
from geometry.step_io import import_brep_bytes, import_step_bytes, model_brep_bytes, read_step
from geometry.symmetry import faces_on_plane, keep_positive_half, symmetry_plane
from geometry.walls import thin_walls

# The unknowns estimate knows the thin walls up to this fraction of the part's diagonal thick:
# those refined on levels whose finest size is up to 0.2 diagonals (geometry.meshing's
# THIN_WALL_FRACTION), far coarser than any default (at most pitch / 25, under 0.04 diagonals) or a
# useful --mesh-size. Finding them takes 0.1-0.5 s on the corpus parts that resolve.
WALL_SEARCH_DIAGONALS = 0.1


@dataclass(frozen=True)
class PartScale:
    """The lengths the default mesh sizes are relative to (metres)."""

    pitch_m: float
    bore_radius_m: float  # the larger pin bore's (a smaller one, named by --bores, is refined locally)
    smallest_hole_radius_m: float  # of the other holes (screw, grease holes); inf if none


@dataclass(frozen=True)
class PartGeometry:
    """What resolution measures in gmsh: the body and its pin bores, its sizes, its symmetry.

    The bores' gmsh face tags in `summary.pins` belong to the resolution's model, which is gone;
    meshing finds the bore faces again from the `Bore` geometry.
    """

    summary: PartSummary  # the body's number, its pin bores (fixed first), ignored holes, hardware solids
    scale: PartScale
    volume_m3: float  # the body's CAD volume
    diagonal_m: float  # the body's bounding-box diagonal: the part's length scale
    all_solids_diagonal_m: float  # the file's, hardware included (fem.adaptive's start size, as before)
    mirror_plane: MirrorPlane | None  # the plane through both bore axes if the body is symmetric about it
    mesh_features: MeshFeatures  # volume, surface and holes: a mesh's unknowns estimated before meshing
    body_brep: bytes  # the body alone as OpenCASCADE's BREP text (`Part.load_body_brep`)


@dataclass(frozen=True, eq=False)
class Part:
    """One link: what every mesh level, the FEA cache and the reports need of it.

    `resolve_part` reads the STEP file (the bytes and their fingerprint); the body, its bores and
    sizes (`geometry`) are chosen and measured on first use, once, and kept: a run whose FEA is
    all in the cache then builds nothing in gmsh (the parametric link costs 0.5 s to build and
    inspect), and a STEP run uses them at once to print the choice before any FEA.
    """

    name: str  # the STEP path, "default", or "parametric LinkDimensions(...)": messages and LinkMesh.source
    origin: LinkSource | LinkDimensions  # what it was resolved from, with the user's part options
    fingerprint: str  # sha256 of the STEP bytes, or of the parametric link's dimensions (repr)
    step_bytes: bytes | None  # the STEP file as read at resolution; None for the parametric link
    bores: BoreOverride | None = None  # manual bores instead of detection (a single solid)
    symmetry_checked: bool = True  # False: mirror_plane is None without a check (resolve_part(symmetry=False))

    @cached_property
    def geometry(self) -> PartGeometry:
        """The body, its pin bores, sizes and symmetry: chosen and measured on first use, then kept."""
        return _measure(self)

    def measure_keeping_half(self) -> PartGeometry:
        """`geometry`, measured now if it is not yet, the mirror half the measurement ends with (a
        symmetric part) kept in gmsh for the first `mesh_part(self, mirror=True)` in this process
        (`half_model_name`), which then meshes it instead of building the CAD again and cutting it
        (the CAD 0.20-0.26 CPU s on the built-in link; the same model, so the same mesh:
        tests/test_geometry_session.py)."""
        if "geometry" not in self.__dict__:  # functools.cached_property's slot
            self.__dict__["geometry"] = _measure(self, keep_half=True)
        return self.geometry

    @property
    def half_model_name(self) -> str:
        """The gmsh model `measure_keeping_half` keeps its mirror half under."""
        return f"half of {self.name} {self.fingerprint} {self.bores!r}"

    @property
    def summary(self) -> PartSummary:
        return self.geometry.summary

    @property
    def pins(self) -> PinBores:
        return self.geometry.summary.pins

    @property
    def scale(self) -> PartScale:
        return self.geometry.scale

    @property
    def volume_m3(self) -> float:
        return self.geometry.volume_m3

    @property
    def mirror_plane(self) -> MirrorPlane | None:
        return self.geometry.mirror_plane

    @property
    def is_step(self) -> bool:
        return self.step_bytes is not None

    def load_body(self) -> list[int]:
        """Add the link body alone to the current gmsh model (hardware removed); its volume tags."""
        if self.step_bytes is None:
            return [add_link(self.origin)]
        volumes = import_step_bytes(self.step_bytes, self.name)
        body = volumes[self.summary.body_index - 1]
        keep_only(volumes, body)
        return [body]

    def load_body_brep(self) -> list[int]:
        """`load_body` from the BREP text its measurement wrote (`PartGeometry.body_brep`): about 0.01
        CPU s where building the parametric link takes 0.2-0.45 s, a STEP import longer. The text
        round trip is not exact to the bit (the default link's volume moves by 2e-16 relative), and
        a mesh of the shape it gives differs by some nodes: the stress study's sub-models, whose
        answer carries a 3-4 % estimate, load it; the stiffness levels do not (meshed from it, the
        default link's coarse level had 39,219 DOFs instead of 39,432, k moved by 0.13 % and its
        estimate widened from 0.85 to 0.95 %: docs/performance.md)."""
        return import_brep_bytes(self.geometry.body_brep)


def resolve_part(source=None, *, bores: BoreOverride | None = None, symmetry: bool = True) -> Part:
    """The `Part` of a source: None (the built-in link), a STEP path, a `LinkSource` (a STEP path with
    the user's part options) or `LinkDimensions` (the parametric link resized, a study's variant).
    This is the only place that tells these kinds apart. A STEP file is read here, and only here.

    bores: manual bores instead of detection (a single solid only). symmetry: check the mirror
    symmetry (False leaves `mirror_plane` None and `symmetry_checked` False: --full-model skips the
    check, whose cost grows with the square of the number of faces).
    """
    if source is None or isinstance(source, LinkDimensions):
        dims = DEFAULT_LINK if source is None else source
        name = "default" if source is None else f"parametric {source}"
        return Part(name, dims, _sha256(repr(dims).encode()), None, bores, symmetry)
    origin = as_link_source(source)
    data = read_step(origin.path)
    return Part(os.fspath(source), origin, _sha256(data), data, bores, symmetry)


def _measure(part: Part, keep_half: bool = False) -> PartGeometry:
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


def as_part(source=None, *, bores: BoreOverride | None = None, symmetry: bool = True) -> Part:
    """`source` itself if it is a `Part`, else `resolve_part(source)`: the library's entry points
    take either, so that a caller with a path need not resolve it first."""
    if isinstance(source, Part):
        if bores is not None:
            raise GeometryError(
                f"bores={bores!r}: the part {source.name} is resolved already; expected bores=None "
                "(pass the bores to resolve_part)"
            )
        return source
    return resolve_part(source, bores=bores, symmetry=symmetry)


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


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
