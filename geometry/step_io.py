"""STEP files in and out of the current gmsh model, with explicit units.

The model is always in metres (`session.gmsh_model` sets Geometry.OCCTargetUnit = "M" before any
use): OpenCASCADE converts whatever length unit a file declares to metres on import, and gmsh's
STEP writer scales the model's metres to the millimetre header it always writes. A file in metres
is written with the target unit set to millimetres (so the metre values go out unscaled) and its
header's length unit then rewritten to metres.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import gmsh

from geometry.atomic import atomic_target
from geometry.dimensions import LinkDimensions
from geometry.errors import GeometryError
from geometry.parametric import LinkFeatures, add_link
from geometry.session import gmsh_model, quiet_stdout

_STEP_MAGIC = b"ISO-10303-21"
_MILLIMETRE_UNIT = "SI_UNIT(.MILLI.,.METRE.)"
_METRE_UNIT = "SI_UNIT($,.METRE.)"
_UNITS = ("mm", "m")


def import_step(path: str | os.PathLike) -> list[int]:
    """Import a STEP file into the current model (in metres); return its volume tags.

    Files that hold only faces are sewn and turned into solids. Raises GeometryError for a file that
    is missing, unreadable, not STEP, or holds no solid.
    """
    return import_step_bytes(read_step(path), path)


def read_step(path: str | os.PathLike) -> bytes:
    """The bytes of a STEP file; GeometryError for a file that is missing, unreadable or not STEP."""
    path = Path(path)
    if not path.is_file():
        raise GeometryError(f"{path}: no such file; expected a STEP file (.step/.stp)")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise GeometryError(f"{path}: cannot be read ({exc.strerror}); expected a readable STEP file") from exc
    if not data[:256].lstrip().startswith(_STEP_MAGIC):
        raise GeometryError(f"{path}: not a STEP file (no ISO-10303-21 header); expected a STEP AP203/AP214/AP242 file")
    return data


def import_step_bytes(data: bytes, name: str | os.PathLike) -> list[int]:
    """`import_step` of a STEP file's bytes (read once by `read_step`); messages name the file `name`.

    OpenCASCADE reads only files: the bytes go through a temporary copy, removed after the import.
    """
    with tempfile.TemporaryDirectory(prefix="link-step-") as folder:
        copy = Path(folder) / "part.step"
        copy.write_bytes(data)
        gmsh.option.setString("Geometry.OCCTargetUnit", "M")
        try:
            with quiet_stdout():
                gmsh.model.occ.importShapes(str(copy), highestDimOnly=True, format="step")
                gmsh.model.occ.synchronize()
        except Exception as exc:  # gmsh reports every failure as a bare Exception
            raise GeometryError(f"{name}: OpenCASCADE could not read it ({exc}); expected a valid STEP file") from exc
    volumes = [tag for _, tag in gmsh.model.getEntities(3)]
    if not volumes and gmsh.model.getEntities(2):
        # Heal the whole model: listing the faces sews them but makes no solid (gmsh 4.15).
        gmsh.model.occ.healShapes([], sewFaces=True, makeSolids=True)
        gmsh.model.occ.synchronize()
        volumes = [tag for _, tag in gmsh.model.getEntities(3)]
    if not volumes:
        raise GeometryError(
            f"{name}: holds no solid (and its faces, if any, do not close one); expected one solid link"
        )
    return volumes


def model_brep_bytes() -> bytes:
    """The current model's shapes as OpenCASCADE's BREP text (model units, metres; no unit header)."""
    with tempfile.TemporaryDirectory(prefix="link-brep-") as folder:
        copy = Path(folder) / "body.brep"
        gmsh.write(str(copy))
        return copy.read_bytes()


def import_brep_bytes(data: bytes) -> list[int]:
    """Import `model_brep_bytes`' text into the current model; its volume tags."""
    with tempfile.TemporaryDirectory(prefix="link-brep-") as folder:
        copy = Path(folder) / "body.brep"
        copy.write_bytes(data)
        volumes = gmsh.model.occ.importShapes(str(copy), highestDimOnly=True, format="brep")
        gmsh.model.occ.synchronize()
    return [tag for dim, tag in volumes if dim == 3]


def write_model_step(path: str | os.PathLike, *, unit: str = "mm") -> Path:
    """Write the current model (in metres) to a STEP file in `unit` ("mm" or "m"), atomically."""
    if unit not in _UNITS:
        raise GeometryError(f"unit={unit!r}: expected one of {_UNITS}")
    path = Path(path)
    # The writer converts model units (the target unit) to millimetres; declaring the model in
    # millimetres writes its metre values unscaled, under a header then corrected to metres.
    gmsh.option.setString("Geometry.OCCTargetUnit", "MM" if unit == "m" else "M")
    try:
        with atomic_target(path) as tmp:
            with quiet_stdout():
                gmsh.write(str(tmp))
            if unit == "m":
                _declare_metres(tmp)
    finally:
        gmsh.option.setString("Geometry.OCCTargetUnit", "M")
    return path


def _declare_metres(path: Path) -> None:
    text = path.read_text()
    if text.count(_MILLIMETRE_UNIT) != 1:
        raise RuntimeError(f"{path}: gmsh's STEP writer no longer writes one {_MILLIMETRE_UNIT} length unit")
    path.write_text(text.replace(_MILLIMETRE_UNIT, _METRE_UNIT))


def write_step(
    dims: LinkDimensions, path: str | os.PathLike, *, unit: str = "mm", features: LinkFeatures = LinkFeatures()
) -> Path:
    """Write the parametric link to a STEP file whose coordinates are in `unit` ("mm" or "m")."""
    if unit not in _UNITS:
        raise GeometryError(f"unit={unit!r}: expected one of {_UNITS}")
    with gmsh_model("write_step"):
        add_link(dims, features)
        return write_model_step(path, unit=unit)
