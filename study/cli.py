"""`python -m study STUDY.toml`: many designs through the same stages as pipeline.py, on Dask.

    python -m study STUDY.toml [--out DIR] [--scheduler ADDRESS] [--workers N] [--resume] [--optimise] [-q]

Configuration in (the study file), the points sampled, the stages run as Dask tasks, the results
written (table, feasible set, Pareto front, plots, page, full reports of the best designs).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

from study.spec import StudyError, load_study

PROG = "python -m study"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description=(
            "Sweep or optimise the built-in link or your own (STEP files: geometry = ... in the study file) and "
            "the drive: every design point meshed, solved (FEA) and run through the chain model on a Dask cluster; "
            "writes a tidy table (Parquet, CSV), the feasible set, the Pareto front, which inputs matter "
            "(sensitivity), plots and an HTML page. SI units throughout."
        ),
    )
    p.add_argument("study", type=Path, help="study file (TOML; see docs/user-guide.md, The study file)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: results-<study file name>)")
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on an existing Dask cluster, e.g. tcp://host:8786 (default: a local cluster)",
    )
    p.add_argument(
        "--workers", type=int, default=2, help="worker processes of the local cluster (default: %(default)s)"
    )
    p.add_argument("--resume", action="store_true", help="continue a study in --out: run only its missing points")
    p.add_argument(
        "--optimise",
        action="store_true",
        help="also run the constrained optimiser of [optimise] over the range variables",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    return p


def _checked_out(args) -> Path:
    from stages.output_folder import out_folder_problem
    from study.store import ResultStore

    out = args.out if args.out is not None else Path(f"results-{args.study.stem}")
    if args.workers < 1:
        raise StudyError(f"--workers: expected a number of worker processes >= 1, got {args.workers}")
    problem = out_folder_problem(out, create=False)
    if problem is not None:
        raise StudyError(problem)
    if ResultStore(out).exists() and not args.resume:
        raise StudyError(
            f"--out: {str(out)!r} already holds a study; pass --resume to continue it or choose another --out"
        )
    return out


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        spec = load_study(args.study)
        out = _checked_out(args)
        if args.optimise and spec.optimise is None:
            raise StudyError(f"{args.study}: --optimise needs an [optimise] table (objective, popsize, maxiter)")
        if args.optimise and not spec.ranges:
            raise StudyError(f"{args.study}: --optimise varies the range variables, and [variables] has none")
        client, cluster = _connect(args)
    except StudyError as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        return 2
    try:
        return run_study(args, spec, out, client)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; every finished point is in {out}/points; rerun with --resume", file=sys.stderr)
        return 130
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _connect(args):
    from study.execution import connect

    try:
        return connect(args.scheduler, args.workers)
    except (OSError, TimeoutError) as e:
        raise StudyError(
            f"--scheduler: cannot reach {args.scheduler!r} ({e}); expected the address of a "
            "running `dask scheduler`, e.g. tcp://host:8786"
        ) from None


def run_study(args, spec, out: Path, client) -> int:
    from fem.cache import write_text_atomic
    from study.execution import run_points, worker_threads
    from study.outputs import write_outputs
    from study.progress import ProgressBar
    from study.sampling import design_points
    from study.store import ResultStore
    from study.tasks import base_config, part_payloads

    store = ResultStore(out)
    store.open()
    if not (out / "study.toml").exists() or not (out / "study.toml").samefile(args.study):
        shutil.copyfile(args.study, out / "study.toml")
    points = design_points(spec, base_config(spec.settings))
    done = store.done_ids()
    todo = [p for p in points if p.point_id not in done]
    run = store.start_run(len(todo))
    bar = ProgressBar(len(points), 0, worker_threads(client), args.quiet)
    bar.message(
        f"study {spec.name!r}: {len(points)} points ({len(points) - len(todo)} already in {out}), "
        f"{worker_threads(client)} workers" + (f" at {args.scheduler}" if args.scheduler else " (local)")
    )
    bar.points_done = len(points) - len(todo)
    outcome = run_points(client, todo, spec.settings, store, run, bar, part_payloads(spec))
    history = None
    if args.optimise:
        from study.optimise import optimise

        history = optimise(client, spec, store, run, bar, out)
    write_outputs(spec, points, store, out, client, bar, history)
    write_text_atomic(
        out / "last_run.json",
        json.dumps({"run": run, "points": len(points), "ran": outcome.ran, "failed": outcome.failed}, indent=1),
    )
    if outcome.failed:
        for line in outcome.failed:
            print(f"{PROG}: task failed: {line}", file=sys.stderr)
        print(
            f"{PROG}: {len(outcome.failed)} tasks failed; their points are missing: rerun with --resume",
            file=sys.stderr,
        )
        return 1
    return 0
