"""The FEA in a process beside the dynamics and the figures (stages.beside, the default of
`pipeline.py`) against the same run in one process (--serial): the same summary.json, byte for
byte apart from the wall times; and a failure in that process is one line, exit 2, --out untouched.

The failing runs replace `stages.fea._fea_steps` by generators of this module: the child is a fresh
interpreter that unpickles the steps function by name, so it imports them from here.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import pipeline
import stages.fea
from fem.errors import FemError

# Coarse on purpose: two FEA levels ending at 10 mm, stress levels, a short chain, one material.
FAST = ["--mesh-size", "10", "--drive", "link", "--links", "12", "--samples-per-degree", "2", "-q"]
FAST += ["--materials", "al6061-t6", "--cams", "modified-sine,cycloidal"]
REAL_STEPS = stages.fea._fea_steps
ROOT = Path(__file__).resolve().parents[1]


def _summary_without_timing(out: Path) -> str:
    summary = json.loads((out / "summary.json").read_text())
    del summary["timing_s"]
    return json.dumps(summary, indent=1)


def _run(*args: str) -> None:
    """pipeline.py in a fresh process on one thread: MKL's and OpenBLAS's threaded sums move the last
    bits with the machine's load (the steady state's residual by 1e-9 of itself, measured), which
    a byte-for-byte comparison would see."""
    one_thread = {name: "1" for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
    env = {**os.environ, "PYTHONPATH": str(ROOT), **one_thread}
    done = subprocess.run([sys.executable, "pipeline.py", *args], cwd=ROOT, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_the_fea_beside_gives_the_serial_runs_summary_byte_for_byte(tmp_path):
    beside, serial = tmp_path / "beside", tmp_path / "serial"
    _run(*FAST, "--out", str(beside), "--cache-dir", str(tmp_path / "c1"))
    _run(*FAST, "--serial", "--out", str(serial), "--cache-dir", str(tmp_path / "c2"))
    assert _summary_without_timing(beside) == _summary_without_timing(serial)
    assert sorted(p.name for p in beside.iterdir()) == sorted(p.name for p in serial.iterdir())
    # the deformed image drawn by the run's image process (stages.fea._start_drawing) as in one process
    image = "al6061-t6_deformed.png"
    assert (beside / image).read_bytes() == (serial / image).read_bytes()
    timing = json.loads((beside / "summary.json").read_text())["timing_s"]
    assert set(timing) == {"fea", "dynamics", "outputs", "total"}


def failing_after_the_stiffness(*args, **kwargs):
    steps = REAL_STEPS(*args, **kwargs)
    yield next(steps)
    raise FemError("stress study: a failure made up by the test")


def killed_after_the_stiffness(*args, **kwargs):
    steps = REAL_STEPS(*args, **kwargs)
    yield next(steps)
    os.kill(os.getpid(), signal.SIGKILL)


@pytest.mark.parametrize(
    "steps, message",
    [
        (failing_after_the_stiffness, "pipeline.py: error: stress study: a failure made up by the test"),
        (killed_after_the_stiffness, "pipeline.py: error: the FEA: its process ended early (signal 9"),
    ],
)
def test_a_failure_beside_is_one_line_exit_2_and_nothing_written(steps, message, tmp_path, monkeypatch, capsys):
    out, cache = tmp_path / "out", tmp_path / "cache"
    out.mkdir()
    (out / "summary.json").write_text("an earlier run's")
    monkeypatch.setattr(stages.fea, "_fea_steps", steps)
    assert pipeline.main([*FAST, "--out", str(out), "--cache-dir", str(cache)]) == 2
    stderr = capsys.readouterr().err
    lines = [line for line in stderr.splitlines() if not line.startswith("pipeline.py: warning:")]
    assert len(lines) == 1 and lines[0].startswith(message) and "Traceback" not in stderr, lines
    assert [p.name for p in out.iterdir()] == ["summary.json"]  # no staging folder left behind
    assert (out / "summary.json").read_text() == "an earlier run's"
    assert not list(cache.rglob("result.json"))  # no FEA record stored without its stress


def test_a_failure_drawing_the_images_is_one_line_exit_2_and_nothing_written(tmp_path, monkeypatch, capsys):
    """The deformed images are drawn by a process forked from the run (it sees this patch)."""
    import fem.render

    def failing(drawings, **kwargs):
        raise FemError("images: a failure made up by the test")

    out, cache = tmp_path / "out", tmp_path / "cache"
    monkeypatch.setattr(fem.render, "draw_pictures", failing)
    assert pipeline.main([*FAST, "--out", str(out), "--cache-dir", str(cache)]) == 2
    stderr = capsys.readouterr().err
    lines = [line for line in stderr.splitlines() if not line.startswith("pipeline.py: warning:")]
    assert lines == ["pipeline.py: error: images: a failure made up by the test"] and "Traceback" not in stderr
    assert not out.exists() or not list(out.iterdir())
    assert not list(cache.rglob("result.json"))


def test_the_fea_process_starts_before_the_outputs_modules_are_imported(tmp_path):
    # the outputs' modules (matplotlib: about 1.3 s) are imported while the FEA's process meshes,
    # not before it starts (pipeline._import_chain_and_outputs)
    probe = (
        "import sys, pipeline, stages.fea\n"
        "def started(*args, **kwargs):\n"
        "    print('reporting.outputs' in sys.modules, 'matplotlib' in sys.modules)\n"
        "    raise SystemExit(0)\n"
        "stages.fea.start_fea = started\n"
        f"pipeline.main(['--out', {str(tmp_path / 'out')!r}, '--cache-dir', {str(tmp_path / 'cache')!r}])\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "False"]


def test_a_dead_waiting_fea_process_is_one_line_exit_2_and_nothing_written(tmp_path, capsys):
    """`python pipeline.py` starts the FEA's process before it reads its command line
    (stages.fea.waiting_fea_process); that process dying before it is handed the FEA is one line."""
    from stages.beside import Beside

    waiting = Beside.waiting("the FEA", ())
    os.kill(waiting.pid, signal.SIGKILL)
    out, cache = tmp_path / "out", tmp_path / "cache"
    assert pipeline.main([*FAST, "--out", str(out), "--cache-dir", str(cache)], fea_process=waiting) == 2
    stderr = capsys.readouterr().err
    lines = [line for line in stderr.splitlines() if not line.startswith("pipeline.py: warning:")]
    assert len(lines) == 1 and lines[0].startswith("pipeline.py: error: the FEA: its process ended early (signal 9")
    assert "Traceback" not in stderr
    assert not out.exists() or not list(out.iterdir())
    assert not list(cache.rglob("result.json"))


def test_a_waiting_fea_process_is_ended_where_no_fea_runs_beside(tmp_path):
    """Without an FEA beside (--serial here; every material cached likewise) start_fea ends the
    waiting process at once, not with the run."""
    from stages.beside import Beside
    from stages.progress import Progress

    cfg = pipeline.parse_cli([*FAST, "--serial", "--out", str(tmp_path / "out"), "--cache-dir", str(tmp_path / "c")])
    waiting = Beside.waiting("the FEA", ())
    fea = stages.fea.start_fea(cfg, Progress(True), beside=cfg.stress_beside, process=waiting, stress_later=True)
    assert not waiting._process.is_alive() and not fea.beside


def test_a_bad_option_ends_the_waiting_fea_process_with_the_runs_one_line_error():
    """`python pipeline.py` starts the FEA's process before it reads its options; a run that ends on
    a bad option ends it too (pipeline.main), with the option's one-line error."""
    probe = (
        "import multiprocessing, pipeline\n"
        "from stages.fea import waiting_fea_process\n"
        "status = pipeline.main(['--links', '-3'], fea_process=waiting_fea_process())\n"
        "print(status, [p.name for p in multiprocessing.active_children()])\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, env=env, capture_output=True, text=True)
    assert done.stdout.splitlines() == ["2 []"], done.stderr
    assert done.stderr.startswith("pipeline.py: error: --links") and len(done.stderr.splitlines()) == 1
