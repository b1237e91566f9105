"""Figures of a design study: the Pareto front, each metric against each design variable, and a
parallel-coordinates view of the designs. Values come in SI; axes show mm, MPa or kN where that
reads better (`display_unit`). Every function writes one PNG and returns its path."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from reporting.plots import _save, plt

#: column-name suffix -> (unit shown, factor from SI)
UNITS = (
    ("_N_per_m", "N/m", 1.0),
    ("_Pa_per_N", "MPa/N", 1e-6),
    ("_m_s2", "m/s²", 1.0),
    ("_m_s", "m/s", 1.0),
    ("_m3", "cm³", 1e6),
    ("_Pa", "MPa", 1e-6),
    ("_Hz", "Hz", 1.0),
    ("_kg", "kg", 1.0),
    ("_N", "kN", 1e-3),
    ("_m", "mm", 1e3),
    ("_s", "s", 1.0),
)


def display_unit(name: str) -> tuple[str, float]:
    """(axis label, factor from SI) of a column, e.g. web_thickness_m -> ('web thickness (mm)', 1e3)."""
    for suffix, unit, factor in UNITS:
        if name.endswith(suffix):
            return f"{name[: -len(suffix)].replace('_', ' ')} ({unit})", factor
    return name.replace("_", " "), 1.0


def _values(rows: list[dict], name: str) -> np.ndarray:
    factor = display_unit(name)[1]
    return np.array([np.nan if r.get(name) is None else float(r[name]) * factor for r in rows], dtype=float)


def plot_pareto(rows: list[dict], objectives: list[str], path: Path) -> Path:
    """The first two objectives of every computed design: infeasible grey, feasible blue, the front
    red and joined in order."""
    x_name, y_name = objectives[:2]
    fig, ax = plt.subplots(figsize=(7, 5))
    groups = (
        ("infeasible (constraints)", [r for r in rows if r["status"] == "ok" and not r["feasible"]], "0.7", "x"),
        ("feasible", [r for r in rows if r["feasible"] and not r["pareto"]], "tab:blue", "o"),
        ("Pareto front", [r for r in rows if r["pareto"]], "tab:red", "D"),
    )
    for label, members, colour, marker in groups:
        if members:
            ax.scatter(
                _values(members, x_name),
                _values(members, y_name),
                c=colour,
                marker=marker,
                s=28,
                label=f"{label} ({len(members)})",
                zorder=3 if label == "Pareto front" else 2,
            )
    front = [r for r in rows if r["pareto"]]
    if len(front) > 1:
        x, y = _values(front, x_name), _values(front, y_name)
        order = np.argsort(x)
        ax.plot(x[order], y[order], color="tab:red", lw=1, drawstyle="steps-post")
    ax.set_xlabel(display_unit(x_name)[0])
    ax.set_ylabel(display_unit(y_name)[0])
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Pareto front" + (" (objectives 3+ not drawn)" if len(objectives) > 2 else ""))
    return _save(fig, path)


def plot_metrics_vs_variables(rows: list[dict], metrics: list[str], variables: list[str], path: Path) -> Path:
    """A grid: one row per metric, one column per design variable; feasible designs filled,
    infeasible hollow, colour by material."""
    computed = [r for r in rows if r["status"] == "ok"]
    materials = sorted({r["material"] for r in computed})
    colours = dict(zip(materials, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
    fig, axes = plt.subplots(
        len(metrics), len(variables), figsize=(3.2 * len(variables), 2.6 * len(metrics)), squeeze=False
    )
    for i, metric in enumerate(metrics):
        for j, variable in enumerate(variables):
            ax = axes[i, j]
            for material in materials:
                for feasible in (True, False):
                    members = [r for r in computed if r["material"] == material and r["feasible"] == feasible]
                    if members:
                        ax.scatter(
                            _values(members, variable),
                            _values(members, metric),
                            s=14,
                            facecolors=colours[material] if feasible else "none",
                            edgecolors=colours[material],
                            label=f"{material}{'' if feasible else ' (infeasible)'}",
                        )
            ax.grid(alpha=0.3)
            if i == len(metrics) - 1:
                ax.set_xlabel(display_unit(variable)[0])
            if j == 0:
                ax.set_ylabel(display_unit(metric)[0], fontsize=8)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="upper center", ncol=min(4, len(labels)), fontsize=8)
    return _save(fig, path)


def plot_parallel_coordinates(rows: list[dict], columns: list[str], path: Path) -> Path:
    """Each computed design a line across its variables and metrics (each axis scaled to its range):
    infeasible grey, feasible blue, Pareto red on top."""
    computed = [r for r in rows if r["status"] == "ok"]
    data = np.column_stack([_values(computed, c) for c in columns]) if computed else np.zeros((0, len(columns)))
    low, high = np.nanmin(data, axis=0, initial=np.inf), np.nanmax(data, axis=0, initial=-np.inf)
    span = np.where(high > low, high - low, 1.0)
    scaled = (data - low) / span
    fig, ax = plt.subplots(figsize=(max(8, 1.3 * len(columns)), 5))
    x = np.arange(len(columns))
    for keep, colour, width, z in (
        (lambda r: not r["feasible"], "0.75", 0.6, 1),
        (lambda r: r["feasible"] and not r["pareto"], "tab:blue", 0.8, 2),
        (lambda r: r["pareto"], "tab:red", 1.6, 3),
    ):
        for row, line in zip(computed, scaled):
            if keep(row):
                ax.plot(x, line, color=colour, lw=width, alpha=0.8, zorder=z)
    ax.set_xticks(x, [display_unit(c)[0] for c in columns], rotation=30, ha="right", fontsize=8)
    for i in x:
        ax.axvline(i, color="k", lw=0.5)
        if np.isfinite(low[i]):
            ax.text(i, -0.04, f"{low[i]:.3g}", ha="center", va="top", fontsize=7)
            ax.text(i, 1.02, f"{high[i]:.3g}", ha="center", va="bottom", fontsize=7)
    ax.set_yticks([])
    ax.set_ylim(-0.12, 1.1)
    ax.set_title("designs across variables and metrics (grey: infeasible, blue: feasible, red: Pareto front)")
    return _save(fig, path)


def plot_convergence(history: list[dict], objective: str, path: Path) -> Path:
    """Best penalised objective per optimiser generation."""
    label, factor = display_unit(objective)
    fig, ax = plt.subplots(figsize=(6, 4))
    gens = [h["generation"] for h in history]
    ax.plot(gens, [h["best_objective"] * factor for h in history], marker="o")
    ax.set_xlabel("generation")
    ax.set_ylabel(f"best {label} (penalised)")
    ax.grid(alpha=0.3)
    ax.set_title("optimiser convergence")
    return _save(fig, path)


def plot_sensitivity(found, path: Path) -> Path:
    """One metric's first-order indices (study.sensitivity.MetricSensitivity), largest on top, with
    their intervals; range variables blue, list variables orange; the adequacy verdict in the title
    (red when the points are too few to rank the inputs)."""
    indices = list(reversed(found.indices))
    fig, ax = plt.subplots(figsize=(7, 0.45 * max(len(indices), 2) + 1.6))
    y = np.arange(len(indices))
    colours = ["tab:blue" if i.kind == "range" else "tab:orange" for i in indices]
    ax.barh(
        y,
        [i.first_order for i in indices],
        xerr=[i.half_width for i in indices],
        color=colours,
        error_kw={"ecolor": "k", "capsize": 3, "lw": 1},
    )
    ax.set_yticks(y, [i.input for i in indices], fontsize=8)  # the study file's names
    ax.axvline(0, color="k", lw=0.6)
    ax.set_xlim(
        min([-0.05, *(i.first_order - i.half_width for i in indices)]),
        max([1.0, *(i.first_order + i.half_width for i in indices)]),
    )
    ax.set_xlabel("first-order index S1 (share of the variance explained alone), 95 % interval")
    ax.grid(axis="x", alpha=0.3)
    kinds = [k for k in ("range", "list") if any(i.kind == k for i in indices)]
    ax.legend(
        [plt.Rectangle((0, 0), 1, 1, color="tab:blue" if k == "range" else "tab:orange") for k in kinds],
        [f"{k} variable" for k in kinds],
        fontsize=8,
        loc="lower right",
    )
    ax.set_title(f"{found.metric}\n{found.adequacy}", fontsize=9, color="k" if found.adequate else "tab:red")
    if not indices:
        ax.text(0.5, 0.5, found.adequacy, ha="center", va="center", transform=ax.transAxes, fontsize=8, wrap=True)
    return _save(fig, path)
