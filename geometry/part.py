"""The part, resolved once per run: `resolve_part` turns what the user named (a STEP file with its part
options, or the built-in parametric link) into a `Part` that everything downstream takes.

Resolving reads the STEP file from disk (once: the bytes are kept, and the content fingerprint is
theirs), chooses the link body and its pin bores (fixed bore first), measures the hardware solids,
the body's volume and size, and checks the mirror symmetry about the plane through the bore axes.
No meshing: a part that cannot be a link is refused in about the import's time.

Each mesh level still loads the body into a fresh gmsh model (`Part.load_body`): gmsh keeps one
global model and meshing consumes it (the solid is cut at the loaded bore and, for a mirror half,
at the plane). The level loads it from the part's own copy (the STEP bytes kept at resolution, or
the parametric link's dimensions) and takes the body by its number: nothing is read from disk and
nothing is detected or chosen again. An exact serialised shape would be cheaper to load, but
OpenCASCADE's BREP text round trip is not exact (the default link's volume moved by 2e-16 relative
and its 6 mm mesh by 71 nodes, measured), and the meshes must stay the ones the STEP import gives.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass
from pathlib import Path

import gmsh

from geometry.assembly import LinkSource, PartSummary, as_link_source, hardware_solids, pick_body
from geometry.bores import BoreOverride, bores_from_override
from geometry.dimensions import DEFAULT_LINK, LinkDimensions
from geometry.errors import GeometryError
from geometry.link_mesh import Bore, MirrorPlane
from geometry.parametric import add_link
from geometry.pin_pair import PinBores
from geometry.session import gmsh_model
from geometry.step_io import import_step_bytes, read_step
from geometry.symmetry import symmetry_plane

@dataclass(frozen=True)
class PartScale:
    """The lengths the default mesh sizes are relative to (metres)."""

    pitch_m: float
    bore_radius_m: float  # the smaller pin bore's
    smallest_hole_radius_m: float  # of the other holes (screw, grease holes); inf if none


@dataclass(frozen=True, eq=False)
class Part:
    """One link, resolved: what every mesh level, the FEA cache and the reports need of it.

    The bores' gmsh face tags in `summary.pins` belong to the resolution's model, which is gone;
    meshing finds the bore faces again from the `Bore` geometry.
    """

    name: str  # the STEP path, "default", or "parametric LinkDimensions(...)": messages and LinkMesh.source
    origin: LinkSource | LinkDimensions  # what it was resolved from, with the user's part options
    fingerprint: str  # sha256 of the STEP bytes, or of the parametric link's dimensions (repr)
    step_bytes: bytes | None  # the STEP file as read at resolution; None for the parametric link
    summary: PartSummary  # the body's number, its pin bores (fixed first), ignored holes, hardware solids
    scale: PartScale
    volume_m3: float  # the body's CAD volume
    diagonal_m: float  # the body's bounding-box diagonal: the part's length scale
    all_solids_diagonal_m: float  # the file's, hardware included (fem.adaptive's start size, as before)
    mirror_plane: MirrorPlane | None  # the plane through both bore axes if the body is symmetric about it
    symmetry_checked: bool  # False: resolved with symmetry=False, mirror_plane None without a check

    @property
    def fixed_bore(self) -> Bore:
        return self.summary.pins.fixed.bore

    @property
    def loaded_bore(self) -> Bore:
        return self.summary.pins.loaded.bore

    @property
    def pins(self) -> PinBores:
        return self.summary.pins

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


def resolve_part(source=None, *, bores: BoreOverride | None = None, symmetry: bool = True) -> Part:
    """The `Part` of a source: None (the built-in link), a STEP path, a `LinkSource` (a STEP path with
    the user's part options) or `LinkDimensions` (the parametric link resized, a study's variant).
    This is the only place that tells these kinds apart.

    bores: manual bores instead of detection (a single solid only). symmetry: check the mirror
    symmetry (False leaves `mirror_plane` None and `symmetry_checked` False: --full-model skips the
    check, whose cost grows with the square of the number of faces).
    """
    dims = data = None
    if source is None or isinstance(source, LinkDimensions):
        dims = DEFAULT_LINK if source is None else source
        name = "default" if source is None else f"parametric {source}"
        origin, fingerprint = dims, _sha256(repr(dims).encode())
    else:
        origin = as_link_source(source)
        name = os.fspath(source)
        data = read_step(origin.path)
        fingerprint = _sha256(data)
    with gmsh_model("part"):
        volumes = [add_link(dims)] if data is None else import_step_bytes(data, name)
        all_solids_diagonal_m = _model_diagonal_m()
        if bores is not None:
            if len(volumes) != 1:
                raise GeometryError(f"{name}: holds {len(volumes)} solids; expected exactly one solid link")
            fixed, loaded = bores_from_override(volumes, bores, name)
            body, pins = volumes[0], PinBores(fixed, loaded, f"given by {bores}", ())
        else:
            body, pins = pick_body(volumes, LinkSource(Path(name)) if data is None else origin, name)
        summary = PartSummary(source=str(origin) if data is not None else name, n_solids=len(volumes),
                              body_index=volumes.index(body) + 1,
                              body_volume_m3=float(gmsh.model.occ.getMass(3, body)), pins=pins,
                              hardware=hardware_solids(volumes, body))
        keep_only(volumes, body)
        # measured as each mesh level sees the model: the body alone
        volume_m3 = float(gmsh.model.occ.getMass(3, body))
        diagonal_m = _model_diagonal_m()
        plane = symmetry_plane([body], pins.fixed.bore, pins.loaded.bore) if symmetry else None
    return Part(name=name, origin=origin, fingerprint=fingerprint, step_bytes=data, summary=summary,
                scale=_scale(pins, dims), volume_m3=volume_m3, diagonal_m=diagonal_m,
                all_solids_diagonal_m=all_solids_diagonal_m, mirror_plane=plane, symmetry_checked=symmetry)


def as_part(source=None, *, bores: BoreOverride | None = None, symmetry: bool = True) -> Part:
    """`source` itself if it is a `Part`, else `resolve_part(source)`: the library's entry points
    take either, so that a caller with a path need not resolve it first."""
    if isinstance(source, Part):
        if bores is not None:
            raise GeometryError(f"bores={bores!r}: the part {source.name} is resolved already; expected bores=None "
                                "(pass the bores to resolve_part)")
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
    return PartScale(pins.pitch_m, float(min(pins.fixed.bore.radius_m, pins.loaded.bore.radius_m)),
                     min(holes, default=math.inf))


def _model_diagonal_m() -> float:
    xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(-1, -1)
    return math.dist((xmin, ymin, zmin), (xmax, ymax, zmax))


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
