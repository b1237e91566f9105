"""The whole-job benchmark's split of a PSS peak between the run's processes
(benchmarks/bench_whole_job.py, loaded from its file): a spawned interpreter is the FEA's process,
a fork of the run a figure worker."""

from __future__ import annotations

import importlib.util
import multiprocessing
import sys
from pathlib import Path

import psutil

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_whole_job.py"


def load_bench():
    spec = importlib.util.spec_from_file_location("bench_whole_job", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def _wait(event) -> None:
    event.wait(30)


def test_the_children_of_a_run_are_told_apart_by_how_they_started():
    bench = load_bench()
    me = psutil.Process()
    children = {}
    for method in ("spawn", "fork"):
        context = multiprocessing.get_context(method)
        event = context.Event()
        child = context.Process(target=_wait, args=(event,))
        child.start()
        children[method] = (child, event)
    try:
        roles = {method: bench._role(psutil.Process(c.pid), me.cmdline()) for method, (c, _) in children.items()}
    finally:
        for child, event in children.values():
            event.set()
            child.join(30)
    assert roles == {"spawn": "FEA", "fork": "forks (figures, images)"}


def test_the_fea_process_waiting_for_its_steps_is_the_fea():
    from stages.beside import Beside

    waiting = Beside.waiting("the FEA", ())
    try:
        assert load_bench()._role(psutil.Process(waiting.pid), psutil.Process().cmdline()) == "FEA"
    finally:
        waiting.cancel()


def test_a_runs_line_says_when_and_of_what_its_peak_was():
    bench = load_bench()
    run = bench.Run(peak_pss_by_role={"run": 120e6, "FEA": 600e6, "forks (figures, images)": 230e6}, peak_at_s=7.25)
    run.peak_after = "stress level 2: local element 1.1 mm"
    assert bench.peak_line(run) == (
        "PSS peak at 7.2 s, after 'stress level 2: local element 1.1 mm': run 120, FEA 600, forks (figures, images) 230, "
        "other 0 MB"
    )


def test_the_times_come_from_the_unsampled_runs_and_the_memory_from_the_sampled_ones():
    bench = load_bench()
    timed = bench.Run(wall_s={"stiffness": 5.0}, total_s=10.0, cpu_s=18.0)
    sampled = bench.Run(wall_s={"stiffness": 7.0}, total_s=14.0, memory=dict.fromkeys(bench.MEMORY, 900e6), cpu_s=21.0)
    lines = bench.report({"new": [timed]}, {"new": [sampled]})
    assert "| stiffness | 5.00 |" in lines
    assert "| whole job | **10.00** (10.0) |" in lines
    assert "| whole job, CPU s | **18.00** (18.0) |" in lines
    assert "| PSS | 900 |" in lines
    assert "| (the sampled runs' whole job, s) | 14.00 |" in lines


def test_the_runs_read_and_write_their_bytecode_outside_the_trees(monkeypatch, tmp_path):
    bench = load_bench()
    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    env = bench.child_env(tmp_path / "tree", tmp_path / "bytecode")
    assert "PYTHONDONTWRITEBYTECODE" not in env
    assert env["PYTHONPYCACHEPREFIX"] == str(tmp_path / "bytecode")
    assert env["PYTHONPATH"] == str(tmp_path / "tree")
