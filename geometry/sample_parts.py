"""Real-world-shaped two-pin parts built with gmsh's OpenCASCADE kernel, for the tests and the README.

Each builder adds its solid(s) to the current gmsh model (in metres) and returns what was drawn
(the pin bores), so a test can check the import against it. `write_part` exports one to a
millimetre STEP file, as SolidWorks or Fusion 360 would. Sizes are in millimetres below
(MM = 1e-3) because that is how such parts are drawn. From the shell:

    python -m geometry.sample_parts OUT_DIR [NAME ...]   # writes OUT_DIR/NAME.step (default: all)
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import gmsh

from geometry.session import gmsh_model
from geometry.step_io import write_model_step

MM = 1e-3


@dataclass(frozen=True)
class PartSpec:
    """What the part was drawn with: the pin bores (axis points in metres), their radius, pitch."""

    fixed_axis_point_m: tuple[float, float, float]
    loaded_axis_point_m: tuple[float, float, float]
    bore_radius_m: float
    n_solids: int = 1
    body_index: int = 0  # which of the exported solids is the link body (file order)

    @property
    def pitch_m(self) -> float:
        return math.dist(self.fixed_axis_point_m[:2], self.loaded_axis_point_m[:2])


def _stadium(pitch: float, end_radius: float, thickness: float) -> int:
    """A plate with round ends about (0, 0) and (pitch, 0), z from 0 to thickness."""
    occ = gmsh.model.occ
    body = occ.addBox(0, -end_radius, 0, pitch, 2 * end_radius, thickness)
    ends = [occ.addCylinder(x, 0, 0, 0, 0, thickness, end_radius) for x in (0, pitch)]
    fused, _ = occ.fuse([(3, body)], [(3, e) for e in ends])
    return fused[0][1]


def _drill(volume: int, holes: list[int]) -> int:
    cut, _ = gmsh.model.occ.cut([(3, volume)], [(3, h) for h in holes])
    assert len(cut) == 1
    return cut[0][1]


def _through_z(x: float, y: float, radius: float, z0: float, z1: float) -> int:
    return gmsh.model.occ.addCylinder(x, y, z0, 0, 0, z1 - z0, radius)


def conveyor_link_with_nest_holes() -> PartSpec:
    """A 101.6 mm (4 in) pitch link, 12.7 mm pin bores; four M5 tapped-size holes (4.2 mm drill)
    for the nest parallel to the pins, two M4 holes for an end plate, and a 3 mm grease hole from
    one end into the fixed bore (normal to the pins)."""
    p, t, r_end, r_bore = 101.6 * MM, 16 * MM, 19 * MM, 6.35 * MM
    link = _stadium(p, r_end, t)
    holes = [_through_z(x, 0, r_bore, -t, 2 * t) for x in (0, p)]
    holes += [_through_z(p / 2 + dx, dy, 2.1 * MM, -t, 2 * t) for dx in (-18 * MM, 18 * MM) for dy in (-9 * MM, 9 * MM)]
    holes += [_through_z(p / 2, dy, 1.65 * MM, -t, 2 * t) for dy in (-12 * MM, 12 * MM)]
    holes.append(gmsh.model.occ.addCylinder(-r_end - MM, 0, t / 2, r_end, 0, 0, 1.5 * MM))
    _drill(link, holes)
    return PartSpec((0, 0, 0), (p, 0, 0), r_bore)


def counterbored_chamfered_link() -> PartSpec:
    """A 76.2 mm pitch link whose fixed bore is counterbored (a 16 mm, 4 mm deep relief meeting the
    10 mm through hole) and whose loaded bore is chamfered 1 mm at both ends; two counterbored M6
    screw holes between them."""
    p, t, r_end, r_bore = 76.2 * MM, 14 * MM, 15 * MM, 5 * MM
    occ = gmsh.model.occ
    link = _stadium(p, r_end, t)
    holes = [_through_z(x, 0, r_bore, -t, 2 * t) for x in (0, p)]
    holes.append(_through_z(0, 0, 8 * MM, t - 4 * MM, 2 * t))
    c = 1 * MM
    holes += [
        occ.addCone(p, 0, z0, 0, 0, dz, r0, r1)
        for z0, dz, r0, r1 in ((-c, 2 * c, r_bore + 2 * c, r_bore), (t - c, 2 * c, r_bore, r_bore + 2 * c))
    ]
    for x in (p / 2 - 12 * MM, p / 2 + 12 * MM):
        holes.append(_through_z(x, 0, 3.3 * MM, -t, 2 * t))
        holes.append(_through_z(x, 0, 5.5 * MM, t - 6.5 * MM, 2 * t))
    _drill(link, holes)
    return PartSpec((0, 0, 0), (p, 0, 0), r_bore)


def roller_chain_plate() -> PartSpec:
    """An ANSI 40 (12.7 mm pitch) pin-link plate: figure-eight outline of two 6 mm round ends with a
    waisted middle, 1.5 mm thick, 3.96 mm pin holes."""
    p, t, r_end, r_hole = 12.7 * MM, 1.5 * MM, 6 * MM, 1.98 * MM
    plate = _stadium(p, r_end, t)
    waist = [_through_z(p / 2, s * 9.2 * MM, 5 * MM, -t, 2 * t) for s in (-1, 1)]
    holes = [_through_z(x, 0, r_hole, -t, 2 * t) for x in (0, p)]
    _drill(plate, waist + holes)
    return PartSpec((0, 0, 0), (p, 0, 0), r_hole)


def long_link() -> PartSpec:
    """A 300 mm long conveyor link: 250 mm pitch, 25 mm end radius, 20 mm thick, 20 mm pin bores,
    and two 30 mm lightening holes between them (a larger equal pair that is not the pins)."""
    p, t, r_end, r_bore = 250 * MM, 20 * MM, 25 * MM, 10 * MM
    link = _stadium(p, r_end, t)
    holes = [_through_z(x, 0, r_bore, -t, 2 * t) for x in (0, p)]
    holes += [_through_z(x, 0, 15 * MM, -t, 2 * t) for x in (90 * MM, 160 * MM)]
    _drill(link, holes)
    return PartSpec((0, 0, 0), (p, 0, 0), r_bore)


def link_with_pins_and_bushings() -> PartSpec:
    """An assembly of five solids: a 76.2 mm pitch link (16 mm bores, body first in the file), two
    steel bushings pressed into its bores (16 mm outside, 10 mm inside, 2 mm proud each side) and
    two 10 mm pins through them (4 mm longer than the bushings each side)."""
    p, t, r_end, r_bore, r_pin = 76.2 * MM, 14 * MM, 16 * MM, 8 * MM, 5 * MM
    link = _stadium(p, r_end, t)
    _drill(link, [_through_z(x, 0, r_bore, -t, 2 * t) for x in (0, p)])
    for x in (0, p):
        outer = _through_z(x, 0, r_bore, -2 * MM, t + 2 * MM)
        _drill(outer, [_through_z(x, 0, r_pin, -t, 2 * t)])
    for x in (0, p):
        _through_z(x, 0, r_pin, -6 * MM, t + 6 * MM)
    return PartSpec((0, 0, 0), (p, 0, 0), r_bore, n_solids=5)


def four_equal_holes() -> PartSpec:
    """A 100 x 40 x 12 mm plate with four equal 10 mm holes at the corners of a 70 x 20 mm
    rectangle: its two diagonals are equal candidate pin pairs (ambiguous)."""
    occ = gmsh.model.occ
    plate = occ.addBox(-15 * MM, -20 * MM, 0, 100 * MM, 40 * MM, 12 * MM)
    _drill(plate, [_through_z(x, y, 5 * MM, -MM, 13 * MM) for x in (0, 70 * MM) for y in (-10 * MM, 10 * MM)])
    return PartSpec((0, -10 * MM, 0), (70 * MM, 10 * MM, 0), 5 * MM)


def half_bore_rod() -> PartSpec:
    """A connecting rod drawn without its cap: a full small-end bore and an open half big-end bore."""
    p, t = 80 * MM, 12 * MM
    occ = gmsh.model.occ
    rod = _stadium(p, 15 * MM, t)
    big = _through_z(p, 0, 10 * MM, -t, 2 * t)
    cap_side = occ.addBox(p, -20 * MM, -t, 30 * MM, 40 * MM, 3 * t)
    _drill(rod, [_through_z(0, 0, 5 * MM, -t, 2 * t), big, cap_side])
    return PartSpec((0, 0, 0), (p, 0, 0), 5 * MM)


def perforated_plate() -> PartSpec:
    """Not a link: a 900 x 60 x 10 mm plate with 300 holes of growing size (a 2.8 MB STEP of 861
    faces), for the time a refusal takes. Its spec names the two largest holes, which are no pair."""
    occ = gmsh.model.occ
    n = 150
    plate = occ.addBox(0, 0, 0, n * 6 * MM, 60 * MM, 10 * MM)
    holes = [
        occ.addCylinder((3 + 6 * i) * MM, (10 + 40 * (i % 2)) * MM, -MM, 0, 0, 12 * MM, (1 + 0.05 * i) * MM)
        for i in range(n)
    ]
    holes += [occ.addCylinder((3 + 6 * i) * MM, 30 * MM, 5 * MM, 0, 0, 6 * MM, (1.5 + 0.05 * i) * MM) for i in range(n)]
    _drill(plate, holes)
    return PartSpec(((n * 6 - 3) * MM, 50 * MM, 0), ((n * 6 - 3) * MM, 30 * MM, 0), 8.45 * MM)


PARTS = {
    "nest_holes": conveyor_link_with_nest_holes,
    "counterbored": counterbored_chamfered_link,
    "chain_plate": roller_chain_plate,
    "long_link": long_link,
    "assembly": link_with_pins_and_bushings,
    "ambiguous": four_equal_holes,
    "half_bore": half_bore_rod,
    "perforated_plate": perforated_plate,
}


def write_part(name: str, path: Path) -> tuple[PartSpec, list[float]]:
    """Build part `name`, export it to `path` (mm STEP); its spec and each solid's CAD volume (m^3)."""
    with gmsh_model(f"part-{name}"):
        spec = PARTS[name]()
        gmsh.model.occ.synchronize()
        volumes = [gmsh.model.occ.getMass(3, tag) for _, tag in gmsh.model.getEntities(3)]
        write_model_step(path, unit="mm")
    return spec, volumes


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m geometry.sample_parts",
        description="Write real-world-shaped sample parts as millimetre STEP files.",
    )
    parser.add_argument("out", type=Path, help="folder for NAME.step (created if missing)")
    parser.add_argument("names", nargs="*", metavar="NAME", help=f"parts to write (default: all): {', '.join(PARTS)}")
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in PARTS]
    if unknown:
        parser.exit(2, f"{parser.prog}: error: unknown part {unknown[0]!r}; expected one of {', '.join(PARTS)}\n")
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.names or PARTS:
        path = args.out / f"{name}.step"
        _, volumes = write_part(name, path)
        print(f"{path}: {len(volumes)} solid(s), {sum(volumes) * 1e6:.3f} cm^3")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
