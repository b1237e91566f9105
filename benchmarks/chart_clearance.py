"""Clearance chain charts (issue #11): the explicit integrator's stability map (step / limit x link
stiffness x pin clearance), where the event-located reference fails (clearance x stiffness x rtol),
where the common-interface methods blow up or lose accuracy (step or rtol x stiffness), and the
work-precision of every method against the reference. Cases: verification.clearance_stability."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from dynamics.options import DEFAULT_PIN_CLEARANCE_M
from verification.clearance_stability import (
    CLEARANCES_M,
    EVENT_BUDGET,
    EVENT_DEGREES,
    EVENT_RTOLS,
    FIXED_STEP,
    METHOD_SETTINGS,
    OUTCOMES,
    STIFFNESSES_N_PER_M,
    event_map,
    method_map,
    method_work_precision,
    step_map,
    work_precision,
)

COLORS = dict(zip(OUTCOMES, ("tab:green", "tab:orange", "tab:red", "tab:purple")))


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def make(out_dir: Path, quick: bool) -> list[str]:
    stiff = STIFFNESSES_N_PER_M[1:2] if quick else STIFFNESSES_N_PER_M
    cases = step_map(stiff)
    fig, axes = plt.subplots(1, len(CLEARANCES_M), figsize=(4.5 * len(CLEARANCES_M), 4), dpi=100, sharey=True)
    for ax, g in zip(axes, CLEARANCES_M):
        for c in (c for c in cases if c.clearance_m == g):
            ax.scatter(c.step_factor, c.stiffness_N_per_m, color=COLORS[c.outcome], edgecolors="k", s=40)
        ax.axvline(1.0, color="k", ls="--", lw=1)
        _log_axes(ax, "step / stability limit (full-contact top frequency)", f"pin clearance {g * 1e3:g} mm")
    axes[0].set_ylabel("link stiffness k (N/m)")
    for outcome, color in COLORS.items():
        axes[-1].scatter([], [], color=color, edgecolors="k", label=outcome)
    axes[-1].legend(fontsize=8, loc="lower left")
    fig.suptitle(
        "Clearance chain, explicit velocity Verlet with the default run's ab2 predictor: outcome per step "
        "and stiffness (10 links, one index, friction 0.35; accurate = within 1 % of h_max/64)",
        fontsize=10,
    )
    map_path = _save(fig, out_dir / "clearance_stability_map.png")
    lines = [
        f"k {c.stiffness_N_per_m:.0e}, g {c.clearance_m * 1e3:g} mm, h/h_max {c.step_factor:g}: {c.outcome}"
        + ("" if c.outcome == "diverged" else f" ({c.relative_error:.1e})")
        for c in cases
    ]
    points = work_precision(substeps=(4, 16) if quick else (4, 8, 16, 32, 64), rtols=(1e-6,) if quick else (1e-6, 1e-8))
    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=100)
    for key, marker, name in (("error_x", "o", "displacement"), ("error_a", "s", "acceleration")):
        fast = [p for p in points if p.label.startswith("fast")]
        ref = [p for p in points if p.label.startswith("reference")]
        ax.loglog([p.wall_s for p in fast], [getattr(p, key) for p in fast], marker=marker, label=f"fast, {name}")
        ax.loglog(
            [p.wall_s for p in ref],
            [getattr(p, key) for p in ref],
            marker=marker,
            ls=":",
            label=f"reference (looser rtol), {name}",
        )
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("max error / max |reference|")
    ax.set_title(
        "Clearance chain work-precision: 20 links, 180° from rest,\nagainst the event-located reference at rtol 1e-10",
        fontsize=9,
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    wp_path = _save(fig, out_dir / "clearance_work_precision.png")
    lines += [f"{p.label}: {p.wall_s * 1e3:.1f} ms, error x {p.error_x:.1e}, a {p.error_a:.1e}" for p in points]
    event_path, event_lines = _event_chart(out_dir, quick)
    method_path, method_lines = _method_chart(out_dir, quick)
    methods_wp_path, wp_lines = _methods_work_precision_chart(out_dir, quick)
    return (
        lines
        + event_lines
        + method_lines
        + wp_lines
        + [f"wrote {p}" for p in (map_path, wp_path, event_path, method_path, methods_wp_path)]
    )


def _log_axes(ax, xlabel: str, title: str, fontsize: int = 10) -> None:
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_title(title, fontsize=fontsize)
    ax.grid(True, which="both", alpha=0.3)


def _legend(ax, outcomes=OUTCOMES):
    for outcome in outcomes:
        ax.scatter([], [], color=COLORS[outcome], edgecolors="k", label=outcome)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))


def _event_chart(out_dir: Path, quick: bool):
    rtols = EVENT_RTOLS[::2] if quick else EVENT_RTOLS
    cases = (
        event_map(stiffnesses=(1e6, 1e8, 1e10), clearances=(1e-7, 1e-5, 1e-3), rtols=rtols)
        if quick
        else event_map(rtols=rtols)
    )
    fig, axes = plt.subplots(1, len(rtols), figsize=(4.6 * len(rtols), 4.2), dpi=100, sharey=True)
    for ax, rtol in zip(axes, rtols):
        for c in (c for c in cases if c.rtol == rtol):
            ax.scatter(c.clearance_m, c.stiffness_N_per_m, color=COLORS[c.outcome], edgecolors="k", s=60)
            ax.annotate(
                f"{c.contact_changes}\n{c.wall_s:.1f}s",
                (c.clearance_m, c.stiffness_N_per_m),
                fontsize=6,
                xytext=(6, -2),
                textcoords="offset points",
            )
        _log_axes(ax, "pin clearance g (m)", f"rtol {rtol:g}")
    axes[0].set_ylabel("link stiffness k (N/m)")
    _legend(axes[-1], ("accurate", "inaccurate", "failed"))
    fig.suptitle(
        f"Event-located reference (solve_ivp DOP853, restarted at every contact change): 10 links, "
        f"first {EVENT_DEGREES:g}° of an index from rest;\naccurate = within 1e-3 of the fast integrator "
        f"at h_max/32; failed = more than max_events = {EVENT_BUDGET} changes; labels: contact changes, "
        "wall time",
        fontsize=9,
    )
    path = _save(fig, out_dir / "clearance_event_map.png")
    lines = [
        f"reference rtol {c.rtol:g}, k {c.stiffness_N_per_m:.0e}, g {c.clearance_m:.0e}: {c.outcome}, "
        f"{c.contact_changes} changes, {c.function_evaluations} evaluations, {c.wall_s:.2f} s"
        + (f", error {c.relative_error:.1e}" if c.outcome != "failed" else f" ({c.message})")
        for c in cases
    ]
    return path, lines


def _method_chart(out_dir: Path, quick: bool):
    stiff = (1e6, 1e8, 1e10) if quick else None
    cases = method_map(stiffnesses=stiff) if quick else method_map()
    methods = list(METHOD_SETTINGS)
    fig, axes = plt.subplots(1, len(methods), figsize=(3.8 * len(methods), 4.2), dpi=100, sharey=True)
    for ax, method in zip(axes, methods):
        for c in (c for c in cases if c.method == method):
            ax.scatter(c.setting, c.stiffness_N_per_m, color=COLORS[c.outcome], edgecolors="k", s=50)
        title = {"exact": "exact (Heun splitting of the span law)"}.get(method, method)
        if method in FIXED_STEP:
            _log_axes(ax, "omega_max h (full-contact top frequency)", title, fontsize=9)
            if method == "central-difference":
                ax.axvline(2.0, color="k", ls="--", lw=1)
        else:
            _log_axes(ax, "rtol", title, fontsize=9)
            ax.invert_xaxis()
    axes[0].set_ylabel("link stiffness k (N/m)")
    _legend(axes[-1])
    fig.suptitle(
        "Clearance chain on the common interface (ClearanceChain.system(), dynamics.solvers.solve): "
        f"10 links, {DEFAULT_PIN_CLEARANCE_M * 1e3:g} mm, friction 0, 30° from rest;\naccurate = within 1 % of the fast integrator "
        "at h_max/64 (Newmark and HHT take no nonlinear force)",
        fontsize=9,
    )
    path = _save(fig, out_dir / "clearance_method_map.png")
    lines = [
        f"{c.method}, k {c.stiffness_N_per_m:.0e}, setting {c.setting:.3g}: {c.outcome}, {c.wall_s:.2f} s"
        + ("" if c.outcome in ("diverged", "failed") else f" ({c.relative_error:.1e})")
        for c in cases
    ]
    return path, lines


def _methods_work_precision_chart(out_dir: Path, quick: bool):
    points = method_work_precision(degrees=30.0 if quick else 90.0)
    fig, ax = plt.subplots(figsize=(8, 5), dpi=100)
    families = []
    for p in points:
        family = p.label.split(",")[0]
        if family not in families:
            families.append(family)
    for family in families:
        group = [p for p in points if p.label.split(",")[0] == family]
        (line,) = ax.loglog([p.wall_s for p in group], [p.error_a for p in group], marker="s", label=family)
        ax.loglog([p.wall_s for p in group], [p.error_x for p in group], marker="o", ls=":", color=line.get_color())
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("max error / max |reference|")
    ax.plot([], [], "ks-", label="acceleration")
    ax.plot([], [], "ko:", label="displacement")
    ax.set_title(
        f"Every method on the clearance chain: 10 links, {DEFAULT_PIN_CLEARANCE_M * 1e3:g} mm, friction 0, {30 if quick else 90}° "
        "from rest, step or "
        "tolerance swept;\nagainst the event-located reference at rtol 1e-10",
        fontsize=9,
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    path = _save(fig, out_dir / "clearance_methods_work_precision.png")
    lines = [f"{p.label}: {p.wall_s * 1e3:.1f} ms, error x {p.error_x:.1e}, a {p.error_a:.1e}" for p in points]
    return path, lines
