"""Work-precision of the peak von Mises stress on the default link (aluminium, per newton of pin load).

Two ways to a peak stress, against wall time (meshing + solve + stress, cumulative):
- uniform refinement: the peak away from the clamped bore on meshes of 6, 4.5, 3.4 (and 2.6) mm;
- local refinement at the hot spots (`fem.stress.stress_study` from the 4.5 mm mesh of the
  stiffness study, ball sizes halved per level) with its 5 % stopping rule (2 % in the full run, so
  the chart shows where it goes).
The y axis is the relative difference to the finest local-refinement value; the grey band is that
value's own last change under refinement (its estimate): differences inside it are not resolved.
"""

from __future__ import annotations

import time
from pathlib import Path

import matplotlib.pyplot as plt
from chart_fea_workprecision import _finish  # benchmarks/ is on the path (charts.py)

import fem
import geometry
from fem.settings import DEFAULT_BORE_REFINEMENT
from fem.stress import stress_study

MATERIAL = "al6061-t6"
BASE_M = 0.0045


def measure(quick: bool):
    material = fem.get_material(MATERIAL)
    uniform = []
    elapsed = 0.0
    for h in (0.006, 0.0045) if quick else (0.006, 0.0045, 0.0034, 0.0026):
        start = time.perf_counter()
        link = geometry.load_link(None, mesh_size_m=h, order=2, bore_refinement=DEFAULT_BORE_REFINEMENT)
        s = fem.analyse_link(link, material)
        elapsed += time.perf_counter() - start
        uniform.append((h, s.dofs, s.peak_von_mises_away_from_clamp_Pa_per_N, elapsed))
    local = stress_study(None, [material], base_mesh_size_m=BASE_M, stress_tolerance=0.05 if quick else 0.02)[MATERIAL]
    return uniform, local


def make(out_dir: Path, quick: bool) -> list[str]:
    uniform, local = measure(quick)
    best = local.peak_Pa_per_N
    fig, ax = plt.subplots(figsize=(8.5, 6), dpi=100)
    lines = []
    ax.semilogx(
        [t for *_, t in uniform],
        [abs(p / best - 1) for _, _, p, _ in uniform],
        "s-",
        label="uniform refinement (6, 4.5, 3.4, 2.6 mm)",
    )
    for h, dofs, peak, t in uniform:
        lines.append(f"uniform {h * 1e3:.2g} mm: {dofs} DOFs, peak {peak * 1e-3:.4g} MPa/kN, cumulative {t:.1f} s")
    times = local.level_seconds
    ax.semilogx(
        times,
        [abs(p / best - 1) for _, _, p in local.levels],
        "o-",
        label="local refinement at the hot spots (fem.stress), from the 4.5 mm mesh",
    )
    for (size, dofs, peak), t in zip(local.levels, times):
        lines.append(f"local {size * 1e3:.2g} mm: {dofs} DOFs, peak {peak * 1e-3:.4g} MPa/kN, cumulative {t:.1f} s")
    ax.axhspan(
        0,
        local.rel_change,
        color="grey",
        alpha=0.2,
        label=f"finest value's last change ({local.rel_change * 100:.1f} %): not resolved",
    )
    ax.axhline(0.05, color="k", ls=":", label="5 % (the issue's convergence target)")
    ax.set_xlabel("wall time (s), cumulative: meshing + assembly + solve + stress")
    ax.set_ylabel("relative difference to the finest local-refinement peak")
    ax.set_title(
        f"Peak von Mises stress work-precision, default link, aluminium: {best * 1e-3:.4g} MPa per kN "
        f"at {tuple(round(x * 1e3, 1) for x in local.location_m)} mm",
        fontsize=9,
    )
    return lines + [local.description, _finish(fig, ax, out_dir / "fea_stress_work_precision.png")]
