"""A toothed wheel (drive sprocket or idler) and the chordal (polygonal) action it feeds a strand with.

Pitch radius. A chain of pitch p seated on z teeth puts its pins on a circle of radius
R = p / (2 sin(pi / z)): each link is a chord subtending one tooth angle 2 pi / z.

Feed radius. One tooth of rotation advances the chain by exactly one pitch, so the mean chain
advance per radian is R_m = p z / (2 pi) = R sin(pi / z) / (pi / z) (< R; 1.2 % below R at z = 12,
-> R as z -> infinity). The drive's torsional stiffness k_theta (N m/rad) acts on the chain's path
coordinate as k_theta / R_m^2 (N/m); a wheel of inertia J adds J / R_m^2 (kg) to its seated links.

Chordal action. The strand leaves the wheel along the tangent at its tangent point. The last seated
pin, at angle gamma from the tangent point, is at R sin(gamma) along the strand (the 1-D model keeps
the along-strand component and drops the strand's small transverse rise). gamma runs over one tooth,
-pi/z .. pi/z; when it reaches pi/z the next pin seats (or, on the leaving side, the pin leaves) and
gamma jumps back by one tooth while the along-strand position stays continuous (R sin(pi/z) = p/2).
With the wheel turning steadily at omega the strand end moves at omega R cos(gamma): between
omega R cos(pi/z) and omega R, its mean omega R_m.

Tooth phase. `tooth_phase` is where the teeth stand at the dwell, as a fraction of a tooth: 0 (the
default) puts gamma = -pi/z at the dwell, i.e. a pin seats while the wheel is at rest and gamma sweeps
-pi/z .. pi/z during the index, symmetric about mid-index where the cam is fastest. It is the phase
that keeps the strand end's velocity and acceleration continuous (the seat change, with its kink in
the feed, happens at rest, where the cam laws have zero velocity and acceleration), so the chordal
action adds no impact of its own. Any other phase phi moves the seat change into the index: it
happens when the wheel has turned (1 - phi) of a tooth since the dwell (`seat_change_angle_rad`),
i.e. when the cam has lifted (1 - phi) p, at the wheel's pitch-circle speed; after it the pin one
tooth behind pulls the strand, whose departure from the mean feed is the same function one tooth
back, d(a - 2 pi / z) (continuous there: R sin(pi/z) - R sin(-pi/z) = p). phi -> 1 puts the seat
change at the index's start: phase 0 with the seat change moved by one index.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.options import DEFAULT_PRELOAD_N

STEEL_DENSITY_KG_PER_M3 = 7850.0


@dataclass(frozen=True)
class Wheel:
    """A toothed wheel: teeth z, the chain's pitch p (m), seated links, inertia J (kg m^2)."""

    teeth: int
    pitch_m: float
    wrap_links: int
    inertia_kg_m2: float = 0.0
    tooth_phase: float = 0.0  # fraction of a tooth at the dwell; 0: a pin seats at the dwell

    def __post_init__(self) -> None:
        if not (isinstance(self.teeth, (int, np.integer)) and self.teeth >= 3):
            raise DynamicsError(f"teeth: expected an integer >= 3, got {self.teeth!r} (option --sprocket-teeth)")
        if not (np.isfinite(self.pitch_m) and self.pitch_m > 0):
            raise DynamicsError(f"pitch_m: expected a positive pitch in metres, got {self.pitch_m!r}")
        if not (isinstance(self.wrap_links, (int, np.integer)) and 0 <= self.wrap_links < self.teeth):
            raise DynamicsError(
                f"wrap_links: expected an integer in 0..{self.teeth - 1} (fewer than the teeth), "
                f"got {self.wrap_links!r} (option --sprocket-wrap-links)"
            )
        if not (np.isfinite(self.inertia_kg_m2) and self.inertia_kg_m2 >= 0):
            raise DynamicsError(f"inertia_kg_m2: expected a finite value >= 0, got {self.inertia_kg_m2!r}")
        if not (np.isfinite(self.tooth_phase) and 0.0 <= self.tooth_phase < 1.0):
            raise DynamicsError(f"tooth_phase: expected a fraction of a tooth in [0, 1), got {self.tooth_phase!r}")

    @property
    def tooth_angle_rad(self) -> float:
        return 2.0 * np.pi / self.teeth

    @property
    def pitch_radius_m(self) -> float:
        return pitch_radius_m(self.pitch_m, self.teeth)

    @property
    def feed_radius_m(self) -> float:
        """Mean chain advance per radian, p z / (2 pi)."""
        return self.pitch_m * self.teeth / (2.0 * np.pi)

    @property
    def seat_change_angle_rad(self) -> float:
        """The wheel's angle since the dwell at which the pin seated at the dwell hands the strand to
        the next one, (1 - phase) of a tooth: the end of the index (the next dwell) at phase 0."""
        return (1.0 - self.tooth_phase) * self.tooth_angle_rad

    def gamma_at_dwell_rad(self) -> float:
        return (self.tooth_phase - 0.5) * self.tooth_angle_rad

    def strand_end_m(self, angle_rad) -> np.ndarray:
        """Along-strand position of the last seated pin when the wheel has turned `angle_rad` from
        the dwell (0 at the dwell), seat changes included: p k + R sin(gamma) - (its value at 0)."""
        gamma, k = self._gamma_and_seat(angle_rad)
        r = self.pitch_radius_m
        return self.pitch_m * k + r * np.sin(gamma) - r * np.sin(self.gamma_at_dwell_rad())

    def strand_end_speed_ratio(self, angle_rad) -> np.ndarray:
        """d(strand end)/d(angle) / R = cos(gamma): the chordal speed ratio, in [cos(pi/z), 1]."""
        return np.cos(self._gamma_and_seat(angle_rad)[0])

    def _gamma_and_seat(self, angle_rad):
        a = np.asarray(angle_rad, dtype=float)
        tooth = self.tooth_angle_rad
        shifted = a + self.gamma_at_dwell_rad() + 0.5 * tooth  # 0 .. tooth within the seat at the dwell
        k = np.floor(shifted / tooth)
        return shifted - k * tooth - 0.5 * tooth, k

    def feed_departure_m(self, angle_rad) -> np.ndarray:
        """d(angle) = R sin(gamma_0 + angle) - R sin(gamma_0) - R_m angle for the pin seated at the
        dwell, continued analytically past its seat change: the strand end's departure from the
        mean feed (zero for every angle as z -> infinity). Used within one index, where the pin that
        pulls the strand is the one seated at the dwell."""
        a = np.asarray(angle_rad, dtype=float)
        g0, r = self.gamma_at_dwell_rad(), self.pitch_radius_m
        return r * (np.sin(g0 + a) - np.sin(g0)) - self.feed_radius_m * a

    def feed_departure_slope(self, angle_rad) -> np.ndarray:
        """d'(angle) = R cos(gamma_0 + angle) - R_m (metres per radian)."""
        a = np.asarray(angle_rad, dtype=float)
        return self.pitch_radius_m * np.cos(self.gamma_at_dwell_rad() + a) - self.feed_radius_m


def pitch_radius_m(pitch_m: float, teeth: int) -> float:
    """R = p / (2 sin(pi / z))."""
    return float(pitch_m / (2.0 * np.sin(np.pi / teeth)))


def steel_disc_inertia_kg_m2(radius_m: float, thickness_m: float) -> float:
    """J = 1/2 rho pi r^4 t of a solid steel disc: an upper bound for a plate wheel of that radius."""
    return float(0.5 * STEEL_DENSITY_KG_PER_M3 * np.pi * radius_m**4 * thickness_m)


DEFAULT_WHEEL_THICKNESS_M = 0.025


def default_wheel_inertia_kg_m2(pitch_m: float, teeth: int) -> float:
    """The run's default wheel inertia: a solid steel disc of the pitch radius, DEFAULT_WHEEL_THICKNESS_M
    thick (0.688 kg m^2 at z = 12 on the 112.5 mm pitch); an upper bound, a plate or spoked wheel is lighter."""
    return steel_disc_inertia_kg_m2(pitch_radius_m(pitch_m, teeth), DEFAULT_WHEEL_THICKNESS_M)


# Tooth contact stiffness (docs/physics.md, "Rigid seating's validity and the tooth contact stiffness"):
# the pin's line contact on the tooth flank, steel on steel, by Palmgren's roller-on-raceway line
# contact, delta = PALMGREN_MM * Q^0.9 / l^0.8 (delta in mm, Q in N, l in mm; A. Palmgren, Ball and
# Roller Bearing Engineering, 1959, as quoted by T. A. Harris, Rolling Bearing Analysis), whose tangent
# stiffness dQ / d delta = Q^0.1 l^0.8 / (0.9 PALMGREN_MM) N/mm grows only as Q^0.1: the default takes
# it at the run's default preload on the default link's 30 mm of pin (its body height), along the path
# (the flank's pressure angle, the tooth's and the pin's bending, all in series, would soften it: an
# upper bound of the seat's stiffness).
PALMGREN_MM = 3.84e-5
DEFAULT_TOOTH_LOAD_N = DEFAULT_PRELOAD_N  # the run's default preload (settings.RunConfig.preload_N's default)
DEFAULT_TOOTH_CONTACT_LENGTH_M = 0.030  # geometry.dimensions.LinkDimensions.body_height_m's default


def line_contact_stiffness_N_per_m(load_N: float, length_m: float) -> float:
    """Palmgren's steel line contact's tangent stiffness at `load_N` over a contact `length_m` long."""
    length_mm = 1e3 * length_m
    return float(load_N**0.1 * length_mm**0.8 / (0.9 * PALMGREN_MM) * 1e3)


DEFAULT_TOOTH_STIFFNESS_N_PER_M = line_contact_stiffness_N_per_m(DEFAULT_TOOTH_LOAD_N, DEFAULT_TOOTH_CONTACT_LENGTH_M)
