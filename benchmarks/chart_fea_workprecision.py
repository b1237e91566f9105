"""FEA work-precision and cost growth on the default link (aluminium 6061-T6, 1 kN pin load).

Work-precision (fea_work_precision.png): relative error of k against wall time (meshing +
basis/load + assembly + solve; stress post-processing excluded), log-log, for
- P1 on linear tets,
- P2 on straight tets (order-1 mesh, quadratic field),
- P2 on curved tets (isoparametric, the default),
each over mesh sizes h = 16 mm x (3/4)^i (bore refinement 0.7, as stiffness_study), plus the
studies that certify their answer, each drawn as its actual error (filled) and its estimate
(open, same time) joined by a line: the previous default (three uniform levels 6.5 / 4.5 / 3.5 mm),
the same two levels relative to the part (6 / 4.5 mm on this link) on the whole link and as the new
default runs them (the finest on the link's mirror half), a finer pair on the whole link, and the
adaptive `stiffness_to_tolerance` runs (tolerances 5 % and 1 %).
Reference: Richardson extrapolation (fem.richardson) of curved P2 on the three finest levels, each
with more DOFs than any plotted point; its own estimated error is drawn as a band: errors below it
are not resolved.

Cost growth (fea_cost_growth.png): the curved-P2 levels' time against DOFs, split into meshing,
assembly (basis + load + stiffness) and solve (PARDISO), with power-law exponents fitted over the
levels with >= 20k DOFs. Each point is one cold run in this process.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import NamedTuple

import matplotlib.pyplot as plt
import numpy as np

import fem
import geometry
from fem.adaptive import stiffness_to_tolerance
from fem.richardson import Extrapolation, extrapolate
from fem.settings import DEFAULT_BORE_REFINEMENT
from fem.study import StiffnessEstimate

MATERIAL = "al6061-t6"
RATIO = 4 / 3
FIT_MIN_DOFS = 20_000


# A NamedTuple, not a dataclass: benchmarks/run.py loads modules without registering them in
# sys.modules, which dataclasses need to resolve string annotations.
class Point(NamedTuple):
    kind: str
    mesh_size_m: float
    dofs: int
    stiffness_N_per_m: float
    timing_s: dict[str, float]  # mesh, assembly (basis + load + stiffness), solve

    @property
    def wall_s(self) -> float:
        return sum(self.timing_s.values())


KINDS = {  # kind: (element order, geometry mesh order)
    "P1 (linear tets)": (1, 1),
    "P2 straight tets": (2, 1),
    "P2 curved tets (default)": (2, 2),
}


def solve_point(kind: str, h: float) -> Point:
    order, mesh_order = KINDS[kind]
    start = time.perf_counter()
    link = geometry.load_link(None, mesh_size_m=h, order=mesh_order, bore_refinement=DEFAULT_BORE_REFINEMENT)
    mesh_s = time.perf_counter() - start
    s = fem.analyse_link(link, fem.get_material(MATERIAL), order=order)
    timing = {
        "mesh": mesh_s,
        "assembly": s.timing_s.get("basis_and_load", 0.0) + s.timing_s.get("load", 0.0) + s.timing_s["assembly"],
        "solve": s.timing_s["solve"],
    }
    return Point(kind, h, s.dofs, s.stiffness_N_per_m, timing)


def sizes(coarsest_m: float, n: int) -> list[float]:
    return [coarsest_m / RATIO**i for i in range(n)]


def fit_exponent(dofs, times) -> float:
    dofs, times = np.asarray(dofs, float), np.asarray(times, float)
    keep = dofs >= FIT_MIN_DOFS
    if keep.sum() < 2:
        keep = np.ones_like(dofs, dtype=bool)
    return float(np.polyfit(np.log(dofs[keep]), np.log(times[keep]), 1)[0])


class Measurements(NamedTuple):
    curves: dict[str, list[Point]]  # plotted points per kind, coarse to fine
    curved_levels: list[Point]  # every curved-P2 level, the reference's three last
    reference: Extrapolation
    adaptive: dict[float, StiffnessEstimate]  # stiffness_to_tolerance runs by tolerance
    studies: dict[str, StiffnessEstimate]  # fixed-level studies, by label


def measure(quick: bool) -> Measurements:
    """Solve every point (see the module doc); quick: coarser levels and a rougher reference."""
    plotted_p2 = sizes(0.016, 3 if quick else 5)
    reference_sizes = [0.0065, 0.0051, 0.0045] if quick else [0.0038, 0.00285, 0.0025]
    p1_sizes = sizes(0.012, 3 if quick else 6)
    curved = [solve_point("P2 curved tets (default)", h) for h in plotted_p2 + reference_sizes]
    reference_levels = curved[-3:]
    reference = extrapolate([p.stiffness_N_per_m for p in reference_levels], [p.dofs for p in reference_levels])
    curves = {
        "P1 (linear tets)": [solve_point("P1 (linear tets)", h) for h in p1_sizes],
        "P2 straight tets": [solve_point("P2 straight tets", h) for h in plotted_p2],
        "P2 curved tets (default)": curved[: len(plotted_p2)],
    }
    if max(p.dofs for pts in curves.values() for p in pts) >= reference_levels[0].dofs:
        raise RuntimeError("the reference levels must have more DOFs than every plotted point")
    material = fem.get_material(MATERIAL)
    adaptive = {tol: stiffness_to_tolerance(None, material, tol) for tol in ((0.05,) if quick else (0.05, 0.01))}
    whole = {"mirror_symmetry": False}  # the paths before the mirror half, as they ran
    studies = {
        "previous default: 3 uniform levels 6.5/4.5/3.5 mm": fem.stiffness_study(
            None, material, mesh_sizes_m=(0.0065, 0.0045, 0.0035), **whole
        ),
        "2 levels relative to the part (6/4.5 mm), whole link": fem.stiffness_study(None, material, **whole),
        "new default: the same, finest on the mirror half": fem.stiffness_study(None, material),
    }
    if not quick:
        studies["2 levels 4.5/3.4 mm, whole link"] = fem.stiffness_study(
            None, material, mesh_sizes_m=(0.0045, 0.003375), **whole
        )
    return Measurements(curves, curved, reference, adaptive, studies)


def relative_error(k: float, reference: Extrapolation) -> float:
    return abs(k - reference.extrapolated) / reference.extrapolated


def adaptive_wall_s(estimate: StiffnessEstimate) -> float:
    """Meshing + assembly + solve over all levels (stress post-processing excluded, as for the points)."""
    return sum(value for key, value in estimate.timing_s.items() if key not in ("total", "post"))


def plot_work_precision(m: Measurements, path: Path) -> list[str]:
    ref = m.reference
    levels = m.curved_levels[-3:]
    lines = [
        f"reference k = {ref.extrapolated:.6e} N/m (curved P2, levels "
        f"{', '.join(f'{p.mesh_size_m * 1e3:.3g} mm/{p.dofs}' for p in levels)} DOFs), "
        f"estimated relative error {ref.rel_error_estimate:.1e}, observed rate {ref.observed_rate}"
    ]
    fig, ax = plt.subplots(figsize=(8.5, 6), dpi=100)
    for (kind, pts), marker in zip(m.curves.items(), "s^o"):
        errors = [relative_error(p.stiffness_N_per_m, ref) for p in pts]
        ax.loglog([p.wall_s for p in pts], errors, marker=marker, label=kind)
        for p, e in zip(pts, errors):
            lines.append(
                f"{kind}: h = {p.mesh_size_m * 1e3:.3g} mm, {p.dofs} DOFs, k = {p.stiffness_N_per_m:.6e} N/m, "
                f"error {e:.2e}, {p.wall_s:.2f} s (mesh {p.timing_s['mesh']:.2f}, assembly {p.timing_s['assembly']:.2f}, solve {p.timing_s['solve']:.2f})"
            )
    certified = {f"stiffness_to_tolerance({tol:g})": est for tol, est in m.adaptive.items()} | m.studies
    for (label, est), marker in zip(certified.items(), "*DPXhv"):
        actual = relative_error(est.stiffness_N_per_m, ref)
        wall = adaptive_wall_s(est)
        estimate = est.stiffness_rel_error_estimate
        ax.loglog([wall, wall], [actual, estimate], "k-", lw=0.8)
        ax.loglog(
            [wall], [actual], "k" + marker, markersize=9, label=f"{label}: actual error (filled), estimate (open)"
        )
        ax.loglog([wall], [estimate], marker, color="k", markerfacecolor="none", markersize=9)
        lines.append(
            f"{label}: {len(est.levels)} levels, estimated error {estimate:.2e}, "
            f"actual {actual:.2e}, {wall:.1f} s (meshing + assembly + solve)"
        )
    ax.axhspan(
        1e-6,
        ref.rel_error_estimate,
        color="grey",
        alpha=0.2,
        label=f"below the reference's own estimated error ({ref.rel_error_estimate:.1e}): not resolved",
    )
    ax.set_xlabel("wall time (s): meshing + assembly + solve, 2 cores")
    ax.set_ylabel("relative error of k against the reference")
    ax.set_title(
        f"FEA work-precision, default link, aluminium; reference k = {ref.extrapolated / 1e6:.2f} MN/m (Richardson, curved P2)",
        fontsize=9,
    )
    ax.set_ylim(bottom=1e-4)
    walls = [p.wall_s for pts in m.curves.values() for p in pts] + [adaptive_wall_s(e) for e in certified.values()]
    ax.set_xlim(0.8 * min(walls), 1.5 * max(walls))
    return lines + [_finish(fig, ax, path)]


def plot_cost_growth(m: Measurements, path: Path) -> list[str]:
    fig, ax = plt.subplots(figsize=(8.5, 6), dpi=100)
    dofs = [p.dofs for p in m.curved_levels]
    parts = {"total": [p.wall_s for p in m.curved_levels]}
    parts |= {part: [p.timing_s[part] for p in m.curved_levels] for part in ("mesh", "assembly", "solve")}
    lines = []
    for (part, times), marker in zip(parts.items(), "oD^v"):
        exponent = fit_exponent(dofs, times)
        ax.loglog(dofs, times, marker=marker, label=f"{part}: time ~ DOFs^{exponent:.2f}")
        lines.append(
            f"cost growth, curved P2, {part}: exponent {exponent:.2f} (fit over >= {FIT_MIN_DOFS} DOFs); "
            + ", ".join(f"{d}: {t:.2f} s" for d, t in zip(dofs, times))
        )
    ax.set_xlabel("FEA degrees of freedom (curved P2)")
    ax.set_ylabel("wall time (s), 2 cores")
    ax.set_title(
        "FEA cost growth on the default link: meshing (gmsh HXT), assembly (scikit-fem blocks), solve (PARDISO)",
        fontsize=9,
    )
    return lines + [_finish(fig, ax, path)]


def _finish(fig, ax, path: Path) -> str:
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return f"wrote {path}"


def make(out_dir: Path, quick: bool) -> list[str]:
    m = measure(quick)
    return plot_work_precision(m, out_dir / "fea_work_precision.png") + plot_cost_growth(
        m, out_dir / "fea_cost_growth.png"
    )
