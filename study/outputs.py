"""Everything a finished study writes beside its point files: the table (Parquet, CSV), the
feasible set and the Pareto front, the plots, the page, and pipeline.py's full report of the best
designs (made on a worker, written here)."""

from __future__ import annotations

from pathlib import Path

from study.results import StudyResults, assemble, best_designs, summary_counts, varied_numeric, write_tables
from study.sampling import DesignPoint
from study.spec import StudySpec
from study.store import ResultStore

#: Metrics drawn against the variables when the study names none in its objectives/constraints.
DEFAULT_PLOTTED = ("body_mass_kg", "stiffness_N_per_m", "residual_vibration_m", "yield_safety_factor")


def write_outputs(spec: StudySpec, points: list[DesignPoint], store: ResultStore, out: Path, client, bar,
                  history: dict | None) -> StudyResults:
    results = assemble(spec, points, store)
    write_tables(results, out)
    reports = _best_reports(spec, results, out, client, bar) if spec.report_best else []
    _write_page(spec, results, out, reports, history)
    bar.message(f"{len(results.rows)} points in {out}/results.parquet: {len(results.feasible)} feasible, "
                f"{len(results.front)} on the Pareto front; page {out}/index.html")
    return results


def plotted_metrics(spec: StudySpec) -> list[str]:
    from study.records import METRICS

    named = [o.metric for o in spec.objectives] + [c.metric for c in spec.constraints]
    chosen = [m for m in dict.fromkeys(named) if m in METRICS and m != "loss_of_contact"]
    return chosen or list(DEFAULT_PLOTTED)


def _best_reports(spec: StudySpec, results: StudyResults, out: Path, client, bar) -> list[tuple[str, str]]:
    from study.tasks import report_task

    best = best_designs(spec, results)
    cams = tuple(spec.choices["cam"].values) if "cam" in spec.choices else (spec.fixed["cam"],)
    futures = [client.submit(report_task, {k: r[k] for k in _inputs_of(results)}, cams, spec.settings,
                             pure=False) for r in best]
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
    from study.results import IDENTITY, OUTCOME
    from study.records import METRICS

    return [c for c in results.columns
            if c not in IDENTITY and c not in OUTCOME and c not in METRICS and c != "fea_warnings"]


def _write_page(spec: StudySpec, results: StudyResults, out: Path, reports, history) -> None:
    from reporting.study_page import design_table, reason_table, write_study_page
    from reporting.study_plots import plot_metrics_vs_variables, plot_parallel_coordinates, plot_pareto
    from reporting.tables import Table

    counts = summary_counts(results)
    variables = varied_numeric(spec)
    metrics = plotted_metrics(spec)
    objectives = [o.metric for o in spec.objectives]
    intro = [f"{counts['points']} design points ({', '.join(f'{n} {_describe(v)}' for n, v in spec.variables.items())}; "
             f"sampling: {spec.sampling.method}, seed {spec.sampling.seed}); {counts['computed']} computed, "
             f"{counts['feasible']} feasible, {counts['pareto']} on the Pareto front.",
             "Constraints: " + ("; ".join(_constraint_text(c) for c in spec.constraints) or "none") + ". Objectives: "
             + (", ".join(f"{o.sense}imise {o.metric}" for o in spec.objectives) or "none") + "."]
    tables = [reason_table(counts["not_computed"])] if counts["not_computed"] else []
    shown = ["point", "material", "cam", *variables, *dict.fromkeys(objectives + metrics)]
    tables.append(design_table("Pareto front", results.front, shown))
    figures = []
    if len(objectives) >= 2 and results.feasible:
        figures.append(("Pareto front", plot_pareto(results.rows, objectives, out / "pareto.png"),
                        f"{objectives[0]} against {objectives[1]}, every computed design"))
    if variables and any(r["status"] == "ok" for r in results.rows):
        figures.append(("Metrics against the design variables",
                        plot_metrics_vs_variables(results.rows, metrics, variables, out / "metrics_vs_variables.png"),
                        "filled: feasible, hollow: infeasible; colour: material"))
        figures.append(("Parallel coordinates", plot_parallel_coordinates(results.rows, variables + metrics,
                                                                          out / "parallel_coordinates.png"),
                        "each design a line; axes scaled to their ranges (ends labelled)"))
    optimiser = None
    if history is not None:
        from reporting.study_plots import plot_convergence

        gens = history["generations"]
        table = Table("Convergence", ("generation", "best objective", "evaluations"),
                      tuple((g["generation"], g["best_objective"], g["evaluations"]) for g in gens))
        png = plot_convergence(gens, history["objective"], out / "convergence.png") if gens else None
        optimiser = (history["notes"], table, png)
    write_study_page(out / "index.html", f"Design study: {spec.name}", intro, tables, figures, reports, optimiser)


def _describe(v) -> str:
    from study.spec import Range

    return f"{v.min:g}..{v.max:g}" if isinstance(v, Range) else f"{len(v.values)} values"


def _constraint_text(c) -> str:
    parts = [f">= {c.min:g}" if c.min is not None else "", f"<= {c.max:g}" if c.max is not None else "",
             f"= {c.equals}" if c.equals is not None else ""]
    return f"{c.metric} " + " and ".join(p for p in parts if p)
