"""The FEA's coarser stiffness levels in a process of their own (stages.fea.CoarserLevelsBeside,
issue #24): the same k, bit for bit, as the levels solved in one process; a failure or the death of
that process reaches the study as one error; it is stopped when the study fails, and it ends with
the process that started it.

The failing processes run generators of this module in place of `stages.fea._coarser_level_steps`:
the child is a fresh interpreter that unpickles its steps function by name, so it imports them
from here.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from functools import partial
from pathlib import Path

import psutil
import pytest
from threadpoolctl import threadpool_limits

import fem.study
import geometry
import pipeline
import stages.fea
from fem import FemError, get_material, stiffness_studies
from fem.settings import FeaSettings
from stages.beside import Beside, BesideError

pytestmark = pytest.mark.filterwarnings("ignore:mesh. a wall:fem.errors.FemWarning")  # coarse on purpose
ALUMINIUM, TITANIUM = get_material("al6061-t6"), get_material("ti-grade2")
# the default link, coarse: its 2.535 mm rails are refined at 9 mm, so the study adds a third level
# (fem.study.with_wall_check_level) and the process beside solves two
COARSE = FeaSettings(mesh_sizes_m=(0.012, 0.009), concurrent_levels=False)
COARSER = FeaSettings(mesh_sizes_m=(0.016, 0.012))  # where the levels themselves do not matter
ONE_THREAD = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
REAL_STEPS = stages.fea._fea_steps
FAST = ["--mesh-size", "10", "--drive", "link", "--links", "12", "--samples-per-degree", "2", "-q"]
FAST += ["--materials", "al6061-t6", "--cams", "modified-sine,cycloidal"]


def _one_thread(monkeypatch) -> None:
    """MKL's and OpenBLAS's threaded sums move the last bits with the machine's load: one thread
    here and in the processes started from here (which read the variables as they load them)."""
    for name in ONE_THREAD:
        monkeypatch.setenv(name, "1")


def _study_answer(estimates) -> dict:
    return {
        name: (e.levels, e.stiffness_N_per_m, e.stiffness_rel_error_estimate, e.finest.mesh_size_m)
        for name, e in estimates.items()
    }


def levels_in_one_process(part, settings, materials):
    """The study in a fresh process, every level there (one step: its answer)."""
    yield _study_answer(stiffness_studies(part, materials, settings))


def levels_in_two_processes(part, settings, materials):
    """The study in a fresh process, its coarser levels in another (one step: its answer, its progress)."""
    lines: list[str] = []
    coarser = stages.fea.CoarserLevelsBeside(part, settings, materials)
    estimates = stiffness_studies(part, materials, settings, progress=lines.append, coarser=coarser)
    yield _study_answer(estimates), lines, coarser.pid


def test_the_coarser_levels_beside_give_the_one_process_k_bit_for_bit(monkeypatch):
    # both studies in fresh processes on one thread: this one's libraries may be loaded already
    _one_thread(monkeypatch)
    part = geometry.as_part(None)
    part.geometry  # noqa: B018 (measured here and handed over with the part, as stages.fea does)
    materials = [ALUMINIUM, TITANIUM]
    with threadpool_limits(limits=1):
        apart = Beside(partial(levels_in_one_process, part, COARSE, materials), "one process")
        together = Beside(partial(levels_in_two_processes, part, COARSE, materials), "two processes")
        one, (two, lines, pid) = apart.next(), together.next()
        apart.close()
        together.close()
    assert _ended(pid)
    assert two == one  # sizes, DOFs and k of every level; the estimate; the finest level's size
    assert [len(levels) for levels, *_ in two.values()] == [3, 3]
    assert [line.split(",")[0] for line in lines] == [f"FEA level {n}/3" for n in (1, 1, 2, 2, 3, 3)]


class _Solved:
    """A `fem.study.CoarserLevels` that hands over given levels, recording whether it was cancelled."""

    def __init__(self, levels):
        self.levels, self.cancelled = levels, False

    def result(self):
        return self.levels

    def cancel(self):
        self.cancelled = True


def test_coarser_levels_of_other_sizes_are_refused():
    wrong = fem.study.CoarserLevel(0.02, 0.0, {}, ())
    with pytest.raises(FemError, match=r"coarser levels solved beside have sizes \[0\.02\]"):
        stiffness_studies(None, [ALUMINIUM], COARSER, coarser=_Solved([wrong]))


def failing_coarser(*args):
    raise FemError("coarser level: a failure made up by the test")
    yield


def killed_coarser(*args):
    os.kill(os.getpid(), signal.SIGKILL)
    yield


def sleeping_coarser(*args):
    stages.fea._end_with_parent()
    time.sleep(120)
    yield


@pytest.mark.parametrize(
    "steps, error, message",
    [
        (failing_coarser, FemError, "coarser level: a failure made up by the test"),
        (killed_coarser, BesideError, "the FEA's coarser levels: its process ended early (signal 9"),
    ],
)
def test_a_failure_in_the_coarser_levels_process_reaches_the_study(steps, error, message, monkeypatch):
    monkeypatch.setattr(stages.fea, "_coarser_level_steps", steps)
    coarser = stages.fea.CoarserLevelsBeside(None, COARSER, [ALUMINIUM])
    with pytest.raises(error) as raised:
        stiffness_studies(None, [ALUMINIUM], COARSER, coarser=coarser)
    assert str(raised.value).startswith(message) and "\n" not in str(raised.value)


def test_a_failure_of_the_finest_level_stops_the_coarser_levels_process(monkeypatch, tmp_path):
    monkeypatch.setattr(stages.fea, "_coarser_level_steps", sleeping_coarser)
    started = []
    real = stages.fea.CoarserLevelsBeside

    def recorded(*args):
        started.append(real(*args))
        return started[-1]

    def failing(*args, **kwargs):
        raise FemError("PARDISO: the finest level failed")

    monkeypatch.setattr(stages.fea, "CoarserLevelsBeside", recorded)
    monkeypatch.setattr(fem.study, "analyse_link_materials", failing)
    part = geometry.as_part(None)
    steps = REAL_STEPS(part, COARSER, [ALUMINIUM], None, None, {ALUMINIUM.name: None}, print, levels_beside=True)
    with pytest.raises(FemError, match="finest level failed"):
        next(steps)
    assert len(started) == 1 and _ended(started[0].pid)


def _start_coarser_and_wait(send) -> None:
    """A stand-in for the FEA's process: starts the coarser levels' process, says its pid, waits."""
    stages.fea._coarser_level_steps = sleeping_coarser
    coarser = stages.fea.CoarserLevelsBeside(None, COARSER, [ALUMINIUM])
    send.send(coarser.pid)
    time.sleep(120)


def _ended(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


def test_the_coarser_levels_process_ends_with_the_process_that_started_it():
    context = multiprocessing.get_context("spawn")
    receive, send = context.Pipe(duplex=False)
    fea = context.Process(target=_start_coarser_and_wait, args=(send,))
    fea.start()
    assert receive.poll(60), "the stand-in FEA process did not start its coarser levels' process"
    pid = receive.recv()  # killed before or after its prctl: its parent check or the kernel ends it
    os.kill(fea.pid, signal.SIGKILL)  # as Beside.cancel or an out-of-memory kill would, no time to clean up
    fea.join()
    deadline = time.monotonic() + 10
    while not _ended(pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _ended(pid)


def fea_steps_with_failing_coarser(*args, **kwargs):
    """The FEA's steps in its process, its coarser levels' process failing."""
    stages.fea._coarser_level_steps = failing_coarser
    yield from REAL_STEPS(*args, **kwargs)


def test_a_failure_in_the_coarser_levels_process_is_one_line_exit_2_and_nothing_written(tmp_path, monkeypatch, capsys):
    out, cache = tmp_path / "out", tmp_path / "cache"
    out.mkdir()
    (out / "summary.json").write_text("an earlier run's")
    monkeypatch.setattr(stages.fea, "_fea_steps", fea_steps_with_failing_coarser)
    assert pipeline.main([*FAST, "--out", str(out), "--cache-dir", str(cache)]) == 2
    stderr = capsys.readouterr().err
    lines = [line for line in stderr.splitlines() if not line.startswith("pipeline.py: warning:")]
    assert lines == ["pipeline.py: error: coarser level: a failure made up by the test"], lines
    assert [p.name for p in out.iterdir()] == ["summary.json"] and (
        out / "summary.json"
    ).read_text() == "an earlier run's"
    assert not list(Path(cache).rglob("result.json"))
