"""--optimise: scipy's differential evolution over the study's range variables, its population
evaluated on the Dask cluster (the `workers` map of differential_evolution submits each generation
as FEA and chain tasks), constraints by penalty.

The penalised objective orders designs by Deb's rules: any design that meets the constraints beats
any that does not; among those that do not, the smaller total relative violation wins. List
variables stay at one value ([optimise] held, else the first listed). Every evaluation is a point
in `optimisation/points` (so --resume re-evaluates nothing); the best design per generation is the
convergence history (`optimisation_history.csv`, plotted on the page).
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np

from study.execution import run_points
from study.pareto import feasibility
from study.progress import ProgressBar
from study.sampling import held_values, make_point, part_identities
from study.spec import StudySpec
from study.store import ResultStore, write_csv
from study.tasks import base_config, part_payloads
from study.variables import VARIABLES

#: Added to the objective of a design that breaks a constraint (or could not be computed): larger
#: than any objective a link or chain metric takes in SI.
INFEASIBLE_OFFSET = 1e12
#: Relative violation charged for a design that was not computed at all (geometry, FEA, chain).
NOT_COMPUTED_VIOLATION = 1e3


def penalised(row: dict, spec: StudySpec) -> float:
    sign = 1.0 if spec.optimise.sense == "min" else -1.0
    feasible, _ = feasibility(row, spec.constraints)
    if feasible:
        return sign * float(row[spec.optimise.objective])
    if row["status"] != "ok":
        return INFEASIBLE_OFFSET * (1 + NOT_COMPUTED_VIOLATION)
    return INFEASIBLE_OFFSET * (1 + sum(c.amount(row.get(c.metric)) for c in spec.constraints))


def optimise(client, spec: StudySpec, store: ResultStore, run: int, bar: ProgressBar, out: Path) -> dict:
    from scipy.optimize import differential_evolution

    opt = spec.optimise
    names = list(spec.ranges)
    bounds = [(spec.ranges[n].min, spec.ranges[n].max) for n in names]
    integrality = [VARIABLES[n].kind is int for n in names]
    held = {
        **held_values(spec, base_config(spec.settings)),
        **{n: c.values[0] for n, c in spec.choices.items()},
        **opt.held,
    }
    settings = asdict(spec.settings)
    opt_store = ResultStore(out / "optimisation")
    opt_store.open()
    quiet = ProgressBar(0, 0, bar.workers, quiet=True)
    evaluated: list[dict] = []
    history: list[dict] = []

    def evaluate_population(_func, population) -> list[float]:
        points = [
            make_point(len(evaluated) + i, {**held, **_values(names, x)}, settings, part_identities(spec))
            for i, x in enumerate(population)
        ]
        done = opt_store.done_ids()
        todo = list({p.point_id: p for p in points if p.point_id not in done}.values())
        run_points(client, todo, spec.settings, opt_store, run, quiet, part_payloads(spec))
        rows = [{**opt_store.read_point(p.point_id), "point": p.index} for p in points]
        values = [penalised(r, spec) for r in rows]
        for r, v in zip(rows, values):
            evaluated.append({**r, "penalised_objective": v})
        return values

    def record_generation(intermediate_result) -> None:
        best = intermediate_result
        history.append(
            {
                "generation": len(history) + 1,
                "best_objective": float(best.fun),
                "best_feasible": bool(best.fun < INFEASIBLE_OFFSET),
                "evaluations": len(evaluated),
                **{f"best_{n}": v for n, v in _values(names, best.x).items()},
            }
        )
        bar.message(
            f"optimiser generation {len(history)}: best penalised {opt.objective} = {best.fun:.5g}"
            f"{'' if best.fun < INFEASIBLE_OFFSET else ' (no feasible design yet)'}, "
            f"{len(evaluated)} evaluations"
        )

    bar.message(
        f"optimiser: differential evolution over {', '.join(names)}, {opt.sense}imise {opt.objective}, "
        f"population {opt.popsize} x {len(names)}, at most {opt.maxiter} generations"
    )
    result = differential_evolution(
        _never_called,
        bounds,
        popsize=opt.popsize,
        maxiter=opt.maxiter,
        seed=opt.seed,
        tol=opt.tol,
        workers=evaluate_population,
        updating="deferred",
        polish=False,
        init="latinhypercube",
        integrality=integrality if any(integrality) else None,
        callback=record_generation,
    )
    best_row = min(evaluated, key=lambda r: r["penalised_objective"]) if evaluated else None
    _write(out, history, evaluated)
    found = best_row is not None and best_row["penalised_objective"] < INFEASIBLE_OFFSET
    notes = [
        f"Differential evolution (scipy, seed {opt.seed}) over {', '.join(names)}; "
        f"held: {', '.join(f'{k} = {v}' for k, v in held.items() if k in spec.choices)}. "
        f"{len(evaluated)} evaluations in {len(history)} generations ({result.message}).",
        (
            f"Best design: {', '.join(f'{n} = {best_row[n]:.5g}' for n in names)}, {opt.objective} = "
            f"{best_row[opt.objective]:.5g} (feasible)."
            if found
            else "No design met the constraints."
        ),
    ]
    return {"objective": opt.objective, "generations": history, "notes": notes, "best": best_row if found else None}


def _never_called(x):
    raise AssertionError("differential_evolution evaluates through its workers map only")


def _values(names: list[str], x) -> dict:
    return {
        n: (int(round(float(v))) if VARIABLES[n].kind is int else float(v)) for n, v in zip(names, np.atleast_1d(x))
    }


def _write(out: Path, history: list[dict], evaluated: list[dict]) -> None:
    if history:
        write_csv(history, list(history[0]), out / "optimisation_history.csv")
    if evaluated:
        columns = list(dict.fromkeys(k for r in evaluated for k in r))
        write_csv(evaluated, columns, out / "optimisation_points.csv")
