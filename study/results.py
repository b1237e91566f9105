"""The study's table: every point's record, its feasibility and whether it is on the Pareto front;
written as Parquet and CSV with the feasible set and the front beside them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from study.pareto import feasibility, objective_matrix, pareto_mask, pick_spread
from study.records import METRICS
from study.sampling import DesignPoint
from study.spec import StudySpec
from study.store import ResultStore, write_csv, write_table

IDENTITY = ("point", "point_id", "geometry")
OUTCOME = ("status", "reason", "feasible", "infeasible_reason", "pareto")


@dataclass(frozen=True)
class StudyResults:
    columns: list[str]
    rows: list[dict]  # point order

    @property
    def feasible(self) -> list[dict]:
        return [r for r in self.rows if r["feasible"]]

    @property
    def front(self) -> list[dict]:
        return [r for r in self.rows if r["pareto"]]


def assemble(spec: StudySpec, points: list[DesignPoint], store: ResultStore) -> StudyResults:
    """The table of the points that are stored (in point order), with feasibility and the front."""
    done = store.done_ids()
    rows = [{**store.read_point(p.point_id), "point": p.index} for p in points if p.point_id in done]
    for row in rows:
        row["feasible"], row["infeasible_reason"] = feasibility(row, spec.constraints)
        row["pareto"] = False
    feasible = [r for r in rows if r["feasible"]]
    if spec.objectives and feasible:
        for row, on_front in zip(feasible, pareto_mask(objective_matrix(feasible, spec.objectives))):
            row["pareto"] = bool(on_front)
    inputs = list(points[0].inputs) if points else []
    columns = [*IDENTITY, *inputs, *OUTCOME, "fea_warnings", *METRICS]
    return StudyResults(columns, rows)


def best_designs(spec: StudySpec, results: StudyResults) -> list[dict]:
    """The designs that get a full pipeline report: spread along the Pareto front (or the first
    feasible ones when the study has no objectives)."""
    front = results.front if spec.objectives else results.feasible
    if not spec.objectives:
        return front[: spec.report_best]
    costs = objective_matrix(front, spec.objectives)
    return [front[i] for i in pick_spread(costs, spec.report_best)]


def write_tables(results: StudyResults, out: Path) -> None:
    write_table(results.rows, results.columns, out / "results.parquet", out / "results.csv")
    write_csv(results.feasible, results.columns, out / "feasible.csv")
    write_csv(results.front, results.columns, out / "pareto.csv")


def varied_numeric(spec: StudySpec) -> list[str]:
    return [n for n in spec.ranges] + [
        n for n, c in spec.choices.items() if all(isinstance(v, (int, float)) for v in c.values)
    ]


def summary_counts(results: StudyResults) -> dict:
    reasons: dict[str, int] = {}
    for r in results.rows:
        if r["status"] != "ok":
            key = r["reason"].split(":")[0]
            reasons[key] = reasons.get(key, 0) + 1
    return {
        "points": len(results.rows),
        "computed": sum(r["status"] == "ok" for r in results.rows),
        "feasible": len(results.feasible),
        "pareto": len(results.front),
        "not_computed": reasons,
    }
