"""What designers read off a chain response: pure functions on arrays, SI units.

Histories are arrays of shape (n_times, n_links) for the links and (n_times,) for the cam input;
link numbers are 1-based as on the machine (link 1 is driven by the cam). The sponsor's
accelerometers sat at four stations (`station_links`): drive end = link 1, tight side =
round(3N/4), idler end = round(N/2), slack side = round(N/4), with MATLAB's rounding (half away
from zero), as the report's script indexed them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from dynamics.errors import DynamicsError

STATIONS = ("drive-end", "tight-side", "idler-end", "slack-side")


def matlab_round(x):
    """Round half away from zero (MATLAB's `round`; Python's rounds half to even)."""
    x = np.asarray(x, dtype=float)
    return np.sign(x) * np.floor(np.abs(x) + 0.5)


def station_links(n_links: int) -> dict[str, int]:
    """1-based link numbers of the four accelerometer stations for a chain of `n_links`."""
    if not (isinstance(n_links, (int, np.integer)) and n_links >= 1):
        raise DynamicsError(f"n_links: got {n_links!r}; expected an integer >= 1")
    fractions = {"drive-end": None, "tight-side": 0.75, "idler-end": 0.5, "slack-side": 0.25}
    return {
        name: 1 if f is None else int(min(n_links, max(1, matlab_round(f * n_links)))) for name, f in fractions.items()
    }


def rms(y: np.ndarray, axis: int = 0) -> np.ndarray:
    """Root mean square along `axis` (over the samples, as MATLAB's dsp.RMS on columns)."""
    y = np.asarray(y, dtype=float)
    return np.sqrt(np.mean(y**2, axis=axis))


@dataclass(frozen=True)
class LinkMetrics:
    """Per-link values, each an array of length n_links (index i is link i + 1)."""

    rms_displacement_m: np.ndarray
    rms_velocity_m_s: np.ndarray
    rms_acceleration_m_s2: np.ndarray
    max_abs_acceleration_m_s2: np.ndarray
    max_deviation_m: np.ndarray  # max |x - z|
    max_velocity_deviation_m_s: np.ndarray  # max |v - zdot|
    max_acceleration_deviation_m_s2: np.ndarray  # max |a - zddot|
    residual_vibration_m: np.ndarray  # max |x - z| inside dwells

    @property
    def n_links(self) -> int:
        return self.rms_displacement_m.size

    def at_link(self, link: int) -> StationMetrics:
        if not 1 <= link <= self.n_links:
            raise DynamicsError(f"link: got {link!r}; expected 1..{self.n_links}")
        return StationMetrics(link, **{f.name: float(getattr(self, f.name)[link - 1]) for f in fields(self)})


@dataclass(frozen=True)
class StationMetrics:
    """The `LinkMetrics` values of one link."""

    link: int
    rms_displacement_m: float
    rms_velocity_m_s: float
    rms_acceleration_m_s2: float
    max_abs_acceleration_m_s2: float
    max_deviation_m: float
    max_velocity_deviation_m_s: float
    max_acceleration_deviation_m_s2: float
    residual_vibration_m: float


RANKABLE = tuple(f.name for f in fields(StationMetrics) if f.name != "link")


def _check_history(x, v, a, z, zdot, zddot, dwell_mask):
    x, v, a = (np.asarray(q, dtype=float) for q in (x, v, a))
    z, zdot, zddot = (np.asarray(q, dtype=float) for q in (z, zdot, zddot))
    if x.ndim != 2 or x.shape[0] < 1:
        raise DynamicsError(f"x: got shape {x.shape}; expected (n_times, n_links)")
    for name, q in (("v", v), ("a", a)):
        if q.shape != x.shape:
            raise DynamicsError(f"{name}: got shape {q.shape}; expected {x.shape} like x")
    for name, q in (("z", z), ("zdot", zdot), ("zddot", zddot)):
        if q.shape != (x.shape[0],):
            raise DynamicsError(f"{name}: got shape {q.shape}; expected ({x.shape[0]},), one value per time")
    mask = np.asarray(dwell_mask, dtype=bool)
    if mask.shape != (x.shape[0],):
        raise DynamicsError(f"dwell_mask: got shape {mask.shape}; expected ({x.shape[0]},)")
    return x, v, a, z, zdot, zddot, mask


def residual_vibration(x_m: np.ndarray, z_m: np.ndarray, dwell_mask: np.ndarray) -> np.ndarray:
    """Per link, max |x - z| over the samples inside dwells."""
    x = np.asarray(x_m, dtype=float)
    mask = np.asarray(dwell_mask, dtype=bool)
    if not mask.any():
        raise DynamicsError("dwell_mask: no sample lies in a dwell; expected at least one (simulate past an index)")
    return np.max(np.abs(x[mask] - np.asarray(z_m, dtype=float)[mask, None]), axis=0)


def link_metrics(x_m, v_m_s, a_m_s2, z_m, zdot_m_s, zddot_m_s2, dwell_mask) -> LinkMetrics:
    """All per-link metrics of one response to one cam input."""
    x, v, a, z, zdot, zddot, mask = _check_history(x_m, v_m_s, a_m_s2, z_m, zdot_m_s, zddot_m_s2, dwell_mask)
    return LinkMetrics(
        rms_displacement_m=rms(x),
        rms_velocity_m_s=rms(v),
        rms_acceleration_m_s2=rms(a),
        max_abs_acceleration_m_s2=np.max(np.abs(a), axis=0),
        max_deviation_m=np.max(np.abs(x - z[:, None]), axis=0),
        max_velocity_deviation_m_s=np.max(np.abs(v - zdot[:, None]), axis=0),
        max_acceleration_deviation_m_s2=np.max(np.abs(a - zddot[:, None]), axis=0),
        residual_vibration_m=residual_vibration(x, z, mask),
    )


def station_metrics(metrics: LinkMetrics) -> dict[str, StationMetrics]:
    """The metrics at the four accelerometer stations."""
    return {name: metrics.at_link(link) for name, link in station_links(metrics.n_links).items()}


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) sample indices of each run of True."""
    padded = np.concatenate([[False], mask, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(int)))
    return [(int(s), int(e) - 1) for s, e in zip(edges[::2], edges[1::2])]


@dataclass(frozen=True)
class Settling:
    """Settling after each index: the dwells found in the mask and, per dwell and link, the time
    from the dwell's first sample until |x - z| stays within the band to the dwell's end (NaN: it
    never does within that dwell)."""

    band_m: float
    dwell_start_s: np.ndarray  # (n_dwells,)
    dwell_end_s: np.ndarray  # (n_dwells,) last sample of each dwell
    settling_time_s: np.ndarray  # (n_dwells, n_links)


def settling_times(t_s, x_m, z_m, dwell_mask, band_m: float) -> Settling:
    """Settling time to `band_m` after each index. The crossing into the band is located by linear
    interpolation between the last sample outside and the first inside (error O(dt^2) for smooth
    envelopes); a link already inside at the dwell's first sample has settling time 0."""
    t = np.asarray(t_s, dtype=float)
    x = np.asarray(x_m, dtype=float)
    z = np.asarray(z_m, dtype=float)
    mask = np.asarray(dwell_mask, dtype=bool)
    if x.ndim != 2 or t.shape != (x.shape[0],) or z.shape != t.shape or mask.shape != t.shape:
        raise DynamicsError(
            "settling_times: expected t_s, z_m, dwell_mask of shape (n_times,) and x_m (n_times, n_links)"
        )
    if not (np.isfinite(band_m) and band_m > 0):
        raise DynamicsError(f"band_m: got {band_m!r}; expected a band > 0 in metres")
    runs = _runs(mask)
    if not runs:
        raise DynamicsError("dwell_mask: no sample lies in a dwell; expected at least one dwell")
    out = np.full((len(runs), x.shape[1]), np.nan)
    for r, (first, last) in enumerate(runs):
        dev = np.abs(x[first : last + 1] - z[first : last + 1, None])
        outside = dev > band_m
        for link in range(x.shape[1]):
            idx = np.flatnonzero(outside[:, link])
            if idx.size == 0:
                out[r, link] = 0.0
                continue
            k = idx[-1]  # last sample outside the band
            if k == dev.shape[0] - 1:
                continue  # still outside at the dwell's end
            d0, d1 = dev[k, link], dev[k + 1, link]
            w = (d0 - band_m) / (d0 - d1)
            out[r, link] = t[first + k] + w * (t[first + k + 1] - t[first + k]) - t[first]
    return Settling(float(band_m), t[[f for f, _ in runs]], t[[last for _, last in runs]], out)


@dataclass(frozen=True)
class TensionExtremes:
    peak_N: float
    peak_link: int  # 1-based index of the spring (column) where the peak occurs
    min_N: float
    min_link: int
    slack: bool  # min tension < 0: the chain would go slack there


def tension_extremes(tension_N: np.ndarray) -> TensionExtremes:
    """Largest and smallest tension over time and springs; `tension_N` is (n_times, n_springs)."""
    tension = np.asarray(tension_N, dtype=float)
    if tension.ndim != 2 or tension.size == 0 or not np.all(np.isfinite(tension)):
        raise DynamicsError(f"tension_N: got shape {tension.shape}; expected a finite (n_times, n_springs) array")
    i_max = np.unravel_index(np.argmax(tension), tension.shape)
    i_min = np.unravel_index(np.argmin(tension), tension.shape)
    low = float(tension[i_min])
    return TensionExtremes(float(tension[i_max]), int(i_max[1]) + 1, low, int(i_min[1]) + 1, low < 0.0)


@dataclass(frozen=True)
class Ranking:
    """Cam laws from best (smallest value of `metric`) to worst."""

    metric: str
    station: str
    order: tuple[tuple[str, float], ...]  # (cam, value)

    @property
    def best(self) -> str:
        return self.order[0][0]


def rank_cams(by_cam: Mapping[str, Mapping[str, StationMetrics]], metric: str, station: str = "tight-side") -> Ranking:
    """Rank cam laws by `metric` (a `StationMetrics` field; smaller is better) at `station`.

    `by_cam` maps cam id -> station name -> StationMetrics (what `station_metrics` returns)."""
    if metric not in RANKABLE:
        raise DynamicsError(f"metric: got {metric!r}; expected one of {', '.join(RANKABLE)}")
    if station not in STATIONS:
        raise DynamicsError(f"station: got {station!r}; expected one of {', '.join(STATIONS)}")
    if not by_cam:
        raise DynamicsError("by_cam: got no cam laws; expected at least one")
    values = [(cam, float(getattr(stations[station], metric))) for cam, stations in by_cam.items()]
    return Ranking(metric, station, tuple(sorted(values, key=lambda cv: (cv[1], cv[0]))))
