"""Which two holes of a part carry the pins.

Real links have other holes: tapped holes for the nest, a grease hole, screw holes for end caps,
counterbores and chamfers on the pin bores themselves. The rule, in order:

1. Coaxial holes are one bore: a counterbore (or any larger coaxial relief) belongs to the through
   hole it meets, and the bore is that through hole (the smallest radius on the axis: the pin has
   to pass it).
2. Candidate pairs are two bores with parallel axes and equal radius (within 1 %), more than the
   sum of their radii apart.
3. Pins sit at the ends of a link: only pairs at the ends of the part count (it reaches no more
   than one pitch beyond either bore, along the line joining them, and that line runs along the
   part's length: the pitch spans at least 30 % of the part's extent along its principal axis, so two
   screw holes across one end of a long part are not a pair), so lightening holes and nest
   screw holes between the pins lose even when they are larger, and a plate full of holes is not
   taken for a link. Then the largest radius wins (end-cap screw holes on the lugs are smaller
   than the pins), then the pair farthest apart. With --pitch or --bore-radius, pairs away from
   the ends count too (ends still first).
4. If two pairs tie on all three (radius within 1 %, pitch within 0.1 %), the choice is ambiguous
   and refused with the list; so are parts with no candidate pair.

`BoreChoice` narrows the candidates from the command line: `--bores` names the two axes by a point
on each (the first is the fixed bore), `--pitch` and `--bore-radius` keep only pairs of that pitch
and radius. Open holes (a half bore of a connecting rod drawn without its cap) are never pins: the
pull load case needs a full bore, so the largest open hole that reaches at least half way round is
named in the refusal, with its radius and centre (the feature a person would name, not a pocket's
rounded end).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from geometry.bores import DetectedBore, Holes, order_pair
from geometry.errors import GeometryError

EQUAL_RADIUS_TOL = 0.01  # relative: two bores of one pin size (drawn H7 vs a clearance fit still count)
EQUAL_PITCH_TOL = 1e-3  # relative: two pairs this close in pitch (and radius) are a tie
PITCH_MATCH_TOL = 0.01  # relative: how close --pitch must be to a pair's pitch
# The pins sit at the two ends of the part's length: the pitch, projected on the part's principal
# axis, spans at least this fraction of the part's extent along it (a link's pitch spans 60-90 %
# of its length, a bar reaching one pitch beyond each bore a third; two holes across one end of
# a long part span next to nothing of it).
LENGTH_SPAN_FRACTION = 0.3
# An open hole is named in a refusal only if its faces reach at least this far round (a half bore
# drawn without its cap spans 180 deg; a pocket's rounded end or a slot end can span less).
HALF_ROUND_DEG = 175.0
_PARALLEL_TOL = 1e-6  # 1 - |cos| of the angle between two parallel axes
BORES_HINT = "--bores X1,Y1,Z1:X2,Y2,Z2 (a point on each pin axis in mm, fixed bore first)"
CHOOSE_HINT = f"pass {BORES_HINT} or --pitch MM --bore-radius MM to choose"


@dataclass(frozen=True)
class BoreChoice:
    """What the user said about the pin bores (metres); all None: choose by the rule above."""

    fixed_point_m: tuple[float, float, float] | None = None
    loaded_point_m: tuple[float, float, float] | None = None
    pitch_m: float | None = None
    radius_m: float | None = None

    def __post_init__(self) -> None:
        if (self.fixed_point_m is None) != (self.loaded_point_m is None):
            raise GeometryError(f"--bores: expected two axis points, got one; expected {BORES_HINT}")
        for name, value in (("--pitch", self.pitch_m), ("--bore-radius", self.radius_m)):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise GeometryError(f"{name}: expected a positive length in mm, got {value * 1e3:g}")

    @property
    def given(self) -> bool:
        return any(v is not None for v in (self.fixed_point_m, self.pitch_m, self.radius_m))

    def describe(self) -> str:
        parts = []
        if self.fixed_point_m is not None:
            parts.append(f"--bores {_mm(self.fixed_point_m)}:{_mm(self.loaded_point_m)}")
        if self.pitch_m is not None:
            parts.append(f"--pitch {self.pitch_m * 1e3:g}")
        if self.radius_m is not None:
            parts.append(f"--bore-radius {self.radius_m * 1e3:g}")
        return " ".join(parts)


@dataclass(frozen=True)
class IgnoredHole:
    hole: DetectedBore
    reason: str


@dataclass(frozen=True)
class PinBores:
    """The chosen pair, how it was chosen, and every other hole with why it was not a pin bore."""

    fixed: DetectedBore
    loaded: DetectedBore
    rule: str
    ignored: tuple[IgnoredHole, ...]

    @property
    def pitch_m(self) -> float:
        return _axis_distance(self.fixed, self.loaded)


def select_pin_bores(holes: Holes, choice: BoreChoice, source: str) -> PinBores:
    """The pin bores among the part's holes (module docstring: the rule); GeometryError if none or ambiguous."""
    bores, reliefs = _merge_coaxial(list(holes.full))
    if choice.fixed_point_m is not None:
        fixed = _bore_at(bores, choice.fixed_point_m, holes, source)
        loaded = _bore_at(bores, choice.loaded_point_m, holes, source)
        if fixed is loaded:
            raise GeometryError(
                f"{source}: both --bores points lie on the bore at {_mm(fixed.bore.center_m)} mm; "
                "expected one point on each pin axis"
            )
        _check_pair(fixed, loaded, source)
        pair, rule = (fixed, loaded), f"given by {choice.describe()}{_unequal_note(fixed, loaded)}"
    else:
        pair, rule = _best_pair(bores, holes, choice, source)
        pair = order_pair(*pair, source)
    ignored = tuple(
        IgnoredHole(h, _reason(h, pair, named=choice.fixed_point_m is not None))
        for h in bores
        if all(h is not p for p in pair)
    )
    ignored += tuple(
        IgnoredHole(h, f"coaxial relief (counterbore) of the bore at {_mm(of.bore.center_m)} mm") for h, of in reliefs
    )
    ignored += tuple(
        IgnoredHole(h, f"open bore (spans about {angle:.0f} deg, not a full round)") for h, angle in holes.open
    )
    return PinBores(pair[0], pair[1], rule, ignored)


def _merge_coaxial(full: list[DetectedBore]) -> tuple[list[DetectedBore], list[tuple[DetectedBore, DetectedBore]]]:
    """The smallest hole on each axis line, and the larger coaxial ones with the hole they relieve."""
    full = sorted(full, key=lambda h: h.bore.radius_m)
    bores: list[DetectedBore] = []
    reliefs: list[tuple[DetectedBore, DetectedBore]] = []
    for hole in full:
        through = next((b for b in bores if _coaxial(b, hole)), None)
        if through is None:
            bores.append(hole)
        else:
            reliefs.append((hole, through))
    return bores, reliefs


def pair_rank(holes: Holes, choice: BoreChoice) -> tuple[float, float] | None:
    """(radius, pitch) of the pin pair this solid offers under `choice`, None if it has none: in an
    assembly the link body is the solid with the best-ranked pair (the same rule across solids)."""
    bores, _ = _merge_coaxial(list(holes.full))
    if choice.fixed_point_m is not None:
        try:
            pair = (_bore_at(bores, choice.fixed_point_m, holes, ""), _bore_at(bores, choice.loaded_point_m, holes, ""))
        except GeometryError:
            return None
        return None if pair[0] is pair[1] else (_radius(pair), _axis_distance(*pair))
    pairs = _candidate_pairs(bores, holes, choice)
    return (_radius(pairs[0]), _axis_distance(*pairs[0])) if pairs else None


def _candidate_pairs(
    bores: list[DetectedBore], holes: Holes, choice: BoreChoice
) -> list[tuple[DetectedBore, DetectedBore]]:
    """Pairs of equal parallel bores matching --pitch / --bore-radius, best first (rule 3)."""
    pairs = [(a, b) for i, a in enumerate(bores) for b in bores[i + 1 :] if _is_candidate_pair(a, b)]
    if choice.pitch_m is not None:
        pairs = [p for p in pairs if abs(_axis_distance(*p) - choice.pitch_m) <= PITCH_MATCH_TOL * choice.pitch_m]
    if choice.radius_m is not None:
        pairs = [p for p in pairs if abs(p[0].bore.radius_m - choice.radius_m) <= EQUAL_RADIUS_TOL * choice.radius_m]
    if not choice.given:  # unasked, only pairs at the ends: a plate full of holes is not taken for a link
        pairs = [p for p in pairs if _at_the_ends(p, holes)]
    return sorted(pairs, key=lambda p: (not _at_the_ends(p, holes), -_radius(p), -_axis_distance(*p)))


def _at_the_ends(pair: tuple[DetectedBore, DetectedBore], holes: Holes) -> bool:
    """The part reaches no more than one pitch beyond either bore along the line joining them."""
    a, b = pair[0].bore, pair[1].bore
    offset = b.center_m - a.center_m
    offset = offset - (offset @ a.axis) * a.axis
    pitch = float(np.linalg.norm(offset))
    direction = offset / pitch
    lo, hi = holes.reach_m(direction)
    beyond = max(float(a.center_m @ direction) - lo, hi - float(b.center_m @ direction))
    return beyond <= (1 + 1e-9) * pitch and _spans_the_length(pair, holes)


def principal_axis(holes: Holes, pin_axis: np.ndarray) -> np.ndarray:
    """The part's length direction normal to the pin axis: the principal axis (largest variance) of
    its outline projected on the plane normal to the pins."""
    points = holes.outline_m - holes.outline_m.mean(axis=0)
    points = points - np.outer(points @ pin_axis, pin_axis)
    _, _, vt = np.linalg.svd(points, full_matrices=False)
    return vt[0]


def _spans_the_length(pair: tuple[DetectedBore, DetectedBore], holes: Holes) -> bool:
    """The pitch spans at least LENGTH_SPAN_FRACTION of the part's extent along its principal axis."""
    a, b = pair[0].bore, pair[1].bore
    length_axis = principal_axis(holes, a.axis)
    lo, hi = holes.reach_m(length_axis)
    return abs(float((b.center_m - a.center_m) @ length_axis)) >= LENGTH_SPAN_FRACTION * (hi - lo)


def ends_used(pair: tuple[DetectedBore, DetectedBore], holes: Holes) -> str:
    """Which ends of the part the pins were taken at, in words (mm)."""
    length_axis = principal_axis(holes, pair[0].bore.axis)
    lo, hi = holes.reach_m(length_axis)
    direction = ",".join(f"{round(x, 3) + 0.0:g}" for x in length_axis)
    return f"the ends of its length: along ({direction}), {(hi - lo) * 1e3:.1f} mm"


def _best_pair(bores: list[DetectedBore], holes: Holes, choice: BoreChoice, source: str):
    pairs = _candidate_pairs(bores, holes, choice)
    rule = "equal parallel bores at the part's ends, the largest such, farthest apart"
    if choice.given:
        rule = f"{rule}, among those matching {choice.describe()}"
    if not pairs:
        raise GeometryError(_no_pair_message(bores, holes, choice, source))
    best = pairs[0]
    ties = [
        p
        for p in pairs
        if _at_the_ends(p, holes) == _at_the_ends(best, holes)
        and _radius(p) >= (1 - EQUAL_RADIUS_TOL) * _radius(best)
        and _axis_distance(*p) >= (1 - EQUAL_PITCH_TOL) * _axis_distance(*best)
    ]
    rule = f"{rule}; {ends_used(best, holes)}"
    if len(ties) > 1:
        listed = " or ".join(f"{_mm(a.bore.center_m)}:{_mm(b.bore.center_m)}" for a, b in ties)
        raise GeometryError(
            f"{source}: {len(ties)} equally good pin-bore pairs (radius {_radius(best) * 1e3:.3f} mm, pitch "
            f"{_axis_distance(*best) * 1e3:.3f} mm): {listed} mm; ambiguous, pass {BORES_HINT} to choose"
        )
    return best, rule


def _no_pair_message(bores: list[DetectedBore], holes: Holes, choice: BoreChoice, source: str) -> str:
    wanted = f" matching {choice.describe()}" if choice.given else " at the part's ends"
    message = f"{source}: no pair of equal parallel full-round bores{wanted} (full round holes, mm: {_listed(bores)})"
    open_bore = largest_open_bore(holes)
    if open_bore is not None:
        hole, angle = open_bore
        return (
            f"{message}; the r {hole.bore.radius_m * 1e3:.4g} mm bore at {_mm(hole.bore.center_m)} mm is open (about "
            f"{angle:.0f} deg, {'a half bore' if angle < 200 else 'not a full round'}) and the pull load case needs a full bore: draw its cap as part of "
            "the solid (or pass --bores to name two full bores)"
        )
    return f"{message}; expected two pin bores ({CHOOSE_HINT})"


def largest_open_bore(holes: Holes) -> tuple[DetectedBore, float] | None:
    """The largest open hole reaching at least HALF_ROUND_DEG round (the half bore a person would
    name), with its span in degrees; None if there is none."""
    half_round = [(hole, angle) for hole, angle in holes.open if angle >= HALF_ROUND_DEG]
    return max(half_round, key=lambda ha: ha[0].bore.radius_m, default=None)


def _bore_at(bores: list[DetectedBore], point_m, holes: Holes, source: str) -> DetectedBore:
    """The bore whose axis passes within its radius of the point (the nearest such)."""
    point = np.asarray(point_m, float)
    near = [(float(_distance_to_axis(h, point)), h) for h in bores]
    near = [(d, h) for d, h in near if d < h.bore.radius_m]
    if near:
        return min(near, key=lambda dh: dh[0])[1]
    for hole, angle in holes.open:
        if _distance_to_axis(hole, point) < hole.bore.radius_m:
            raise GeometryError(
                f"--bores: the point {_mm(point)} mm is on an open bore (about {angle:.0f} deg, a half bore); the pull "
                "load case needs a full bore: draw its cap as part of the solid"
            )
    raise GeometryError(
        f"--bores: no full-round bore of {source} has its axis within its radius of {_mm(point)} mm "
        f"(bores, mm: {_listed(bores)}); expected {BORES_HINT}"
    )


def _listed(bores: list[DetectedBore], most: int = 6) -> str:
    """The holes, largest first, at most `most` of them (the message stays one readable line)."""
    largest = sorted(bores, key=lambda h: -h.bore.radius_m)
    text = ", ".join(f"r {h.bore.radius_m * 1e3:.3f} at {_mm(h.bore.center_m)}" for h in largest[:most]) or "none"
    return text + (f" and {len(bores) - most} smaller" if len(bores) > most else "")


def _unequal_note(fixed: DetectedBore, loaded: DetectedBore) -> str:
    """How the pull load case treats two bores of different radii (empty for equal ones)."""
    r_fixed, r_loaded = fixed.bore.radius_m, loaded.bore.radius_m
    if abs(r_fixed - r_loaded) <= EQUAL_RADIUS_TOL * max(r_fixed, r_loaded):
        return ""
    return (
        f"; unequal bores: the fixed one (r {r_fixed * 1e3:.4g} mm) is clamped all round, the loaded one (r "
        f"{r_loaded * 1e3:.4g} mm) carries the cosine bearing pressure of a pin of its own radius, pulling along the "
        "line between the axes; each bore is meshed for its own radius"
    )


def _check_pair(a: DetectedBore, b: DetectedBore, source: str) -> None:
    if not _parallel(a, b):
        raise GeometryError(
            f"--bores: the bores at {_mm(a.bore.center_m)} and {_mm(b.bore.center_m)} mm of {source} are not "
            "parallel; expected the two parallel pin bores"
        )


def _is_candidate_pair(a: DetectedBore, b: DetectedBore) -> bool:
    equal = abs(a.bore.radius_m - b.bore.radius_m) <= EQUAL_RADIUS_TOL * max(a.bore.radius_m, b.bore.radius_m)
    return equal and _parallel(a, b) and _axis_distance(a, b) > a.bore.radius_m + b.bore.radius_m


def _reason(hole: DetectedBore, pair: tuple[DetectedBore, DetectedBore], named: bool) -> str:
    pin = pair[0].bore.radius_m
    r = hole.bore.radius_m
    if named:
        return "not named by --bores"
    if not _parallel(hole, pair[0]):
        return "not parallel to the pins"
    if r < (1 - EQUAL_RADIUS_TOL) * pin:
        return "smaller than the pin bores"
    size = "larger than" if r > (1 + EQUAL_RADIUS_TOL) * pin else "same size as"
    line = pair[1].bore.center_m - pair[0].bore.center_m
    along = float((hole.bore.center_m - pair[0].bore.center_m) @ line / (line @ line))
    if 0 < along < 1:
        return f"{size} the pin bores, between them (pins sit at the part's ends)"
    return f"{size} the pin bores, with no partner of its radius at the part's ends"


def _radius(pair: tuple[DetectedBore, DetectedBore]) -> float:
    return min(pair[0].bore.radius_m, pair[1].bore.radius_m)


def _parallel(a: DetectedBore, b: DetectedBore) -> bool:
    return 1 - abs(float(a.bore.axis @ b.bore.axis)) < _PARALLEL_TOL


def _distance_to_axis(hole: DetectedBore, point: np.ndarray) -> float:
    rel = point - hole.bore.center_m
    return float(np.linalg.norm(rel - (rel @ hole.bore.axis) * hole.bore.axis))


def _axis_distance(a: DetectedBore, b: DetectedBore) -> float:
    return _distance_to_axis(a, b.bore.center_m)


def _coaxial(a: DetectedBore, b: DetectedBore) -> bool:
    return _parallel(a, b) and _axis_distance(a, b) < 1e-3 * min(a.bore.radius_m, b.bore.radius_m)


def _mm(point_m) -> str:
    # rounded to 0.1 um so that round-off (-7e-14 mm) does not clutter the messages
    return ",".join(f"{round(x * 1e3, 4) + 0.0:.6g}" for x in np.asarray(point_m, float))
