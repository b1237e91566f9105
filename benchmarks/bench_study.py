"""Design studies on Dask: two workers against one on FEA-bound points, the scheduling overhead
per task against the task, the cost of one study point (FEA and chain), and from them the sizing
of 10,000 designs on 100 workers.

The study is the example's settings (curved P2, finest level 12 mm, 40 links, 2 samples per
degree), both materials (one mesh per level shared by them) and one cam per geometry so the FEA
dominates; every geometry distinct and the FEA cache off, so each run solves every FEA. 32
geometries are 16 rounds on two workers: the last round, where one worker may wait for the other,
is then a few per cent of the run as in a real study (10,000 designs on 100 workers: 100 rounds),
where 8 geometries (4 rounds) made it about a tenth and the ratio swung with the task order. Both cluster sizes run the same points, each on a
fresh LocalCluster, timed from the first submit to the last record stored (cluster start-up is
reported apart).
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path

GEOMETRIES_QUICK, GEOMETRIES = 4, 32
TINY_TASKS = 200


def _spec(geometries: int, cams: str = '["modified-sine"]'):
    import tomllib

    from study.spec import parse_study

    return parse_study(
        tomllib.loads(f"""
[variables]
web_thickness_m = {{min = 0.004, max = 0.010}}
cam = {cams}
material = ["al6061-t6", "ti-grade2"]
[fixed]
links = 40
rpm = 60.0
preload_N = 5000.0
[settings]
mesh_size_m = 0.012
order = 2
samples_per_degree = 2
fea_cache = false
[sampling]
method = "grid"
levels = {geometries}
""")
    )


def _run_study(spec, workers: int) -> dict:
    from distributed import Client, LocalCluster

    from study.execution import run_points
    from study.progress import ProgressBar
    from study.sampling import design_points
    from study.store import ResultStore
    from study.tasks import base_config

    points = design_points(spec, base_config(spec.settings))
    start = time.perf_counter()
    with (
        LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        Client(cluster) as client,
        tempfile.TemporaryDirectory() as folder,
    ):
        up = time.perf_counter() - start
        client.run(lambda: __import__("study.tasks") and None)  # imports paid before the clock starts
        store = ResultStore(Path(folder))
        store.open()
        t0 = time.perf_counter()
        run_points(client, points, spec.settings, store, 1, ProgressBar(len(points), 0, workers, quiet=True))
        wall = time.perf_counter() - t0
        timings = store.timings()
        tiny = _tiny_task_s(client)
    fea = [t["seconds"] for t in timings if t["kind"] == "fea"]
    fea_cpu = [t["cpu_seconds"] for t in timings if t["kind"] == "fea"]
    chain = [t for t in timings if t["kind"] == "chain"]
    return {
        "startup_s": up,
        "wall_s": wall,
        "points": len(points),
        "fea_s": fea,
        "chain_s_per_point": sum(t["seconds"] for t in chain) / sum(t["points"] for t in chain),
        "tasks": len(timings),
        "task_s": sum(t["seconds"] for t in timings),
        "tiny_task_s": tiny,
        "fea_cpu_share": sum(fea_cpu) / sum(fea),
        "fea_cpu_s": sum(fea_cpu) / len(fea_cpu),
        "load": os.getloadavg(),
    }


FEA_TASK_IN_A_PROCESS = """
import json, sys
sys.path.insert(0, "benchmarks")
import study.tasks as tasks
from bench_study import _spec
from study.sampling import design_points

if not {remedy}:
    tasks.keep_large_arrays_on_heap = lambda: False
spec = _spec(2)
point = design_points(spec, tasks.base_config(spec.settings))[0]
cpu = [tasks.fea_task(point.inputs, ("al6061-t6", "ti-grade2"), spec.settings)["cpu_seconds"] for _ in range(2)]
print(json.dumps(cpu))
"""


def _fea_task_cpu_s(dask_malloc_variable: bool, remedy: bool) -> float:
    """CPU seconds of one study FEA task (the second of two in the process, so imports are paid) in
    a fresh process started with or without the MALLOC_TRIM_THRESHOLD_ that Dask's nanny gives its
    workers, with or without the task's remedy (`study/worker_malloc.py`)."""
    import json
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root), "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    env.pop("MALLOC_TRIM_THRESHOLD_", None)
    if dask_malloc_variable:
        env["MALLOC_TRIM_THRESHOLD_"] = "65536"
    out = subprocess.run(
        [sys.executable, "-c", FEA_TASK_IN_A_PROCESS.format(remedy=remedy)],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])[-1]


def _tiny_task_s(client) -> float:
    """Round trip of a task that does nothing, submitted as the study submits (one future each)."""
    from distributed import wait

    start = time.perf_counter()
    wait([client.submit(int, i, pure=False) for i in range(TINY_TASKS)])
    return (time.perf_counter() - start) / TINY_TASKS


def run(quick: bool) -> list[str]:
    geometries = GEOMETRIES_QUICK if quick else GEOMETRIES
    spec = _spec(geometries)
    # the three cases alternate; medians of three rounds (one task's CPU swings by about 10 %)
    cases = ((False, False), (True, False), (True, True))
    rounds = [[_fea_task_cpu_s(*case) for case in cases] for _ in range(1 if quick else 3)]
    malloc = {case: statistics.median(r[i] for r in rounds) for i, case in enumerate(cases)}
    one, two = _run_study(spec, 1), _run_study(spec, 2)
    mean_fea = sum(one["fea_s"]) / len(one["fea_s"])
    speedup = one["wall_s"] / two["wall_s"]
    # one worker runs its tasks back to back: whatever the wall time holds beyond the tasks' own
    # time is the scheduler's (submit, transfer, store), per task
    overhead = (one["wall_s"] - one["task_s"]) / one["tasks"]
    # one design of the example: one FEA task (both materials) + 10 chain runs (5 cams x 2 materials)
    chain = one["chain_s_per_point"]
    designs, workers = 10_000, 100
    fea_total_h = designs * mean_fea / 3600
    chain_total_h = designs * 10 * chain / 3600
    lines = [
        f"{geometries} geometries x 2 materials x 1 cam (P2, 12 mm, 40 links), FEA cache off",
        "| workers | wall (s) | points/min | cluster start (s) | FEA task CPU (s) | FEA task CPU / wall | "
        "load average after (1 min) |",
        "|---|---|---|---|---|---|---|",
        *(
            f"| {n} | {r['wall_s']:.1f} | {60 * r['points'] / r['wall_s']:.2f} | {r['startup_s']:.1f} | "
            f"{r['fea_cpu_s']:.2f} | {r['fea_cpu_share']:.2f} | {r['load'][0]:.1f} |"
            for n, r in ((1, one), (2, two))
        ),
        "(CPU / wall below 1: the tasks waited for a core, i.e. the machine was shared; the ratio below is "
        "only meaningful on an otherwise idle machine. Equal CPU per FEA task with 1 and 2 workers: running "
        "two at once adds no work)",
        f"throughput, 2 workers / 1 worker: {speedup:.2f}x (target >= 1.7x)",
        f"scheduling overhead per task (1 worker, wall - task time): {1e3 * overhead:.0f} ms = "
        f"{100 * overhead / mean_fea:.2f} % of an FEA task ({mean_fea:.2f} s, both materials) (target < 5 %)",
        f"empty task round trip: {1e3 * one['tiny_task_s']:.1f} ms",
        f"one FEA task's CPU (median of {len(rounds)}) in a plain process {malloc[False, False]:.2f} s; with Dask's worker "
        f"MALLOC_TRIM_THRESHOLD_=65536 {malloc[True, False]:.2f} s; with it and the task's remedy "
        f"(study/worker_malloc.py) {malloc[True, True]:.2f} s",
        f"one design: FEA {mean_fea:.2f} s per geometry (both materials), chain {1e3 * chain:.0f} ms per "
        f"material x cam x speed x preload scenario",
        f"sizing, {designs} geometries x 2 materials x 5 cams: worker time FEA {fea_total_h:.1f} h + chain "
        f"{chain_total_h:.2f} h; on {workers} workers {60 * (fea_total_h + chain_total_h) / workers:.0f} min if they "
        f"scale perfectly, {60 * (fea_total_h + chain_total_h) / (workers * speedup / 2):.0f} min at the "
        f"{speedup / 2:.0%} per-worker efficiency measured here",
    ]
    return lines


if __name__ == "__main__":
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    print("\n".join(run(quick="--quick" in sys.argv)))
