"""Index-dwell cam programs: a sequence of rise, dwell and return segments turned at constant speed.

`CamProgram.svaj(t_s)` gives the follower (chain input) displacement, velocity, acceleration and
jerk in SI. A program is either periodic (continuous indexing: after each cycle the program repeats
shifted by `advance_m`, so z(t + period_s) = z(t) + advance_m) or one-shot (`period_s` and
`advance_m` are None; after its last segment the follower stays where it ended, at rest).

Joints between segments are checked for continuity of s and v (and, for a periodic program, the
joint from the last segment back to the first), so a law that does not start and end at rest cannot
be joined to a dwell by mistake.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynamics.cams.cycle import checked_times, wrap
from dynamics.cams.laws import get_law
from dynamics.errors import DynamicsError

SEGMENT_KINDS = ("rise", "dwell", "return")
# Joints must match to this fraction of the program's lift (s) or peak speed scale (v); the laws
# themselves match to ~1e-15, so anything larger is a real jump.
_JOINT_RELATIVE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Segment:
    """One segment: `kind` rise/dwell/return over `angle_deg` of cam rotation, moving by `lift_m`
    (>0 for rise and return, 0 for dwell) with the motion law `law_id` (unused for dwells)."""

    kind: str
    angle_deg: float
    lift_m: float = 0.0
    law_id: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in SEGMENT_KINDS:
            raise DynamicsError(f"segment kind: got {self.kind!r}; expected one of {', '.join(SEGMENT_KINDS)}")
        if not (np.isfinite(self.angle_deg) and self.angle_deg > 0):
            raise DynamicsError(f"segment angle_deg: got {self.angle_deg!r}; expected a finite angle > 0")
        if self.kind == "dwell":
            if self.lift_m != 0.0:
                raise DynamicsError(f"dwell lift_m: got {self.lift_m!r}; expected 0 (a dwell does not move)")
        else:
            if not (np.isfinite(self.lift_m) and self.lift_m > 0):
                raise DynamicsError(f"{self.kind} lift_m: got {self.lift_m!r}; expected a finite lift > 0 in metres")
            if self.law_id is None:
                raise DynamicsError(f"{self.kind} law_id: missing; expected a cam law id")
            get_law(self.law_id)

    @property
    def signed_lift_m(self) -> float:
        return -self.lift_m if self.kind == "return" else self.lift_m


class CamProgram:
    """A cam program turned at `rpm`; see the module docstring for the periodic/one-shot semantics."""

    def __init__(self, segments: tuple[Segment, ...] | list[Segment], rpm: float, *, periodic: bool, name: str = ""):
        segments = tuple(segments)
        if not segments:
            raise DynamicsError("segments: got none; expected at least one rise, dwell or return")
        if not (np.isfinite(rpm) and rpm > 0):
            raise DynamicsError(f"rpm: got {rpm!r}; expected a cam speed > 0 rev/min")
        self.segments = segments
        self.rpm = float(rpm)
        self.periodic = bool(periodic)
        self.name = name
        self._deg_per_s = 6.0 * self.rpm
        angles = np.array([s.angle_deg for s in segments], dtype=float)
        self._start_deg = np.concatenate([[0.0], np.cumsum(angles)[:-1]])
        self._cycle_deg = float(angles.sum())
        self._start_m = np.concatenate([[0.0], np.cumsum([s.signed_lift_m for s in segments])[:-1]])
        self._net_m = float(sum(s.signed_lift_m for s in segments))
        self._check_joints()

    # Constructors ---------------------------------------------------------------------------------

    @classmethod
    def indexing(
        cls,
        law_id: str,
        *,
        pitch_m: float = 0.1125,
        index_deg: float = 45.0,
        dwell_deg: float = 45.0,
        rpm: float = 180.0,
    ) -> CamProgram:
        """Continuous indexing: one rise of `pitch_m` over `index_deg`, a dwell of `dwell_deg`, repeated."""
        return cls(
            (Segment("rise", index_deg, pitch_m, law_id), Segment("dwell", dwell_deg)),
            rpm,
            periodic=True,
            name=f"indexing {law_id}",
        )

    # The duck type the simulators consume -----------------------------------------------------------

    @property
    def cycle_s(self) -> float:
        """Duration of one pass through the segments."""
        return self._cycle_deg / self._deg_per_s

    @property
    def duration_s(self) -> float:
        """Length of one cycle (periodic) or of the whole program (one-shot)."""
        return self.cycle_s

    @property
    def period_s(self) -> float | None:
        return self.cycle_s if self.periodic else None

    @property
    def advance_m(self) -> float | None:
        return self._net_m if self.periodic else None

    def svaj(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Displacement (m), velocity (m/s), acceleration (m/s^2), jerk (m/s^3) at times t_s (s)."""
        theta, offset_m = self._reduce(t_s)
        s = np.zeros_like(theta)
        v = np.zeros_like(theta)
        a = np.zeros_like(theta)
        j = np.zeros_like(theta)
        seg = self._segment_index(theta)
        end = theta >= self._cycle_deg  # one-shot programs rest where they ended
        s[end] = self._start_m[-1] + self.segments[-1].signed_lift_m
        for i, segment in enumerate(self.segments):
            m = (seg == i) & ~end
            if not np.any(m):
                continue
            s[m] = self._start_m[i]
            if segment.kind == "dwell":
                continue
            dur_s = segment.angle_deg / self._deg_per_s
            h = segment.signed_lift_m
            S, V, A, J = get_law(segment.law_id).svaj((theta[m] - self._start_deg[i]) / segment.angle_deg)
            s[m] += h * S
            v[m] = h * V / dur_s
            a[m] = h * A / dur_s**2
            j[m] = h * J / dur_s**3
        return s + offset_m, v, a, j

    def dwell_mask(self, t_s: np.ndarray) -> np.ndarray:
        """True where the cam dwells (including after the end of a one-shot program)."""
        theta, _ = self._reduce(t_s)
        seg = self._segment_index(theta)
        is_dwell = np.array([s.kind == "dwell" for s in self.segments])
        return is_dwell[seg] | (theta >= self._cycle_deg)

    @property
    def dwell_intervals_s(self) -> tuple[tuple[float, float], ...]:
        """(start, end) times (s) of the dwells within one cycle (periodic) or the program (one-shot, whose
        rest after the last segment is a dwell ending at inf); adjacent dwells are merged."""
        intervals: list[list[float]] = []
        for start, segment in zip(self._start_deg, self.segments):
            if segment.kind != "dwell":
                continue
            t0, t1 = start / self._deg_per_s, (start + segment.angle_deg) / self._deg_per_s
            if intervals and np.isclose(intervals[-1][1], t0):
                intervals[-1][1] = t1
            else:
                intervals.append([t0, t1])
        if not self.periodic:
            if intervals and np.isclose(intervals[-1][1], self.cycle_s):
                intervals[-1][1] = np.inf
            else:
                intervals.append([self.cycle_s, np.inf])
        return tuple((float(a), float(b)) for a, b in intervals)

    def at_rpm(self, rpm: float) -> CamProgram:
        return CamProgram(self.segments, rpm, periodic=self.periodic, name=self.name)

    # Internals ----------------------------------------------------------------------------------------

    def _reduce(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cam angle within the cycle (deg) and the displacement offset of completed cycles (m)."""
        theta = checked_times(t_s, None if self.periodic else "cam program") * self._deg_per_s
        if self.periodic:
            return wrap(theta, self._cycle_deg, self._net_m)
        return theta, np.zeros_like(theta)

    def _segment_index(self, theta: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(self._start_deg, theta, side="right") - 1, 0, len(self.segments) - 1)

    def _check_joints(self) -> None:
        """s and v must agree on both sides of every joint (and across the cycle end if periodic)."""
        ends = []
        for segment in self.segments:
            if segment.kind == "dwell":
                ends.append(((0.0, 0.0), (0.0, 0.0)))
                continue
            dur_s = segment.angle_deg / self._deg_per_s
            S, V, _, _ = get_law(segment.law_id).svaj(np.array([0.0, 1.0]))
            h = segment.signed_lift_m
            ends.append(((h * S[0], h * V[0] / dur_s), (h * S[1] - h, h * V[1] / dur_s)))
        lift_scale = max(abs(s.lift_m) for s in self.segments) or 1.0
        speed_scale = max((s.lift_m * self._deg_per_s / s.angle_deg for s in self.segments), default=0.0) or 1.0
        pairs = list(zip(range(len(self.segments) - 1), range(1, len(self.segments))))
        if self.periodic:
            pairs.append((len(self.segments) - 1, 0))
        for i, k in pairs:
            (ds_end, v_end), (ds_start, v_start) = ends[i][1], ends[k][0]
            if abs(ds_end - ds_start) > _JOINT_RELATIVE_TOLERANCE * lift_scale:
                raise DynamicsError(
                    f"segments {i + 1}->{k + 1}: displacement jumps by {ds_start - ds_end:.3g} m at the joint; "
                    "expected a law with S(0) = 0 and S(1) = 1"
                )
            if abs(v_end - v_start) > _JOINT_RELATIVE_TOLERANCE * speed_scale:
                raise DynamicsError(
                    f"segments {i + 1}->{k + 1}: velocity jumps from {v_end:.6g} to {v_start:.6g} m/s at the joint; "
                    "expected continuous velocity (laws meeting a dwell must start and end at rest)"
                )


def mqp2012_program(law_id: str, rpm: float = 180.0, *, full_cycle: bool = False) -> CamProgram:
    """The 2012 report's cam: rise 112.5 mm over 45 deg, dwell 45 deg, rise, dwell (first 180 deg, one-shot).

    `full_cycle=True` gives Dynacam's whole 360-deg program (rise, dwell, rise, dwell, return 225 mm
    over 90 deg, dwell 90 deg), periodic with zero advance; the report used only its first 180 deg.
    """
    rise = Segment("rise", 45.0, 0.1125, law_id)
    dwell = Segment("dwell", 45.0)
    segments = [rise, dwell, rise, dwell]
    if full_cycle:
        segments += [Segment("return", 90.0, 0.225, law_id), Segment("dwell", 90.0)]
    return CamProgram(segments, rpm, periodic=full_cycle, name=f"mqp2012 {law_id}")
