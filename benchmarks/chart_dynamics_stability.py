"""Stability map chart: per method, which (step or tolerance) x stiffness x N cases give a bounded,
accurate answer, which are bounded but inaccurate, and which diverge or fail; the central-difference
limit dt = 2 / omega_max(k) drawn on the fixed-step panels. Cases: verification.stability."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from dynamics.models.chain import ChainModel
from dynamics.options import DEFAULT_DAMPING_RATIO
from verification.stability import MAP_METHODS, STIFFNESSES_N_PER_M, central_difference_limit_s, stability_map

COLORS = {"accurate": "tab:green", "inaccurate": "tab:orange", "diverged": "tab:red", "failed": "tab:purple"}
N_LINKS = (10, 85)
N_MARKERS = {10: ("o", 0.8), 85: ("s", 1.25)}  # marker and vertical offset factor, so both N show


def make(out_dir: Path, quick: bool) -> list[str]:
    stiff = STIFFNESSES_N_PER_M[::2] if quick else STIFFNESSES_N_PER_M
    cases = stability_map(MAP_METHODS, stiff, N_LINKS, quick=quick)
    panels = [m for m in MAP_METHODS if m not in ("exact", "modal")] + ["exact / modal"]
    fig, axes = plt.subplots(3, 4, figsize=(15, 10.5), dpi=100)
    k_line = np.logspace(np.log10(min(stiff)) - 0.3, np.log10(max(stiff)) + 0.3, 50)
    for ax, panel in zip(axes.flat, panels):
        chosen = [
            c
            for c in cases
            if (c.method in ("exact", "modal")) == (panel == "exact / modal")
            and (panel == "exact / modal" or c.method == panel)
        ]
        for c in chosen:
            marker, offset = N_MARKERS[c.n_links]
            x = {"exact": 1.0, "modal": 2.0}[c.method] if panel == "exact / modal" else c.parameter
            ax.scatter(
                x,
                c.stiffness_N_per_m * offset,
                color=COLORS[c.outcome],
                marker=marker,
                s=36,
                edgecolors="k",
                linewidths=0.4,
            )
        ax.set_yscale("log")
        ax.set_ylabel("link stiffness k (N/m)")
        if panel == "exact / modal":
            ax.set_xticks([1, 2], ["exact", "modal (all)"])
            ax.set_xlim(0.5, 2.5)
        else:
            ax.set_xscale("log")
            name = chosen[0].parameter_name
            ax.set_xlabel("time step dt (s)" if name == "dt_s" else "rtol (atol = 1e-3 rtol)")
            if name == "rtol":
                ax.invert_xaxis()
        if panel in ("central-difference", "newmark", "hht"):
            for n, ls in zip(N_LINKS, ("--", ":")):
                limit = [central_difference_limit_s(ChainModel(n, 2.0, k).system()) for k in k_line]
                ax.plot(limit, k_line, "k", ls=ls, lw=1, label=f"2/ω_max, N={n}")
            ax.legend(fontsize=7, loc="lower left")
        ax.set_title(panel, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    legend_ax = axes.flat[len(panels)]
    for outcome, color in COLORS.items():
        legend_ax.scatter([], [], color=color, label=outcome, edgecolors="k")
    for n, (marker, _) in N_MARKERS.items():
        legend_ax.scatter([], [], color="w", edgecolors="k", marker=marker, label=f"N = {n} links")
    legend_ax.legend(loc="center", fontsize=9)
    legend_ax.axis("off")
    axes.flat[-1].axis("off")
    axes.flat[-1].text(
        0,
        0.5,
        "accurate: max |y − y_ref| ≤ 1 % of max |y_ref|\n"
        "reference: exact first-order hold\n"
        "one index cycle from rest, 180 rpm, modified sine,\n"
        f"one-degree outputs, m = 2 kg, ζ = {DEFAULT_DAMPING_RATIO:g}, friction 0\n"
        "central difference above 2/ω_max: refused\n(SolverDivergedError)",
        fontsize=8,
        va="center",
    )
    fig.suptitle("Dynamics stability map: outcome per method, step/tolerance, stiffness and N", fontsize=11)
    fig.tight_layout()
    path = out_dir / "dynamics_stability_map.png"
    fig.savefig(path)
    plt.close(fig)
    lines = []
    for method in MAP_METHODS:
        mine = [c for c in cases if c.method == method]
        counts = {o: sum(c.outcome == o for c in mine) for o in COLORS}
        worst = max(mine, key=lambda c: c.wall_s)
        lines.append(
            f"{method:18s} "
            + ", ".join(f"{o} {n}" for o, n in counts.items() if n)
            + f"; slowest case {worst.wall_s:.2f} s (k {worst.stiffness_N_per_m:.0e}, N {worst.n_links})"
        )
    cd = [c for c in cases if c.method == "central-difference"]
    agree = all((c.outcome == "diverged") == (c.parameter > c.central_difference_limit_s) for c in cd)
    lines.append(f"central difference: diverged exactly where dt > 2/omega_max: {agree}")
    return lines + [f"wrote {path}"]
