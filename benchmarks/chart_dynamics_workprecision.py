"""Dynamics work-precision chart: error against wall time for every solver, N = 85 and N = 400.

Wall time: best of 2 cold runs at N = 85 (the machine is shared), one run at N = 400.
Problem, reference and error: verification.workprecision (linear default chain, friction 0, k 9e7 N/m,
m 2 kg, modified sine at 180 rpm, two index cycles from rest, one-degree outputs).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from dynamics.options import DEFAULT_DAMPING_RATIO
from verification.workprecision import (
    ALL_METHODS,
    chain_problem,
    force_sampling_error,
    measure,
    reference_response,
    settings,
)

FLOOR_M = 1e-17  # plotted in place of an error of exactly zero
SLOW_AT_LARGE_N = ("radau", "bdf", "lsoda")  # dense implicit solves: keep to their loose tolerances


def sweep(n_links: int, quick: bool):
    problem = chain_problem(n_links)
    ref = reference_response(problem)
    large = n_links > 200
    results = []
    for method in ALL_METHODS:
        name, values = settings(method, problem, quick or large)
        if large and method in SLOW_AT_LARGE_N:
            values = values[:2]
        results.extend(measure(problem, method, ref, name, v, repeats=1 if large else 2) for v in values)
    return problem, ref, results


def make(out_dir: Path, quick: bool) -> list[str]:
    sizes = (85, 400) if not quick else (85, 200)
    fig, axes = plt.subplots(1, len(sizes), figsize=(14, 6.2), dpi=100)
    colors = {"exact": "k", **{m: plt.get_cmap("tab10")(i) for i, m in enumerate(ALL_METHODS[1:])}}
    markers = dict(zip(ALL_METHODS, "*osD^vP<>Xh"))
    lines = []
    for ax, n in zip(axes, sizes):
        problem, ref, results = sweep(n, quick)
        floor = force_sampling_error(problem)
        for method in ALL_METHODS:
            pts = [m for m in results if m.method == method and m.status == "ok"]
            if not pts:
                continue
            t = [m.wall_s for m in pts]
            e = [max(m.error_m, FLOOR_M) for m in pts]
            ax.loglog(
                t,
                e,
                "-",
                color=colors[method],
                marker=markers[method],
                ms=14 if method == "exact" else 5,
                label=method,
                lw=1.2,
            )
            best = min(pts, key=lambda m: m.wall_s)
            lines.append(
                f"N={n} {method:18s} fastest {best.wall_s * 1e3:9.2f} ms at error {best.error_m:.3g} m; "
                f"most accurate {min(m.error_m for m in pts):.3g} m"
            )
        failed = [m for m in results if m.status != "ok"]
        for m in failed:
            lines.append(f"N={n} {m.method} {m.parameter_name}={m.parameter:g}: {m.status}")
        ax.axhline(floor, color="k", ls=":", lw=1)
        ax.text(
            ax.get_xlim()[0] * 1.1,
            floor * 1.4,
            "force sampling error (1° first-order hold vs analytic cam)",
            fontsize=7,
        )
        ax.set_xlabel("wall time per solve (s), cold (one-off set-up included)")
        ax.set_ylabel("max |x − x_ref| over links and output times (m)")
        ax.set_title(
            f"N = {n} links (2N = {2 * n} states); peak |x − z| = {np.max(np.abs(ref)) * 1e3:.2f} mm", fontsize=10
        )
        ax.grid(True, which="both", alpha=0.3)
        lines.append(f"N={n}: force sampling error {floor:.3g} m, peak relative deflection {np.max(np.abs(ref)):.3g} m")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8)
    fig.suptitle(
        "Dynamics work-precision. Linear model (friction 0), so the reference is exact: the first-order-hold "
        f"solution (4 sub-steps),\nk = 9e7 N/m, m = 2 kg, ζ = {DEFAULT_DAMPING_RATIO:g}, modified sine, 180 rpm, "
        "2 index cycles from rest, "
        "one-degree outputs. Sweeps: modal 1..N modes, Newmark/HHT/central difference dt, RK rtol (atol = 1e-3 rtol).",
        fontsize=9,
    )
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    path = out_dir / "dynamics_work_precision.png"
    fig.savefig(path)
    plt.close(fig)
    return lines + [f"wrote {path}"]
