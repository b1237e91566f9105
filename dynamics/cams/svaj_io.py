"""Dynacam-style SVAJ tables: whitespace-separated text, some header lines, then rows of
cam angle (deg), displacement, velocity, acceleration and (optionally) jerk.

The 2012 report's script read such files with `dlmread(file, '', 6, 0)` (six header lines; mm,
mm/s, mm/s^2, mm/s^3). `write_svaj_table` writes exactly that layout; `read_svaj_table` accepts it,
detecting the header lines unless told how many there are.

A table read back is a `TabulatedCam`, the same duck type as `CamProgram` (`svaj`, `period_s`,
`advance_m`, `rpm`, `dwell_mask`, `dwell_intervals_s`). Angles map to time at the table's cam speed
(t = (angle - first angle) / (6 rpm)); velocities in the file must be per second at that speed.
Between rows it interpolates (`interpolation=`):
- "hermite" (default): on each interval the quintic polynomial matching s, v and a at both rows, so
  s, v, a are continuous, v and a are the exact derivatives of s, and any law that is a polynomial
  of degree <= 5 between rows (e.g. 3-4-5) is reproduced exactly; j is the derivative of that
  quintic (the file's jerk column is not used).
- "linear": every column linearly between rows (what the report's script did with its force); j is
  the file's jerk column if present, else the slope of a.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dynamics.cams.cycle import checked_times, wrap
from dynamics.errors import DynamicsError

UNIT_SCALE_M = {"mm": 1e-3, "m": 1.0}
INTERPOLATIONS = ("hermite", "linear")
HEADER_LINES_WRITTEN = 6
# Rows whose |v| and |a| are below this fraction of the table's peaks count as at rest (Dynacam
# prints exact zeros in dwells; this only absorbs print rounding).
_REST_FRACTION = 1e-6


def _unit_scale(units: str) -> float:
    try:
        return UNIT_SCALE_M[units]
    except KeyError:
        raise DynamicsError(f"units: got {units!r}; expected one of {', '.join(UNIT_SCALE_M)}") from None


class TabulatedCam:
    """A cam given by samples; see the module docstring for the interpolation."""

    def __init__(
        self,
        angle_deg,
        s_m,
        v_m_s,
        a_m_s2,
        j_m_s3=None,
        *,
        rpm: float,
        periodic: bool = False,
        interpolation: str = "hermite",
        name: str = "",
    ):
        angle = np.asarray(angle_deg, dtype=float)
        cols = [np.asarray(c, dtype=float) for c in (s_m, v_m_s, a_m_s2)]
        if angle.ndim != 1 or angle.size < 2:
            raise DynamicsError(f"angle_deg: got {angle.size} samples; expected at least 2 rows")
        if any(c.shape != angle.shape for c in cols) or (j_m_s3 is not None and np.shape(j_m_s3) != angle.shape):
            raise DynamicsError("svaj columns: expected s, v, a (and j) of the same length as angle_deg")
        if not np.all(np.isfinite(angle)) or not all(np.all(np.isfinite(c)) for c in cols):
            raise DynamicsError("svaj columns: got non-finite values; expected finite numbers")
        if np.any(np.diff(angle) <= 0):
            i = int(np.argmax(np.diff(angle) <= 0))
            raise DynamicsError(
                f"angle_deg: row {i + 2} ({angle[i + 1]!r}) does not increase; expected strictly increasing angles"
            )
        if not (np.isfinite(rpm) and rpm > 0):
            raise DynamicsError(f"rpm: got {rpm!r}; expected the table's cam speed > 0 rev/min")
        if interpolation not in INTERPOLATIONS:
            raise DynamicsError(f"interpolation: got {interpolation!r}; expected one of {', '.join(INTERPOLATIONS)}")
        self.angle_deg = angle
        self.s_m, self.v_m_s, self.a_m_s2 = cols
        self.j_m_s3 = None if j_m_s3 is None else np.asarray(j_m_s3, dtype=float)
        self.rpm = float(rpm)
        self.periodic = bool(periodic)
        self.interpolation = interpolation
        self.name = name
        self._t = (angle - angle[0]) / (6.0 * self.rpm)
        v_peak = float(np.max(np.abs(self.v_m_s))) or 1.0
        a_peak = float(np.max(np.abs(self.a_m_s2))) or 1.0
        self._at_rest = (np.abs(self.v_m_s) <= _REST_FRACTION * v_peak) & (
            np.abs(self.a_m_s2) <= _REST_FRACTION * a_peak
        )
        if self.periodic and (
            abs(self.v_m_s[-1] - self.v_m_s[0]) > _REST_FRACTION * v_peak
            or abs(self.a_m_s2[-1] - self.a_m_s2[0]) > _REST_FRACTION * a_peak
        ):
            raise DynamicsError(
                "periodic table: v and a at the last row differ from the first; expected a table covering whole cycles"
            )

    @property
    def duration_s(self) -> float:
        return float(self._t[-1])

    @property
    def period_s(self) -> float | None:
        return self.duration_s if self.periodic else None

    @property
    def advance_m(self) -> float | None:
        return float(self.s_m[-1] - self.s_m[0]) if self.periodic else None

    def at_rpm(self, rpm: float) -> TabulatedCam:
        """The same cam turned at another speed: v scales with rpm, a with rpm^2, j with rpm^3."""
        r = rpm / self.rpm
        j = None if self.j_m_s3 is None else self.j_m_s3 * r**3
        return TabulatedCam(
            self.angle_deg,
            self.s_m,
            self.v_m_s * r,
            self.a_m_s2 * r**2,
            j,
            rpm=rpm,
            periodic=self.periodic,
            interpolation=self.interpolation,
            name=self.name,
        )

    def svaj(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Displacement (m), velocity (m/s), acceleration (m/s^2), jerk (m/s^3) at times t_s (s)."""
        t, offset = self._reduce(t_s)
        beyond = t > self._t[-1]
        if np.any(beyond) and not self._at_rest[-1]:
            raise DynamicsError(
                f"t_s: got {float(np.max(t_s))!r} s past the table's end ({self.duration_s:.6g} s), "
                "which is not at rest; expected times within the table"
            )
        tc = np.minimum(t, self._t[-1])
        i = np.clip(np.searchsorted(self._t, tc, side="right") - 1, 0, len(self._t) - 2)
        h = self._t[i + 1] - self._t[i]
        u = (tc - self._t[i]) / h
        if self.interpolation == "hermite":
            s, v, a, j = self._hermite(i, u, h)
        else:
            s, v, a, j = self._linear(i, u, h)
        v, a, j = (np.where(beyond, 0.0, q) for q in (v, a, j))
        return s + offset, v, a, j

    def dwell_mask(self, t_s: np.ndarray) -> np.ndarray:
        """True between two consecutive rows that are both at rest (and past the end of a one-shot table)."""
        t, _ = self._reduce(t_s)
        i = np.clip(np.searchsorted(self._t, t, side="right") - 1, 0, len(self._t) - 2)
        return (self._at_rest[i] & self._at_rest[i + 1]) | (t > self._t[-1])

    @property
    def dwell_intervals_s(self) -> tuple[tuple[float, float], ...]:
        rest_pair = self._at_rest[:-1] & self._at_rest[1:]
        intervals: list[list[float]] = []
        for k in np.flatnonzero(rest_pair):
            if intervals and intervals[-1][1] == self._t[k]:
                intervals[-1][1] = float(self._t[k + 1])
            else:
                intervals.append([float(self._t[k]), float(self._t[k + 1])])
        if not self.periodic and self._at_rest[-1]:
            if intervals and intervals[-1][1] == self._t[-1]:
                intervals[-1][1] = math.inf
            else:
                intervals.append([float(self._t[-1]), math.inf])
        return tuple((a, b) for a, b in intervals)

    def _reduce(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = checked_times(t_s, None if self.periodic else "table")
        if self.periodic:
            return wrap(t, self.duration_s, self.advance_m)
        return t, np.zeros_like(t)

    def _hermite(self, i, u, h):
        s0, s1 = self.s_m[i], self.s_m[i + 1]
        c1, v1h = self.v_m_s[i] * h, self.v_m_s[i + 1] * h
        c2, a1h2 = 0.5 * self.a_m_s2[i] * h**2, self.a_m_s2[i + 1] * h**2
        ds = s1 - (s0 + c1 + c2)
        dv = v1h - (c1 + 2 * c2)
        da = a1h2 - 2 * c2
        c3 = 10 * ds - 4 * dv + 0.5 * da
        c4 = -15 * ds + 7 * dv - da
        c5 = 6 * ds - 3 * dv + 0.5 * da
        s = s0 + u * (c1 + u * (c2 + u * (c3 + u * (c4 + u * c5))))
        v = (c1 + u * (2 * c2 + u * (3 * c3 + u * (4 * c4 + u * 5 * c5)))) / h
        a = (2 * c2 + u * (6 * c3 + u * (12 * c4 + u * 20 * c5))) / h**2
        j = (6 * c3 + u * (24 * c4 + u * 60 * c5)) / h**3
        return s, v, a, j

    def _linear(self, i, u, h):
        def lerp(col):
            return (1 - u) * col[i] + u * col[i + 1]

        j = lerp(self.j_m_s3) if self.j_m_s3 is not None else (self.a_m_s2[i + 1] - self.a_m_s2[i]) / h
        return lerp(self.s_m), lerp(self.v_m_s), lerp(self.a_m_s2), j


def _parse_rows(lines: list[str], header_lines: int | None, path: Path) -> tuple[np.ndarray, int]:
    """Numeric rows (after the header) and the line number of the first of them."""
    if header_lines is not None and (not isinstance(header_lines, int) or header_lines < 0):
        raise DynamicsError(f"header_lines: got {header_lines!r}; expected an integer >= 0 or None (detect)")
    rows: list[list[float]] = []
    first_line = 0
    for number, line in enumerate(lines, start=1):
        if header_lines is not None and number <= header_lines:
            continue
        fields = line.split()
        if not fields:
            continue
        try:
            values = [float(f) for f in fields]
        except ValueError:
            if header_lines is None and not rows:
                continue  # still in the header
            raise DynamicsError(
                f"{path}: line {number}: {line.strip()[:60]!r} is not numeric; "
                "expected whitespace-separated angle, s, v, a[, j]"
            ) from None
        if len(values) not in (4, 5):
            raise DynamicsError(
                f"{path}: line {number}: got {len(values)} columns; expected 4 or 5 (angle, s, v, a[, j])"
            )
        if rows and len(values) != len(rows[0]):
            raise DynamicsError(
                f"{path}: line {number}: got {len(values)} columns; expected {len(rows[0])} like line {first_line}"
            )
        if not rows:
            first_line = number
        rows.append(values)
    if len(rows) < 2:
        raise DynamicsError(f"{path}: found {len(rows)} data rows; expected at least 2 rows of angle, s, v, a[, j]")
    return np.array(rows), first_line


def read_svaj_table(
    path,
    *,
    units: str = "mm",
    rpm: float = 180.0,
    periodic: bool = False,
    header_lines: int | None = None,
    interpolation: str = "hermite",
) -> TabulatedCam:
    """Read a Dynacam-style SVAJ table; lengths in `units` ("mm" or "m"), velocities per second at `rpm`.

    `header_lines=None` skips leading non-numeric lines; give a number (the report used 6) to skip
    exactly that many. `periodic=True` treats the table as one cycle of continuous indexing.
    """
    scale = _unit_scale(units)
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise DynamicsError(
            f"{path}: cannot read the SVAJ table ({exc.__class__.__name__}); expected a readable text file"
        ) from None
    data, first_line = _parse_rows(text.splitlines(), header_lines, path)
    bad = np.flatnonzero(np.diff(data[:, 0]) <= 0)
    if bad.size:
        raise DynamicsError(
            f"{path}: line {first_line + int(bad[0]) + 1}: angle {float(data[bad[0] + 1, 0])!r} does not increase; "
            "expected strictly increasing angles (deg)"
        )
    if not np.all(np.isfinite(data)):
        raise DynamicsError(f"{path}: non-finite values; expected finite numbers")
    j = data[:, 4] * scale if data.shape[1] == 5 else None
    return TabulatedCam(
        data[:, 0],
        data[:, 1] * scale,
        data[:, 2] * scale,
        data[:, 3] * scale,
        j,
        rpm=rpm,
        periodic=periodic,
        interpolation=interpolation,
        name=path.stem,
    )


def write_svaj_table(
    program, path, *, units: str = "mm", step_deg: float = 1.0, stop_deg: float | None = None, title: str | None = None
) -> Path:
    """Write `program` (anything with `svaj`, `rpm`, `duration_s`) sampled every `step_deg` from 0 to
    `stop_deg` inclusive (default: one cycle or the whole program), with 6 header lines."""
    scale = _unit_scale(units)
    if not (np.isfinite(step_deg) and step_deg > 0):
        raise DynamicsError(f"step_deg: got {step_deg!r}; expected an angle step > 0")
    deg_per_s = 6.0 * program.rpm
    stop = program.duration_s * deg_per_s if stop_deg is None else float(stop_deg)
    n = int(round(stop / step_deg))
    if n < 1 or not math.isclose(n * step_deg, stop, rel_tol=1e-9, abs_tol=1e-9):
        raise DynamicsError(f"stop_deg: got {stop!r}; expected a positive multiple of step_deg = {step_deg!r}")
    angle = np.arange(n + 1) * step_deg
    s, v, a, j = program.svaj(angle / deg_per_s)
    u = units
    header = [
        title or f"SVAJ table: {getattr(program, 'name', '') or 'cam program'}",
        "written by link-conveyor (dynamics.cams.svaj_io), Dynacam-style layout",
        f"cam speed {program.rpm:g} rpm, {step_deg:g} deg per row",
        f"units: angle deg, s {u}, v {u}/s, a {u}/s^2, j {u}/s^3",
        "",
        "angle_deg s v a j",
    ]
    body = "\n".join(
        f"{t:.6f} {x:.15g} {y:.15g} {z:.15g} {w:.15g}"
        for t, x, y, z, w in zip(angle, s / scale, v / scale, a / scale, j / scale)
    )
    path = Path(path)
    path.write_text("\n".join(header) + "\n" + body + "\n")
    return path
