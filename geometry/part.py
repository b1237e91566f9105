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
import os
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

from geometry.dimensions import DEFAULT_LINK, LinkDimensions
from geometry.errors import GeometryError

if TYPE_CHECKING:  # gmsh and the searches: only measuring or loading the part needs them (geometry.measure)
    from geometry.assembly import LinkSource, PartSummary
    from geometry.bores import BoreOverride
    from geometry.link_mesh import MirrorPlane
    from geometry.mesh_estimate import MeshFeatures
    from geometry.pin_pair import PinBores


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
        from geometry.measure import measure

        return measure(self)

    def measure_keeping_half(self) -> PartGeometry:
        """`geometry`, measured now if it is not yet, the mirror half the measurement ends with (a
        symmetric part) kept in gmsh for the first `mesh_part(self, mirror=True)` in this process
        (`half_model_name`), which then meshes it instead of building the CAD again and cutting it
        (the CAD 0.20-0.26 CPU s on the built-in link; the same model, so the same mesh:
        tests/test_geometry_session.py)."""
        if "geometry" not in self.__dict__:  # functools.cached_property's slot
            from geometry.measure import measure

            self.__dict__["geometry"] = measure(self, keep_half=True)
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
        from geometry.measure import keep_only
        from geometry.parametric import add_link
        from geometry.step_io import import_step_bytes

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
        from geometry.step_io import import_brep_bytes

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
    from geometry.assembly import as_link_source
    from geometry.step_io import read_step

    origin = as_link_source(source)
    data = read_step(origin.path)
    return Part(os.fspath(source), origin, _sha256(data), data, bores, symmetry)


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


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
