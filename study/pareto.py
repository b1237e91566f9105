"""Feasibility against the study's constraints, and the Pareto front of its objectives."""

from __future__ import annotations

import numpy as np

from study.spec import Constraint, Objective


def feasibility(row: dict, constraints: tuple[Constraint, ...]) -> tuple[bool, str]:
    """(feasible, why not): a point that was not computed keeps its own reason."""
    if row["status"] != "ok":
        return False, row["reason"]
    broken = [why for c in constraints if (why := c.violation(row.get(c.metric))) is not None]
    return not broken, "; ".join(broken)


def objective_matrix(rows: list[dict], objectives: tuple[Objective, ...]) -> np.ndarray:
    """(n_rows, n_objectives), every objective turned into one to minimise."""
    values = np.array([[float(r[o.metric]) for o in objectives] for r in rows], dtype=float).reshape(
        len(rows), len(objectives)
    )
    signs = np.array([1.0 if o.sense == "min" else -1.0 for o in objectives])
    return values * signs


def pareto_mask(costs: np.ndarray) -> np.ndarray:
    """True for the rows no other row dominates (<= in every column, < in one); all minimised.

    Rows sorted lexicographically can only be dominated by rows before them, so each row is
    checked against the front found so far (vectorised), not against every row.
    """
    costs = np.asarray(costs, dtype=float)
    n = costs.shape[0]
    mask = np.zeros(n, dtype=bool)
    if n == 0:
        return mask
    order = np.lexsort(costs.T[::-1])
    front: list[int] = []
    for i in order:
        if front:
            f = costs[front]
            if np.any(np.all(f <= costs[i], axis=1) & np.any(f < costs[i], axis=1)):
                continue
        front.append(i)
    mask[front] = True
    return mask


def pick_spread(costs: np.ndarray, count: int) -> list[int]:
    """`count` rows of a front spread along its first objective (both ends first)."""
    if count <= 0 or costs.shape[0] == 0:
        return []
    order = np.lexsort(costs.T[::-1])
    picks = np.unique(np.round(np.linspace(0, len(order) - 1, min(count, len(order)))).astype(int))
    return [int(order[p]) for p in picks]
