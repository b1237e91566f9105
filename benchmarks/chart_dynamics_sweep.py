"""Speed-sweep chart: residual vibration and peak acceleration at the tight-side station versus cam
speed, 5 cam laws, default chain (85 links, Al figures), 1000 speeds from 30 to 300 rpm."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from dynamics.models.chain import ChainModel
from dynamics.models.mqp2012 import CAMS
from dynamics.response.sweep import rpm_sweep
from reporting.plots import plot_rpm_sweep


def make(out_dir: Path, quick: bool) -> list[str]:
    model = ChainModel(85, 2.03, 92696969.7)
    rpms = np.linspace(30.0, 300.0, 100 if quick else 1000)
    start = time.perf_counter()
    result = rpm_sweep(model, CAMS, rpms)
    wall = time.perf_counter() - start
    path = out_dir / "dynamics_rpm_sweep.png"
    plot_rpm_sweep(result, path)
    i180 = int(np.argmin(np.abs(rpms - 180.0)))
    lines = [f"{rpms.size} speeds x {len(CAMS)} cams, 85 modes, {result.samples_per_cycle} samples/cycle: {wall:.2f} s"]
    for k, cam in enumerate(CAMS):
        lines.append(
            f"  {cam:20s} at {rpms[i180]:.1f} rpm: residual {result.residual_vibration_m[k, i180] * 1e3:.3f} mm, "
            f"peak |a| {result.peak_acceleration_m_s2[k, i180]:.4g} m/s^2"
        )
    lines.append(
        "critical speeds (rpm, mode, harmonic): "
        + ", ".join(f"{c.rpm:.1f} (m{c.mode}, h{c.harmonic})" for c in result.critical_speeds)
    )
    return lines + [f"wrote {path}"]
