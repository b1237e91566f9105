"""Everything a finished study writes beside its point files: the table (Parquet, CSV), the
feasible set and the Pareto front, which inputs matter (sensitivity.csv/.json), the plots, the page, and pipeline.py's full report of the best
designs (made on a worker, written here)."""

from __future__ import annotations

from pathlib import Path

from study.results import StudyResults, assemble, best_designs, summary_counts, varied_numeric, write_tables
from study.sampling import DesignPoint
from study.spec import StudySpec
from study.store import ResultStore

#: Metrics drawn against the variables when the study names none in its objectives/constraints.
DEFAULT_PLOTTED = ("body_mass_kg", "stiffness_N_per_m", "residual_vibration_m", "yield_safety_factor")


def write_outputs(
    spec: StudySpec, points: list[DesignPoint], store: ResultStore, out: Path, client, bar, history: dict | None
) -> StudyResults:
    results = assemble(spec, points, store)
    write_tables(results, out)
    sensitivity = _write_sensitivity(spec, results, out)
    reports = _best_reports(spec, results, out, client, bar) if spec.report_best else []
    _write_page(spec, results, out, reports, history, sensitivity)
    bar.message(
        f"{len(results.rows)} points in {out}/results.parquet: {len(results.feasible)} feasible, "
        f"{len(results.front)} on the Pareto front; page {out}/index.html"
    )
    return results


def plotted_metrics(spec: StudySpec) -> list[str]:
    from study.records import FLAGS, METRICS

    named = [o.metric for o in spec.objectives] + [c.metric for c in spec.constraints]
    chosen = [m for m in dict.fromkeys(named) if m in METRICS and m not in FLAGS]
    return chosen or list(DEFAULT_PLOTTED)


def sensitivity_metrics(spec: StudySpec) -> list[str]:
    """The metrics whose sensitivity is estimated: the objectives, else the plotted metrics."""
    from study.records import METRICS

    objectives = [o.metric for o in spec.objectives if o.metric in METRICS]
    return objectives or plotted_metrics(spec)


def _write_sensitivity(spec: StudySpec, results: StudyResults, out: Path):
    """sensitivity.json and sensitivity.csv (one row per metric and input); None for a study that
    is not sampled with lhs or sobol (nothing written)."""
    import json

    from fem.cache import write_text_atomic
    from study.sensitivity import as_json, as_rows, study_sensitivity
    from study.store import write_csv

    found = study_sensitivity(spec, results.rows, sensitivity_metrics(spec))
    if found is None:
        return None
    write_text_atomic(out / "sensitivity.json", json.dumps(as_json(found), indent=1))
    rows = as_rows(found)
    write_csv(
        rows,
        ["metric", "input", "kind", "first_order", "half_width", "samples", "dropped", "adequate", "adequacy"],
        out / "sensitivity.csv",
    )
    return found


def _best_reports(spec: StudySpec, results: StudyResults, out: Path, client, bar) -> list[tuple[str, str]]:
    from study.tasks import part_payloads, report_task

    best = best_designs(spec, results)
    cams = tuple(spec.choices["cam"].values) if "cam" in spec.choices else (spec.fixed["cam"],)
    parts = part_payloads(spec)
    futures = [
        client.submit(
            report_task,
            {k: r[k] for k in _inputs_of(results)},
            cams,
            spec.settings,
            parts.get(r.get("geometry_file")),
            pure=False,
        )
        for r in best
    ]
    links = []
    for row, future in zip(best, futures):
        folder = out / "best" / f"point-{row['point']:05d}"
        folder.mkdir(parents=True, exist_ok=True)
        for name, data in future.result().items():
            (folder / name).write_bytes(data)
        links.append((f"point {row['point']}: {row['material']}, {row['cam']}", f"best/{folder.name}/report.html"))
        bar.message(f"full report of point {row['point']} in {folder}")
    return links


def _inputs_of(results: StudyResults) -> list[str]:
    from study.records import METRICS
    from study.results import IDENTITY, OUTCOME

    return [
        c
        for c in results.columns
        if c not in IDENTITY and c not in OUTCOME and c not in METRICS and c != "fea_warnings"
    ]


def _write_page(spec: StudySpec, results: StudyResults, out: Path, reports, history, sensitivity) -> None:
    from reporting.study_page import design_table, reason_table, write_study_page
    from reporting.study_plots import plot_metrics_vs_variables, plot_parallel_coordinates, plot_pareto
    from reporting.tables import Table

    counts = summary_counts(results)
    variables = varied_numeric(spec)
    metrics = plotted_metrics(spec)
    objectives = [o.metric for o in spec.objectives]
    intro = [
        f"{counts['points']} design points ({', '.join(f'{n} {_describe(v)}' for n, v in spec.variables.items())}; "
        f"sampling: {spec.sampling.method}, seed {spec.sampling.seed}); {counts['computed']} computed, "
        f"{counts['feasible']} feasible, {counts['pareto']} on the Pareto front.",
        "Constraints: "
        + ("; ".join(_constraint_text(c) for c in spec.constraints) or "none")
        + ". Objectives: "
        + (", ".join(f"{o.sense}imise {o.metric}" for o in spec.objectives) or "none")
        + ".",
    ]
    tables = [reason_table(counts["not_computed"])] if counts["not_computed"] else []
    refused = {
        r["geometry_file"]: r["reason"]
        for r in results.rows
        if spec.parts and r["status"] != "ok" and r["reason"].startswith("geometry:")
    }
    if refused:
        tables.append(
            Table(
                "STEP files refused (their points are infeasible)",
                ("geometry", "reason"),
                tuple(sorted(refused.items())),
            )
        )
    shown = [
        "point",
        *(["geometry_file"] if spec.parts else []),
        "material",
        "cam",
        *variables,
        *dict.fromkeys(objectives + metrics),
    ]
    tables.append(design_table("Pareto front", results.front, shown))
    figures = []
    if len(objectives) >= 2 and results.feasible:
        figures.append(
            (
                "Pareto front",
                plot_pareto(results.rows, objectives, out / "pareto.png"),
                f"{objectives[0]} against {objectives[1]}, every computed design",
            )
        )
    if variables and any(r["status"] == "ok" for r in results.rows):
        figures.append(
            (
                "Metrics against the design variables",
                plot_metrics_vs_variables(results.rows, metrics, variables, out / "metrics_vs_variables.png"),
                "filled: feasible, hollow: infeasible; colour: material",
            )
        )
        figures.append(
            (
                "Parallel coordinates",
                plot_parallel_coordinates(results.rows, variables + metrics, out / "parallel_coordinates.png"),
                "each design a line; axes scaled to their ranges (ends labelled)",
            )
        )
    intro.append(_sensitivity_text(spec, sensitivity))
    figures += _sensitivity_figures(sensitivity or [], out)
    optimiser = None
    if history is not None:
        from reporting.study_plots import plot_convergence

        gens = history["generations"]
        table = Table(
            "Convergence",
            ("generation", "best objective", "evaluations"),
            tuple((g["generation"], g["best_objective"], g["evaluations"]) for g in gens),
        )
        png = plot_convergence(gens, history["objective"], out / "convergence.png") if gens else None
        optimiser = (history["notes"], table, png)
    write_study_page(out / "index.html", f"Design study: {spec.name}", intro, tables, figures, reports, optimiser)


def _sensitivity_text(spec: StudySpec, sensitivity) -> str:
    from study.samplers import SAMPLERS
    from study.sensitivity import ESTIMATOR

    if sensitivity is None:
        filling = " or ".join(name for name, s in SAMPLERS.items() if s.space_filling)
        return (
            f"Sensitivity: not estimated ({spec.sampling.method} sampling"
            f"{'' if spec.ranges else ', no range variable'}; it needs {filling} sampling of ranges)."
        )

    def one(s) -> str:
        shown = ", ".join(f"{i.input} {i.first_order:.2g} +- {i.half_width:.2g}" for i in s.standing_out())
        return f"{s.metric}: {shown or 'no input stands out from zero'} ({s.adequacy})"

    return f"Sensitivity ({ESTIMATOR}): " + "; ".join(one(s) for s in sensitivity) + "."


def _sensitivity_figures(sensitivity, out: Path) -> list[tuple[str, Path, str]]:
    from reporting.study_plots import plot_sensitivity

    return [
        (
            f"Which inputs matter: {s.metric}",
            plot_sensitivity(s, out / f"sensitivity_{s.metric}.png"),
            f"first-order indices of {s.metric} with 95 % intervals; {s.adequacy}",
        )
        for s in sensitivity
    ]


def _describe(v) -> str:
    from study.spec import Range

    return f"{v.min:g}..{v.max:g}" if isinstance(v, Range) else f"{len(v.values)} values"


def _constraint_text(c) -> str:
    parts = [
        f">= {c.min:g}" if c.min is not None else "",
        f"<= {c.max:g}" if c.max is not None else "",
        f"= {c.equals}" if c.equals is not None else "",
    ]
    return f"{c.metric} " + " and ".join(p for p in parts if p)
