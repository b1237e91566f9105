"""A STEP file as a designer sends it: one link, or the link with its hardware as separate solids.

The link body is the solid that holds the pin bores (geometry.pin_pair's rule applied to every
solid: the body is the solid with the best-ranked pair, so a nest with four small screw holes does
not compete with the link). Every other solid is hardware (pins, bushings, rollers, the nest):
its volume is reported, and with a density its mass, but it is not meshed: solids that touch the
link (a pin in its bore, a bushing pressed in) are not fused into its stiffness, which is the
link body's alone.

`inspect_part` does this without meshing, in about the time the import takes, so a part that
cannot be a link is refused at once and the choice of bores is printed before any FEA.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import gmsh
import numpy as np

from geometry.bores import find_holes
from geometry.errors import GeometryError
from geometry.pin_pair import EQUAL_PITCH_TOL, EQUAL_RADIUS_TOL, BoreChoice, PinBores, pair_rank, select_pin_bores

TOUCH_DISTANCE_M = 1e-6  # solids closer than this touch the body (a pin in its bore: distance 0)


@dataclass(frozen=True)
class LinkSource(os.PathLike):
    """A STEP file with what the user said about it: the pin bores (--bores, --pitch, --bore-radius)
    and which solid is the link body (--body, 1-based in file order). Path-like, so it goes wherever
    a STEP path does."""

    path: Path
    bores: BoreChoice = field(default_factory=BoreChoice)
    body: int | None = None

    def __fspath__(self) -> str:
        return str(self.path)

    def __str__(self) -> str:
        return str(self.path)


@dataclass(frozen=True)
class HardwareSolid:
    index: int  # 1-based, in file order
    volume_m3: float
    centre_m: np.ndarray  # (3,) centre of mass
    touches_body: bool


@dataclass(frozen=True)
class PartSummary:
    """What `inspect_part` found: the body, its pin bores and ignored holes, the hardware."""

    source: str
    n_solids: int
    body_index: int  # 1-based, in file order
    body_volume_m3: float
    pins: PinBores
    hardware: tuple[HardwareSolid, ...]

    def as_dict(self) -> dict:
        """JSON-able, SI units."""
        pins = self.pins
        return {
            "solids": self.n_solids,
            "body_solid": self.body_index,
            "body_volume_m3": self.body_volume_m3,
            "pin_bores": {
                "fixed_axis_point_m": pins.fixed.bore.center_m.tolist(),
                "loaded_axis_point_m": pins.loaded.bore.center_m.tolist(),
                "axis": pins.fixed.bore.axis.tolist(),
                "radius_m": pins.fixed.bore.radius_m,
                "pitch_m": pins.pitch_m,
                "rule": pins.rule,
            },
            "ignored_holes": [
                {"axis_point_m": h.hole.bore.center_m.tolist(), "radius_m": h.hole.bore.radius_m, "reason": h.reason}
                for h in pins.ignored
            ],
            "hardware": [
                {
                    "solid": s.index,
                    "volume_m3": s.volume_m3,
                    "centre_m": s.centre_m.tolist(),
                    "touches_body": s.touches_body,
                }
                for s in self.hardware
            ],
        }

    def lines(self) -> list[str]:
        """The choice in words, millimetres: pin bores, rule, ignored holes, hardware."""
        pins = self.pins
        lines = [
            f"pin bores       fixed at ({_mm(pins.fixed.bore.center_m)}) mm, loaded at ({_mm(pins.loaded.bore.center_m)}) mm, "
            f"radius {pins.fixed.bore.radius_m * 1e3:.3f} mm, pitch {pins.pitch_m * 1e3:.3f} mm ({pins.rule})"
        ]
        for ignored in pins.ignored:
            bore = ignored.hole.bore
            lines.append(
                f"  ignored hole  r {bore.radius_m * 1e3:.3f} mm at ({_mm(bore.center_m)}) mm: {ignored.reason}"
            )
        if self.n_solids > 1:
            lines.append(
                f"link body       solid {self.body_index} of {self.n_solids} ({self.body_volume_m3 * 1e6:.3f} cm^3); "
                "the other solids are hardware, not meshed and not fused into k"
            )
            for s in self.hardware:
                touch = "touches the body" if s.touches_body else "apart from the body"
                lines.append(
                    f"  hardware      solid {s.index}: {s.volume_m3 * 1e6:.3f} cm^3 at ({_mm(s.centre_m)}) mm, {touch}"
                )
        return lines


def as_link_source(source: str | os.PathLike) -> LinkSource:
    return source if isinstance(source, LinkSource) else LinkSource(Path(source))


def pick_body(volumes: list[int], source: LinkSource, name: str) -> tuple[int, PinBores]:
    """The link body among the imported solids and its pin bores; GeometryError if none or ambiguous."""
    choice = source.bores
    if source.body is not None:
        if not 1 <= source.body <= len(volumes):
            raise GeometryError(
                f"--body {source.body}: {name} holds {len(volumes)} solid(s); expected a solid number "
                f"from 1 to {len(volumes)} (file order)"
            )
        body = volumes[source.body - 1]
        return body, select_pin_bores(find_holes([body]), choice, name)
    if len(volumes) == 1:
        return volumes[0], select_pin_bores(find_holes(volumes), choice, name)
    holes = {v: find_holes([v]) for v in volumes}
    ranks = {v: pair_rank(holes[v], choice) for v in volumes}
    ranked = sorted((rank, v) for v, rank in ranks.items() if rank is not None)
    if not ranked:
        raise GeometryError(
            f"{name}: none of its {len(volumes)} solids holds a pair of equal parallel pin bores; "
            "expected the link body among them (pass --body N to name it, "
            "--bores X1,Y1,Z1:X2,Y2,Z2 to give its bores)"
        )
    (best_rank, body), *others = reversed(ranked)
    tied = [volumes.index(v) + 1 for rank, v in others if _same_rank(rank, best_rank)]
    if tied:
        numbers = ", ".join(str(i) for i in sorted([volumes.index(body) + 1] + tied))
        raise GeometryError(
            f"{name}: solids {numbers} each hold an equally good pair of pin bores (radius "
            f"{best_rank[0] * 1e3:.3f} mm, pitch {best_rank[1] * 1e3:.3f} mm); ambiguous, pass --body N "
            "(1-based, file order) to name the link body"
        )
    return body, select_pin_bores(holes[body], choice, name)


def hardware_solids(volumes: list[int], body: int) -> tuple[HardwareSolid, ...]:
    solids = []
    for index, v in enumerate(volumes, start=1):
        if v == body:
            continue
        distance = gmsh.model.occ.getDistance(3, body, 3, v)[0]
        solids.append(
            HardwareSolid(
                index,
                float(gmsh.model.occ.getMass(3, v)),
                np.array(gmsh.model.occ.getCenterOfMass(3, v)),
                0 <= distance < TOUCH_DISTANCE_M,
            )
        )
    return tuple(solids)


def inspect_part(source: str | os.PathLike) -> PartSummary:
    """Import the part, pick the link body and its pin bores, measure the hardware; no meshing
    (`geometry.part.resolve_part`'s summary)."""
    from geometry.part import resolve_part

    return resolve_part(source, symmetry=False).summary


def _same_rank(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return abs(a[0] - b[0]) <= EQUAL_RADIUS_TOL * b[0] and abs(a[1] - b[1]) <= EQUAL_PITCH_TOL * b[1]


def _mm(point_m: np.ndarray) -> str:
    return ", ".join(f"{round(x * 1e3, 2) + 0.0:.2f}" for x in point_m)  # + 0.0: no "-0.00"
