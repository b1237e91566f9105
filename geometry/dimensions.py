"""The built-in parametric link and its calibration against the 2012 report.

The report's sponsor link (sections 2.1.5, 4.1.1, 4.1.2) is not available, only its figures: pin
pitch 112.5 mm, main body 0.11 x 0.08 x 0.03 m, thinnest section (at the recess)
6.858 x 74.93 mm, FEA stiffness k = 9.27e7 N/m in 6061-T6 aluminium, and link masses 1.10 kg in
aluminium (2700 kg/m3) and 1.35 kg in titanium (4510 kg/m3).

The default link is a simplified single link with those figures (x along the pitch line, y across
the link, z along the pin axes; bores at x = -pitch/2 and +pitch/2, z from 0 to the body height):

- a main body box `body_length_m x body_width_m x body_height_m` = 110 x 80 x 30 mm;
- a lug at each end: a tongue of width 2 * `lug_radius_m` and a half disc of that radius around the
  bore, the full body height (the lug's rounded end is a convex cylinder coaxial with the bore);
- a through bore of `bore_radius_m` at each lug (the pins, bushings and rollers are not modelled);
- a recess pocketed from the top, `recess_length_m x recess_width_m`, leaving a floor
  (web) of `web_thickness_m`, so the thinnest section is the web, 6.858 x 74.93 mm, plus the two
  side rails of (body_width_m - recess_width_m) / 2 that the pocket leaves standing;
- fillets at every re-entrant corner, as a machine shop cuts an aluminium link: the CNC design
  rule "internal vertical corner radius >= 1/3 of the cut's depth" (e.g. Hubs' CNC machining
  design guide) gives the pocket's vertical corners `pocket_corner_radius_m` = 8 mm (23.1 mm deep)
  and the lug necks, where the outer profile is cut through the 30 mm body, `lug_fillet_radius_m`
  = 10 mm; the pocket floor edges get `pocket_floor_radius_m` = 1 mm (a bull-nose end mill's corner,
  below the wall radii and the 2.5 mm rails). 0 gives a sharp corner (the link before fillets).

Calibration (two unknowns, two conditions):

1. Mass. Both report masses are body plus the same steel hardware, m = rho * V + m_hw, so
   V = (1.35 - 1.10) / (4510 - 2700) = 1.3812e-4 m3 and m_hw = 1.10 - 2700 V = 0.7271 kg
   (`DEFAULT_HARDWARE_MASS_KG`). Given the other dimensions, the recess length is solved from the
   closed-form volume (`nominal_volume_m3`, fillets included; `recess_length_for_volume`) for
   that V: 81.233 mm.
2. Stiffness. The pins load the link over its full height while the web lies at the bottom, so
   the web and the two 2.535 mm side rails the recess leaves standing bend under the eccentric
   load: that, not the web's AE/L (3.147e8 N/m, report equation 8), sets k. With the volume fixed,
   a larger bore shortens the recess and stiffens the link; the bore radius was chosen by P2 FEA of
   the issue's load case (fixed bore clamped, cosine bearing pressure on the loaded bore,
   k = F^2 / 2U) in 6061-T6 (E = 68.9 GPa, nu = 0.33). The sharp-cornered link had r = 9.525 mm
   (3/4 inch) and k = 9.01e7 N/m (-2.8 %); the fillets stiffen the lug necks (9.63e7 N/m at that
   bore), and r = 8.731 mm (an 11/16 inch bushing bore) gives `python -m fem` k = 9.32e7 N/m
   (+-0.9 %): +0.6 % against the report's 9.27e7. (Titanium, E = 105 GPa, nu = 0.37: 1.416e8 N/m
   against the report's 1.439e8.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from geometry.errors import GeometryError

FILLET_FIELDS = ("lug_fillet_radius_m", "pocket_corner_radius_m", "pocket_floor_radius_m")

AL_DENSITY_KG_PER_M3 = 2700.0
TI_DENSITY_KG_PER_M3 = 4510.0
REPORT_LINK_MASS_AL_KG = 1.10
REPORT_LINK_MASS_TI_KG = 1.35

#: Body volume that, with one fixed hardware mass, reproduces both report masses.
CALIBRATED_BODY_VOLUME_M3 = (REPORT_LINK_MASS_TI_KG - REPORT_LINK_MASS_AL_KG) / (
    TI_DENSITY_KG_PER_M3 - AL_DENSITY_KG_PER_M3
)
#: Steel pins, bushings and rollers carried by one link (the part of the report's link mass that
#: does not change with the body material).
DEFAULT_HARDWARE_MASS_KG = REPORT_LINK_MASS_AL_KG - AL_DENSITY_KG_PER_M3 * CALIBRATED_BODY_VOLUME_M3
#: The nest (payload fixture) on each link, report section 2.1.5.
NEST_MASS_KG = 0.93


@dataclass(frozen=True)
class LinkDimensions:
    """Dimensions of the parametric link, in metres (see the module docstring for the shape)."""

    pitch_m: float = 0.1125
    body_length_m: float = 0.110
    body_width_m: float = 0.080
    body_height_m: float = 0.030
    bore_radius_m: float = 0.00873125
    lug_radius_m: float = 0.016
    recess_length_m: float = 0.081233
    recess_width_m: float = 0.07493
    web_thickness_m: float = 0.006858
    lug_fillet_radius_m: float = 0.010
    pocket_corner_radius_m: float = 0.008
    pocket_floor_radius_m: float = 0.001

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            lowest = 0.0 if f.name in FILLET_FIELDS else None  # a fillet radius of 0 is a sharp corner
            if not (
                isinstance(value, (int, float))
                and math.isfinite(value)
                and (value >= 0 if lowest == 0.0 else value > 0)
            ):
                expected = "a length >= 0 in metres (0: sharp)" if lowest == 0.0 else "a positive length in metres"
                raise GeometryError(f"LinkDimensions.{f.name}={value!r}: expected {expected}")
        checks = [
            (self.bore_radius_m < self.lug_radius_m, "bore_radius_m < lug_radius_m"),
            (2 * self.lug_radius_m < self.body_width_m, "2 * lug_radius_m < body_width_m"),
            (self.body_length_m <= self.pitch_m, "body_length_m <= pitch_m (bores in the lugs)"),
            (self.recess_width_m < self.body_width_m, "recess_width_m < body_width_m"),
            (self.web_thickness_m < self.body_height_m, "web_thickness_m < body_height_m"),
            (
                self.recess_length_m / 2 < self.pitch_m / 2 - self.bore_radius_m,
                "recess_length_m / 2 < pitch_m / 2 - bore_radius_m (recess clear of the bores)",
            ),
            (
                2 * self.pocket_corner_radius_m < min(self.recess_length_m, self.recess_width_m),
                "2 * pocket_corner_radius_m < recess_length_m and recess_width_m",
            ),
            (
                self.pocket_floor_radius_m <= self.pocket_corner_radius_m or self.pocket_corner_radius_m == 0,
                "pocket_floor_radius_m <= pocket_corner_radius_m",
            ),
            (
                self.pocket_floor_radius_m
                < min(self.body_height_m - self.web_thickness_m, (self.body_width_m - self.recess_width_m) / 2),
                "pocket_floor_radius_m below the recess depth and the side rail width",
            ),
            (
                _lug_fillet_reach_m(self) < self.body_width_m / 2,
                "lug_fillet_radius_m small enough that the fillet ends on the body's end face (below body_width_m / 2)",
            ),
        ]
        for ok, rule in checks:
            if not ok:
                raise GeometryError(f"LinkDimensions {self}: expected {rule}")


def _lug_fillet_centre_m(dims: LinkDimensions) -> tuple[float, float]:
    """Centre (x, y) of the fillet at the corner (body_length/2, lug_radius) of the +x lug neck.

    The fillet is tangent to the body's end face x = body_length/2 and to the lug's outline: the
    tongue's side y = lug_radius if it is short enough, else the lug's half disc around the bore.
    """
    a, b, c, rho = dims.body_length_m / 2, dims.lug_radius_m, dims.pitch_m / 2, dims.lug_fillet_radius_m
    if rho <= c - a:
        return a + rho, b + rho
    return a + rho, math.sqrt((b + rho) ** 2 - (a + rho - c) ** 2)


def _lug_fillet_reach_m(dims: LinkDimensions) -> float:
    """|y| where the lug-neck fillet meets the body's end face."""
    return _lug_fillet_centre_m(dims)[1] if dims.lug_fillet_radius_m > 0 else dims.lug_radius_m


def _segment_m2(radius: float, angle: float) -> float:
    """Area between a circular arc of `angle` (rad) and its chord."""
    return radius**2 / 2 * (angle - math.sin(angle))


def lug_fillet_area_m2(dims: LinkDimensions) -> float:
    """Plan area one lug-neck fillet adds (four of them, each the full body height)."""
    a, b, c, rho = dims.body_length_m / 2, dims.lug_radius_m, dims.pitch_m / 2, dims.lug_fillet_radius_m
    if rho <= c - a:
        return (1 - math.pi / 4) * rho**2
    fx, fy = _lug_fillet_centre_m(dims)
    # Polygon corner Q -> end of the tongue P -> tangent point on the disc T2 -> tangent point on
    # the end face T1, less the two circular segments its arcs cut off the chords.
    t2 = (c + b * (fx - c) / (b + rho), b * fy / (b + rho))
    polygon = [(a, b), (c, b), t2, (a, fy)]
    shoelace = 0.5 * abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(polygon, polygon[1:] + polygon[:1])))
    disc_angle = math.pi / 2 - math.atan2(t2[1], t2[0] - c)
    fillet_angle = math.acos((fx - c) / (b + rho))
    return shoelace - _segment_m2(b, disc_angle) - _segment_m2(rho, fillet_angle)


def _floor_cove_m2(dims: LinkDimensions) -> tuple[float, float]:
    """Cross-section area of the pocket's floor fillet and its centroid's distance from the wall."""
    f = dims.pocket_floor_radius_m
    return (1 - math.pi / 4) * f**2, f * (10 - 3 * math.pi) / (3 * (4 - math.pi))


def recess_volume_m3(dims: LinkDimensions) -> float:
    """Volume the pocket removes: rounded-rectangle prism less the floor fillet's cove (Pappus)."""
    length, width, corner = dims.recess_length_m, dims.recess_width_m, dims.pocket_corner_radius_m
    depth = dims.body_height_m - dims.web_thickness_m
    cove_m2, centroid_m = _floor_cove_m2(dims)
    cove_path_m = 2 * (length - 2 * corner) + 2 * (width - 2 * corner) + 2 * math.pi * (corner - centroid_m)
    return (length * width - (4 - math.pi) * corner**2) * depth - cove_m2 * cove_path_m


#: The built-in link (the calibrated dimensions above).
DEFAULT_LINK = LinkDimensions()


def nominal_volume_m3(dims: LinkDimensions) -> float:
    """Exact solid volume of the parametric link (closed form, as constrained by LinkDimensions)."""
    lug_outside_body_m2 = (dims.pitch_m - dims.body_length_m) * dims.lug_radius_m + math.pi * dims.lug_radius_m**2 / 2
    return (
        dims.body_length_m * dims.body_width_m * dims.body_height_m
        + 2 * lug_outside_body_m2 * dims.body_height_m
        + 4 * lug_fillet_area_m2(dims) * dims.body_height_m
        - 2 * math.pi * dims.bore_radius_m**2 * dims.body_height_m
        - recess_volume_m3(dims)
    )


def recess_length_for_volume(dims: LinkDimensions, volume_m3: float) -> float:
    """The recess length that gives the link `volume_m3`, other dimensions kept (calibration step 1).

    The volume is linear in the recess length: each metre removes the pocket's cross-section less
    its two floor coves."""
    depth = dims.body_height_m - dims.web_thickness_m
    per_length_m2 = dims.recess_width_m * depth - 2 * _floor_cove_m2(dims)[0]
    return dims.recess_length_m + (nominal_volume_m3(dims) - volume_m3) / per_length_m2
