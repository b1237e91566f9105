"""The part options shared by `python -m fem` and `pipeline.py`: which bores, which solid, what hardware.

Lengths on the command line are millimetres in the CAD file's own frame (the coordinates a CAD
program shows), whatever unit the file declares.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from geometry.errors import GeometryError

if TYPE_CHECKING:  # importing them pulls in gmsh, which the built-in link's run does not need here
    from geometry.assembly import LinkSource, PartSummary


def add_part_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("part (STEP files with other holes, or several solids)")
    group.add_argument(
        "--bores",
        metavar="X1,Y1,Z1:X2,Y2,Z2",
        help="a point on each pin-bore axis in mm (CAD coordinates), fixed (clamped) bore first; "
        "default: equal parallel bores at the part's ends, the largest such, farthest apart",
    )
    group.add_argument("--pitch", metavar="MM", help="keep only pin-bore pairs this far apart (within 1 %%)")
    group.add_argument("--bore-radius", metavar="MM", help="keep only pin bores of this radius (within 1 %%)")
    group.add_argument(
        "--body",
        metavar="N",
        help="in a file of several solids, the link body's number (1-based, file "
        "order); default: the solid holding the pin bores",
    )
    group.add_argument(
        "--hardware-material",
        metavar="ID[,ID...]",
        help="material of the other solids (pins, bushings...), one for all or one per hardware solid in file "
        "order: reports their masses",
    )


# options whose value may start with a minus sign (a negative CAD coordinate)
SIGNED_VALUE_OPTIONS = ("--bores",)
_SIGNED_NUMBER = re.compile(r"-\.?\d")


def signed_values_attached(argv: list[str] | None) -> list[str]:
    """argv with `--bores -103.3,2.2,-25:...` written as `--bores=-103.3,...`: argparse takes a
    value that starts with '-' (and is not one plain number) for an option and refuses it."""
    args = list(sys.argv[1:] if argv is None else argv)
    out: list[str] = []
    i = 0
    while i < len(args):
        if args[i] == "--":
            return out + args[i:]
        if args[i] in SIGNED_VALUE_OPTIONS and i + 1 < len(args) and _SIGNED_NUMBER.match(args[i + 1]):
            out.append(f"{args[i]}={args[i + 1]}")
            i += 2
        else:
            out.append(args[i])
            i += 1
    return out


def link_source(path: str | os.PathLike | None, args: argparse.Namespace) -> LinkSource | None:
    """The STEP path with the part options; None (the built-in link) if no path and no options."""
    given = [name for name in ("bores", "pitch", "bore_radius", "body") if getattr(args, name) is not None]
    if path is None:
        if given:
            raise GeometryError(f"--{given[0].replace('_', '-')}: only for a STEP file; expected a STEP path with it")
        return None
    from geometry.assembly import LinkSource
    from geometry.pin_pair import BoreChoice

    choice = BoreChoice(
        *_axis_points(args.bores),
        pitch_m=None if args.pitch is None else _positive_mm(args.pitch, "--pitch"),
        radius_m=None if args.bore_radius is None else _positive_mm(args.bore_radius, "--bore-radius"),
    )
    return LinkSource(Path(path), choice, None if args.body is None else _solid_number(args.body))


def hardware_densities(ids: str | None, summary: PartSummary, density_of) -> list[float] | None:
    """Density (kg/m^3) per hardware solid from --hardware-material, None if not given.

    density_of(id) looks a material id up (the caller's materials table)."""
    if ids is None:
        return None
    names = [s.strip() for s in ids.split(",") if s.strip()]
    n = len(summary.hardware)
    if len(names) not in (1, n):
        raise GeometryError(
            f"--hardware-material: {len(names)} materials for {n} hardware solid(s) of {summary.source}; "
            "expected one for all or one per hardware solid in file order"
        )
    try:
        densities = [density_of(name) for name in names]
    except ValueError as exc:  # the materials table's "unknown material ..." names the known ids
        raise GeometryError(f"--hardware-material: {exc}") from None
    return densities * n if len(densities) == 1 else densities


def hardware_masses_kg(summary: PartSummary, densities: list[float]) -> list[float]:
    return [solid.volume_m3 * density for solid, density in zip(summary.hardware, densities)]


def _axis_points(text: str | None):
    if text is None:
        return None, None
    halves = text.split(":")
    try:
        points = [tuple(float(x) * 1e-3 for x in half.split(",")) for half in halves]
    except ValueError:
        points = []
    if len(points) != 2 or any(len(p) != 3 or not all(map(math.isfinite, p)) for p in points):
        from geometry.pin_pair import BORES_HINT

        raise GeometryError(f"--bores {text!r}: expected {BORES_HINT}, e.g. 0,0,8:101.6,0,8")
    return points[0], points[1]


def _positive_mm(text: str, option: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise GeometryError(f"{option} {text!r}: expected a positive length in mm")
    return value * 1e-3


def _solid_number(text: str) -> int:
    if not text.strip().isdigit() or int(text) < 1:
        raise GeometryError(f"--body {text!r}: expected a solid number from 1 (file order)")
    return int(text)
