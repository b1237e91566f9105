"""The small measurement scripts the docs' commands run (docs/performance.md, docs/verification.md),
on tiny inputs: benchmarks/run_cpu.py, benchmarks/compare_summaries.py, bench_long_wheels.py's
comparison of two trees at one N and bench_machine.py's window, each tree in its own process,
bench_long_floor.py's cycles; and which benchmarks and charts `--only` selects."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import pipeline
from benchmarks import bench_long_floor, bench_long_wheels, bench_machine, compare_summaries, run_cpu

BURN = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.2:\n    pass"


def _burn_here_and_in_a_child() -> None:
    start = time.process_time()
    while time.process_time() - start < 0.2:
        pass
    subprocess.run([sys.executable, "-c", BURN], check=True)


def test_run_cpu_splits_the_run_from_its_children(monkeypatch, capsys):
    own, children = run_cpu.cpu_seconds(_burn_here_and_in_a_child)
    assert own >= 0.2  # this process from its start: the 0.2 s burnt here at least
    assert 0.2 <= children < own + 5.0  # the child's burn and its interpreter's start only
    calls = []

    def main(options, fea_process):  # as `python pipeline.py` calls it: the FEA's process started first
        fea_process.cancel()
        calls.append((options, fea_process.what))
        return 3

    monkeypatch.setattr(pipeline, "main", main)
    assert run_cpu.main(["--links", "12", "-q"]) == 3  # the run's exit status
    assert calls == [(["--links", "12", "-q"], "the FEA")]
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("the run's process: ") and out[0].endswith(" CPU s")
    assert out[1].startswith("its children (FEA beside, figure workers): ")


def _write(path: Path, tree: dict) -> Path:
    path.write_text(json.dumps(tree))
    return path


def test_compare_summaries_says_which_leaves_differ_and_by_how_much(tmp_path, capsys):
    old = {"timing_s": {"fea": 1.0}, "materials": {"al": {"k": 2.0, "cams": ["a", "b"]}}, "flag": True}
    same = {**old, "timing_s": {"fea": 9.0}}
    moved = {"timing_s": {}, "materials": {"al": {"k": 2.002, "cams": ["a", "c"]}}, "flag": True, "new": 1}
    a, b, c = (_write(tmp_path / f"{n}.json", t) for n, t in (("a", old), ("b", same), ("c", moved)))
    assert compare_summaries.main([str(a), str(b)]) == 0
    assert capsys.readouterr().out == "identical (ignoring timing_s)\n"
    assert compare_summaries.main([str(a), str(c)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "materials.al.cams.1: 'b' -> 'c'"
    assert out[1].startswith("materials.al.k: 2.0 -> 2.002 (relative difference 0.001")
    assert out[2] == "new: None -> 1"
    assert out[3] == "3 leaves differ (ignoring timing_s), largest relative difference 0.001"
    assert compare_summaries.main([str(a), str(b), "--ignore"]) == 1  # timing_s compared too
    assert "timing_s.fea: 1.0 -> 9.0 (relative difference 8)" in capsys.readouterr().out


def test_bench_long_wheels_compares_two_trees_alternating():
    ran = []

    def scenario(n, tree):
        ran.append((n, tree))
        seconds = 1.0 + len(ran)
        return {"wall_s": seconds, "cpu_s": seconds / 2}

    lines = bench_long_wheels.compare_trees(40, Path("/tmp/old-tree"), repeats=3, scenario=scenario)
    trees = [tree for _, tree in ran]
    assert trees == [bench_long_wheels.ROOT, Path("/tmp/old-tree")] * 3 and {n for n, _ in ran} == {40}
    assert lines[0].startswith("run 1, new (") and lines[0].endswith("wall 2.00 s, CPU 1.00 s")
    assert lines[-2] == "new: median of 3: wall 4.00 s, CPU 2.00 s, 40 links"  # runs 1, 3, 5: 2, 4, 6 s
    assert lines[-1] == "old: median of 3: wall 5.00 s, CPU 2.50 s, 40 links"


@pytest.mark.parametrize("module", ["bench_long_wheels", "bench_long_chain"])
def test_the_old_trees_scenario_runs_the_old_trees_own_script(tmp_path, module):
    """Another tree's scenario runs that tree's script, which imports that tree's code (this tree's
    script imports this tree's before it could put the other first on sys.path)."""
    import importlib

    bench = importlib.import_module(f"benchmarks.{module}")
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / f"{module}.py").write_text('import json, sys; print(json.dumps({"argv": sys.argv}))\n')
    result = bench._in_subprocess(40, tree=tmp_path)
    assert result["argv"][0] == str(tmp_path / "benchmarks" / f"{module}.py")
    assert result["argv"][1] == "40" and result["argv"][-1] == str(tmp_path)


@pytest.mark.parametrize("script", ["compare_summaries.py", "bench_long_wheels.py"])
def test_the_scripts_options_parse_from_the_command_line(script):
    """As the docs' commands run them (run_cpu.py's options are pipeline.py's: tested above)."""
    path = Path(bench_long_wheels.ROOT) / "benchmarks" / script
    out = subprocess.run([sys.executable, str(path), "--help"], capture_output=True, text=True, check=True)
    assert "usage:" in out.stdout and ("--old-tree" in out.stdout) == (script == "bench_long_wheels.py")


def _window_model():
    from dynamics.cams import CamProgram
    from dynamics.models.clearance import DEFAULT_PIN_CLEARANCE_M
    from dynamics.models.clearance_machine import ClearanceMachine

    cam = CamProgram.indexing("modified-sine", pitch_m=bench_machine.PITCH_M, rpm=bench_machine.RPM)
    chain = bench_machine._chain("al6061-t6")
    return ClearanceMachine.of(chain, bench_machine.layout(), None, DEFAULT_PIN_CLEARANCE_M), cam


def test_bench_machine_window_in_its_own_process_is_the_window_run_here():
    """machine_window_worker.py, started in this tree, runs the same window as _window_run here: the
    same station metrics (same code, same round-off), a CPU time per steps-per-sample."""
    model, cam = _window_model()
    t = bench_machine._window_times()
    _, here = bench_machine._window_run(model, cam, t, 9)
    measured = bench_machine._window_in_process(bench_machine.ROOT, [9, 10])
    assert set(measured["seconds"]) == {9, 10} and all(s > 0 for s in measured["seconds"].values())
    np.testing.assert_allclose(measured["metrics"][9], here, rtol=1e-12, atol=0)
    assert not np.allclose(measured["metrics"][10], here, rtol=1e-9)  # a different step: a different window


def test_bench_machine_says_which_tree_failed(tmp_path):
    """A tree without the benchmark (not a checkout): the error names the tree and the child's last line."""
    with pytest.raises(RuntimeError, match=r"the window in .* failed \(exit 1\): .*No module named 'benchmarks'"):
        bench_machine._window_in_process(tmp_path, [9])


@pytest.mark.slow  # a fresh checkout: its compiled step compiles from scratch (about 30 s)
def test_bench_machine_old_tree_runs_in_its_own_process(tmp_path):
    """BENCH_MACHINE_OLD_TREE's path on a checkout of this tree's HEAD: both columns, and the same
    errors in both (the same code), from processes alternating between the two trees."""
    old = tmp_path / "old"
    root = bench_machine.ROOT
    subprocess.run(["git", "-C", str(root), "worktree", "add", "--detach", str(old), "HEAD"], check=True)
    try:
        lines = bench_machine._window_table(quick=True, old_tree=str(old), subs=[9])
    finally:
        subprocess.run(["git", "-C", str(root), "worktree", "remove", "--force", str(old)], check=True)
    header = next(line for line in lines if line.startswith("| steps/sample"))
    assert "this tree: CPU time" in header and "old tree: CPU time" in header
    row = next(line for line in lines if line.startswith("| 9 |")).strip("| ").split(" | ")
    assert len(row) == 1 + 3 + 3 + 1  # steps, this tree's three cells, the old tree's three, worst metric
    assert row[3] == row[6]  # the error
    assert any(line.startswith("Target, old tree") for line in lines)


def test_bench_ring_on_topology_stage_runs_both_orders(monkeypatch):
    """_stage runs every scenario ring first and topology first, the cache cleared before every run,
    and reports each order's ratio and both together's: a kernel that gains 15 % when run second
    biases one order's ratio, not the pair's."""
    from types import SimpleNamespace

    from benchmarks import bench_ring_on_topology as bench

    clock, calls, clears = [0.0], [], []
    cost = {"ring": 1.0, "topology": 1.2}

    def simulate_chain(model, cam, t, kernel):
        second = len(calls) % 2 == 1
        calls.append(kernel)
        clock[0] += cost[kernel] * (0.85 if second else 1.0)
        impacts = SimpleNamespace(closing_speed_max_m_s=1.0, closing_speed_median_m_s=0.5, energy_per_cycle_J=2.0)
        response = SimpleNamespace(x_m=np.ones((3, 2)), z_m=np.zeros(3))
        return response, SimpleNamespace(impacts=impacts)

    monkeypatch.setattr(bench, "simulate_chain", simulate_chain)
    monkeypatch.setattr(bench, "time", SimpleNamespace(perf_counter=lambda: clock[0]))
    monkeypatch.setattr(bench.cache, "clear", lambda: clears.append(len(calls)))
    line = bench._stage(quick=True)[-1]
    scenarios = len(bench.MATERIALS) * 2
    assert calls == ["ring", "topology", "topology", "ring"] * scenarios
    assert clears == list(range(len(calls)))  # before every run
    # ring first: 1.0 and 1.2 x 0.85; topology first: 1.2 and 0.85; together 2.22 / 1.85
    assert "ring first: ring kernel 4.00 s, topology kernel 4.08 s, ratio 1.02x" in line
    assert "topology first: ring kernel 3.40 s, topology kernel 4.80 s, ratio 1.41x" in line
    assert "both orders together 1.20x" in line


def test_only_selects_whole_benchmark_names(capsys):
    """`--only machine` is bench_machine.py, not bench_machine_long.py too; several by a comma list
    or a repeated --only; an unknown name is a one-line error listing the names, exit 2, nothing run."""
    from benchmarks import run

    def selected(*only: str) -> list[str]:
        return [path.stem for path in run.modules("bench_", list(only))]

    assert selected("machine") == selected("bench_machine") == ["bench_machine"]
    assert (
        selected("machine,machine_long")
        == selected("machine_long", "machine")
        == ["bench_machine", "bench_machine_long"]
    )
    assert run.main(["--only", "machine", "--only", "machin"]) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1
    assert out.err.startswith("benchmarks/run.py: error: --only machin: ") and "machine, machine_long" in out.err


def test_charts_only_selects_whole_chart_names(capsys, tmp_path):
    from benchmarks import charts

    assert charts.main(["--only", "dynamics", "--out", str(tmp_path)]) == 2  # there are four dynamics_* charts
    err = capsys.readouterr().err
    assert err.startswith("benchmarks/charts.py: error: --only dynamics: ") and "dynamics_workprecision" in err
    assert list(tmp_path.iterdir()) == []


def test_bench_long_floor_times_each_step_and_what_the_budget_leaves(capsys):
    bench_long_floor.main(["--links", "60", "--repeats", "1"])
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("60 links: the coarse search from rest to 1e-3") and out[0].endswith("(found: True)")
    cpu = [float(line.rsplit(": ", 1)[1].split()[0]) for line in out[1:4]]
    names = [line.split(":")[0].split(" (")[0] for line in out[1:4]]
    assert names == ["a coarse cycle", "a cycle at the window's step", "the window"]
    assert all(c > 0 for c in cpu)
    floor = float(out[4].split("): ")[1].split()[0])
    assert floor == pytest.approx(cpu[1] + cpu[2], rel=0.01)  # the window and one accepting cycle (3 digits)
