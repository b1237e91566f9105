"""The study's task graph on a Dask cluster, and the client loop that stores each point as it lands.

Work is split so that nothing is computed twice: one FEA task per geometry (it meshes each level
once for all the geometry's materials), then per (geometry, material) chain tasks of up to
`CHAIN_BATCH` points that take the FEA task's result as their input (Dask moves it between
workers; no shared disk). Only small records come back. A worker that dies mid-task has its task
rerun elsewhere by the scheduler; the client writes each point once, keyed by its id.
"""

from __future__ import annotations

import logging
import uuid
from dataclasses import dataclass, field

from study.progress import ProgressBar
from study.records import record
from study.sampling import DesignPoint
from study.spec import Settings
from study.store import ResultStore
from study.tasks import chain_task, fea_task

#: Points per chain task: large enough that scheduling is a small share of a task (the chain
#: takes tens of milliseconds), small enough to spread a big study over many workers.
CHAIN_BATCH = 32


@dataclass
class RunOutcome:
    ran: int = 0  # points written by this run
    failed: list[str] = field(default_factory=list)  # tasks that raised (their points stay missing)


def connect(scheduler: str | None, workers: int):
    """A client on the given scheduler, or on a LocalCluster of `workers` single-threaded processes."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        return Client(scheduler, timeout="15s"), None
    cluster = LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
    )
    return Client(cluster), cluster


def worker_threads(client) -> int:
    return sum(w["nthreads"] for w in client.scheduler_info()["workers"].values()) or 1


def plan(points: list[DesignPoint]) -> tuple[list[DesignPoint], dict]:
    """(points already known to be infeasible, {geometry: {material: [points]}})."""
    infeasible, groups = [], {}
    for p in points:
        if p.infeasible is not None:
            infeasible.append(p)
        else:
            groups.setdefault(p.geometry, {}).setdefault(p.inputs["material"], []).append(p)
    return infeasible, groups


def run_points(
    client,
    points: list[DesignPoint],
    settings: Settings,
    store: ResultStore,
    run: int,
    bar: ProgressBar,
    parts: dict | None = None,
) -> RunOutcome:
    """`parts`: geometry_file name -> tasks.part_payload, for a study of STEP links (the bytes go
    with the FEA task of their geometry)."""
    from distributed import as_completed

    outcome = RunOutcome()
    infeasible, groups = plan(points)
    bar.fea_tasks = len(groups)
    for p in infeasible:
        store.write_point(record(p.task_view(), "infeasible", p.infeasible, {}), run)
        outcome.ran += 1
    bar.points_skipped(len(infeasible))
    token = uuid.uuid4().hex[:8]  # a fresh key space per run: a dead client's keys never answer for ours
    futures = {}
    for g, by_material in groups.items():
        first = next(iter(by_material.values()))[0]
        part = None if first.inputs.get("geometry_file") is None else parts[first.inputs["geometry_file"]]
        fea = client.submit(fea_task, first.inputs, tuple(by_material), settings, part, key=f"fea-{g}-{token}")
        futures[fea] = ("fea", g, [])
        for material, members in by_material.items():
            for b in range(0, len(members), CHAIN_BATCH):
                batch = members[b : b + CHAIN_BATCH]
                chain = client.submit(
                    chain_task,
                    fea,
                    material,
                    [p.task_view() for p in batch],
                    settings,
                    key=f"chain-{g}-{material}-{b}-{token}",
                )
                futures[chain] = ("chain", g, batch)
    bar.fea_tasks, bar.chain_tasks = len(groups), len(futures) - len(groups)
    bar.show()
    for future in as_completed(list(futures)):
        kind, g, batch = futures.pop(future)
        if future.status != "finished":
            outcome.failed.append(f"{kind} task of geometry {g}: {future.exception()!r}")
            continue
        result = future.result()
        for row in result.get("rows", []):
            store.write_point(row, run)
        outcome.ran += len(batch)
        store.append_timing(
            {
                "run": run,
                "task": future.key,
                "kind": kind,
                "geometry": g,
                "points": len(batch),
                "seconds": result["seconds"],
                "cpu_seconds": result["cpu_seconds"],
                "worker": result["worker"],
            }
        )
        bar.task_done(kind, result["seconds"], len(batch))
    bar.show(final=True)
    return outcome
