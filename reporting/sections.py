"""The sections of report.html, each made by a section builder from a list.

A builder takes the `Report` (the run's results and what the outputs already made of them: the
summary, the tables, the figures) and returns the sections it adds, none when it has nothing to
say. The page shows the builders' sections in the list's order. A new output is one builder:

    def my_section(report: Report) -> list[html.Section]:
        return [html.Section("My output", html.paragraph(...))]

    register_section("my output", my_section, before="timing")

Builders format what the stages computed (natural frequencies, metrics, contact and validity):
they compute no physics of their own.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dynamics.options import LINEAR_ELASTIC_STRAIN_LIMIT
from dynamics.scene import ChainModelKind, Validity
from reporting import html
from reporting.tables import Table

if TYPE_CHECKING:
    from stages.chain import RunResults


@dataclass(frozen=True)
class Report:
    """What a section builder reads."""

    results: RunResults
    summary: dict  # summary.json's content
    tables: dict[str, Table]  # the tables written as CSV and Markdown, by file stem
    residual_png: Path
    figures: dict[str, dict[str, Path]]  # material -> caption label -> PNG
    images: dict[str, Path]  # material -> picture of the deformed link
    sweep_pngs: dict[str, Path]  # material -> speed sweep PNG (empty without --rpm-sweep)

    @property
    def focus(self) -> str:
        return self.results.cfg.focus_station


SectionBuilder = Callable[[Report], list[html.Section]]


@dataclass(frozen=True)
class SectionEntry:
    name: str
    build: Callable[[Any], list[html.Section]]


class SectionRegistry:
    """The ordered section builders of one kind of page (the run's report, the mqp2012 replica's)."""

    def __init__(self) -> None:
        self.entries: list[SectionEntry] = []

    def register(self, name: str, build: Callable[[Any], list[html.Section]], *, before: str | None = None) -> None:
        """Add a builder at the end of the page, or before the builder called `before`."""
        names = self.names()
        if name in names:
            raise ValueError(f"section {name!r} is already registered; expected a new name")
        if before is not None and before not in names:
            raise ValueError(f"before: no section {before!r}; expected one of {', '.join(names)}")
        self.entries.insert(len(self.entries) if before is None else names.index(before), SectionEntry(name, build))

    def names(self) -> tuple[str, ...]:
        return tuple(entry.name for entry in self.entries)

    def build(self, report) -> list[html.Section]:
        return [section for entry in self.entries for section in entry.build(report)]


PAGE = SectionRegistry()  # report.html of a run; the replica's page is reporting.replica_sections.PAGE


def register_section(name: str, build: SectionBuilder, *, before: str | None = None) -> None:
    """Add a builder to the run's report, at the end or before the builder called `before`."""
    PAGE.register(name, build, before=before)


def section_names() -> tuple[str, ...]:
    return PAGE.names()


def build_sections(report: Report) -> list[html.Section]:
    return PAGE.build(report)


def _model_paragraphs(results: RunResults) -> str:
    """Which chain model ran for which scenarios and why; the clearance chain's steady-state
    statements. A model whose response does not hold for its scene is shown as a warning."""
    groups: dict[tuple, list[str]] = {}
    linear_min: dict[tuple, list[float]] = {}
    outside: dict[tuple, list[str]] = {}  # the runs whose linear model's numbers do not hold
    statements = []
    for (m, c), scenario in results.scenarios.items():
        contact = scenario.contact
        key = (contact.model, contact.reason, contact.validity)
        groups.setdefault(key, []).append(f"{m} / {c}")
        linear_min.setdefault(key, []).append(contact.linear_min_tension_N)
        linear = contact.linear_model_validity
        if linear is not None and not linear.valid:
            outside.setdefault(key, []).append(f"{m} / {c}")
        ss = contact.steady_state
        if ss is not None and not (ss.found and ss.period_cycles == 1):
            statements.append(f"{m} / {c}: {ss.statement}")
    out = ""
    for (model, reason, validity), runs in groups.items():
        name = (
            "linear chain (exact solver)"
            if model == ChainModelKind.LINEAR
            else "clearance chain (pin free play, impacts; explicit integrator)"
        )
        css = None if validity == Validity.VALID else "warn"
        low, high = min(linear_min[model, reason, validity]) / 1e3, max(linear_min[model, reason, validity]) / 1e3
        which = (
            f"all {len(runs)} scenarios (material x cam law)" if len(groups) == 1 and len(runs) > 1 else ", ".join(runs)
        )
        marked = _outside_linear_words(outside.get((model, reason, validity), []), runs)
        out += html.paragraph(
            f"Model: {name} for {which}: {reason} (linear chain's minimum tension {low:.3g} to {high:.3g} kN{marked}).",
            "warn" if marked else css,
        )
    for text in statements:
        out += html.paragraph(text, "warn")
    return out


def _outside_linear_words(outside: list[str], runs: list[str]) -> str:
    """The mark on a group's linear minimum tension where the linear model deforms a span beyond a metal
    link's elastic range (dynamics.scene.LinearModelValidity) in some of its runs."""
    if not outside:
        return ""
    which = "" if len(outside) == len(runs) else " for " + ", ".join(outside)
    return (
        f", {Validity.OUTSIDE_LINEAR_MODEL}{which}: it deforms a span by more than "
        f"{LINEAR_ELASTIC_STRAIN_LIMIT:.0%} of the pitch, so that minimum tension and the preload for full "
        "contact describe no chain"
    )


def run_section(report: Report) -> list[html.Section]:
    inputs = report.summary["inputs"]
    geo = report.summary["geometry"]
    intro = html.paragraph(
        f"Link: {geo['source']} (pitch {geo['pitch_m'] * 1e3:.2f} mm, body volume {geo['body_volume_m3'] * 1e6:.2f} cm³). "
        f"Chain of {inputs['links']} links, cam at {inputs['rpm']:g} rpm, "
        f"{'periodic steady state of continuous indexing' if inputs['steady_state'] else 'start from rest'}, "
        f"friction μ = {inputs['friction_coefficient']:g}, damping ζ = {inputs['damping_ratio']:g}, "
        f"preload {inputs['preload_N']:g} N, solver {inputs['solver']}. Stations: "
        + ", ".join(f"{k} = link {v}" for k, v in report.summary["stations"].items())
        + "."
    )
    shortfall = report.summary["fidelity"].get("tolerance_not_met_because")
    short = html.paragraph(f"{shortfall[:1].upper()}{shortfall[1:]}.", "warn") if shortfall else ""
    return [html.Section("Run", intro + short + _model_paragraphs(report.results))]


def _wheel_words(name: str, wheel: dict) -> str:
    return (
        f"{name} ({wheel['teeth']} teeth, pitch radius {wheel['pitch_radius_m'] * 1e3:.1f} mm, "
        f"{wheel['wrap_links']} links seated, inertia {wheel['inertia_kg_m2']:.3g} kg·m²"
    )


def machine_line(summary: dict) -> str:
    """One line: which parts of the machine ran (summary.json's machine and each material's)."""
    run = summary["machine"]
    if run["drive"] == "link":
        return "Machine: the 2012 report's single-point drive, link 1 driven through the drive spring k_d; no wheels (--drive link)."
    parts = {m: data["machine"] for m, data in summary["materials"].items()}
    first = next(iter(parts.values()))
    wheels = first["wheels"]
    if first["drive_held"]:
        drive = "held to the cam"
    else:
        drive = "drive stiffness " + ", ".join(
            f"{p['drive_stiffness_N_m_per_rad']:.3g} N·m/rad ({m})" for m, p in parts.items()
        )
    idler = (
        _wheel_words("idler wheel", wheels["idler"])
        + (", on the tensioner's carriage)" if first["idler_carriage"] else ", fixed axle)")
        if "idler" in wheels
        else "idler: a point inside a span, no wheel"
    )
    frame = run["steady_state_frame"]
    return (
        f"Machine: on its wheels: {_wheel_words('drive sprocket', wheels['sprocket'])}, {drive}); {idler}; "
        f"polygonal action {'on' if run['polygonal_action'] else 'off'}"
        + _tooth_phase_words(run)
        + ("" if frame is None else f"; periodic steady state {frame} (one link seats per index)")
        + "; stations are places on the machine."
    )


def _tooth_phase_words(run: dict) -> str:
    phase = run.get("tooth_phase", 0.0)
    if phase == 0.0:
        return ", tooth phase 0 (the seats change at the dwell)"
    return (
        f", tooth phase {phase:g} (the seats change inside the index, when the cam has lifted {1 - phase:g} of a pitch)"
    )


def machine_section(report: Report) -> list[html.Section]:
    body = html.paragraph(machine_line(report.summary)) + _seating_paragraphs(report.summary)
    return [html.Section("Machine", body)]


def _seating_paragraphs(summary: dict) -> str:
    """Which seating model ran and whether it holds, grouped by its verdict and reason (summary.json's
    seating_model per scenario); a model that does not hold is a warning."""
    groups: dict[tuple, list[tuple[str, float]]] = {}
    for material, data in summary["materials"].items():
        for cam, scenario in data["cams"].items():
            seating = scenario.get("machine", {}).get("seating_model")
            if seating is not None:
                key = (
                    seating["model"],
                    seating["valid"],
                    seating["reason"],
                    seating.get("instead"),
                    seating.get("tooth_stiffness_N_per_m"),
                )
                groups.setdefault(key, []).append((f"{material} / {cam}", seating["snap_J"]))
    out = ""
    for (model, valid, reason, instead, k_t), runs in groups.items():
        model = model if k_t is None else f"{model} (k_t = {k_t:.3g} N/m)"
        snaps = [snap for _, snap in runs]
        which = f"all {len(runs)} scenarios" if len(groups) == 1 else ", ".join(name for name, _ in runs)
        verdict = "holds" if valid else "does NOT hold"
        out += html.paragraph(
            f"Seating: {model} {verdict} for {which}: {reason} (seat change's snap "
            f"{min(snaps):.3g} to {max(snaps):.3g} J per index)"
            + ("." if instead is None else f"; the model that holds there: {instead}."),
            None if valid else "warn",
        )
    return out


def fea_table(results: RunResults) -> Table:
    rows = tuple(
        (
            name,
            r.stiffness_N_per_m,
            100 * r.stiffness_rel_error_estimate,
            r.body_mass_kg,
            results.chains[name].model.link_mass_kg,
            float(results.chains[name].natural_frequencies_Hz[0]),
            r.peak_von_mises_converged_Pa_per_N * 1e3 / 1e6,
            r.dofs,
            "yes" if r.cached else "no",
        )
        for name, r in results.fea.items()
    )
    return Table(
        "Link stiffness and mass (FEA) and the chain they make",
        (
            "material",
            "k (N/m)",
            "k error estimate (%)",
            "body mass (kg)",
            "lumped mass (kg)",
            "chain f1 (Hz)",
            "converged peak von Mises per kN (MPa)",
            "FEA DOFs",
            "from cache",
        ),
        rows,
    )


def link_section(report: Report) -> list[html.Section]:
    return [
        html.Section(
            "Link stiffness and mass",
            html.table_html(fea_table(report.results))
            + "".join(
                html.image_html(p, f"{m}: deformed link (exaggerated), von Mises stress")
                for m, p in report.images.items()
            ),
        )
    ]


def cam_law_section(report: Report) -> list[html.Section]:
    return [
        html.Section(
            "Which cam law",
            html.table_html(report.tables["ranking"])
            + html.image_html(report.residual_png, "Residual vibration in the dwell per cam law and material"),
        )
    ]


def _sweep_models(report: Report) -> str:
    """Which model the speed sweeps ran (one per run: every material's chain runs on the same drive)."""
    return " and ".join(sorted({sweep.model for sweep in report.results.sweeps.values()}))


def _sweep_seating_paragraph(report: Report) -> str:
    """Which seating each material's sweep ran (each speed its own; per point in rpm_sweep.csv's
    seating_model column); nothing on the link drive, which has no seats."""
    from dynamics.response.sweep import seating_note

    notes = {m: seating_note(sweep) for m, sweep in report.results.sweeps.items()}
    said = [f"{m}: {note}" for m, note in notes.items() if note is not None]
    if not said:
        return ""
    return html.paragraph(
        "Seating at each speed, the run's own verdict at that speed (rpm_sweep.csv's seating_model column): "
        + "; ".join(said)
        + "."
    )


def speed_sweep_section(report: Report) -> list[html.Section]:
    if not report.sweep_pngs:
        return []
    return [
        html.Section(
            "Speed sweep",
            html.paragraph(
                f"Periodic steady state at the {report.focus} station versus cam speed, on "
                f"{_sweep_models(report)} (friction left out of the sweep); dashed lines: critical speeds, where a "
                "harmonic of the index frequency meets a natural frequency of that model."
            )
            + _sweep_seating_paragraph(report)
            + "".join(html.image_html(p, f"{m}: speed sweep") for m, p in report.sweep_pngs.items()),
        )
    ]


def stations_section(report: Report) -> list[html.Section]:
    return [html.Section("Accelerometer stations", html.table_html(report.tables["stations"]))]


def report_tables_section(report: Report) -> list[html.Section]:
    return [
        html.Section(
            "The report's tables",
            html.table_html(report.tables["rms_table"]) + html.table_html(report.tables["max_acceleration_table"]),
        )
    ]


def tension_section(report: Report) -> list[html.Section]:
    figures = report.figures
    return [
        html.Section(
            "Link tension and stress",
            html.table_html(report.tables["tension"])
            + "".join(
                html.image_html(f["tension map"], f"{m}: span force over time, worst cam law (grey: free play)")
                for m, f in figures.items()
                if "tension map" in f
            )
            + "".join(
                html.image_html(f["tension"], f"{m}: link tension extremes")
                for m, f in figures.items()
                if "tension" in f
            ),
        )
    ]


def time_histories_section(report: Report) -> list[html.Section]:
    return [
        html.Section(
            f"Time histories: {m}",
            "".join(
                html.image_html(p, f"{m}: {label}") for label, p in f.items() if label not in ("tension", "tension map")
            ),
        )
        for m, f in report.figures.items()
    ]


def timing_section(report: Report) -> list[html.Section]:
    return [
        html.Section(
            "Timing",
            html.table_html(
                Table("Wall time per stage (s)", ("stage", "seconds"), tuple(report.summary["timing_s"].items()))
            ),
        )
    ]


for _name, _build in (
    ("run", run_section),
    ("machine", machine_section),
    ("link", link_section),
    ("cam law", cam_law_section),
    ("speed sweep", speed_sweep_section),
    ("stations", stations_section),
    ("report tables", report_tables_section),
    ("tension", tension_section),
    ("time histories", time_histories_section),
    ("timing", timing_section),
):
    register_section(_name, _build)
