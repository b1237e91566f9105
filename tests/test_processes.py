"""The garbage collector paused for a process's imports (processes.pause_collector_for_imports,
imports_done): off during them, on after with everything made so far frozen, and nothing done
where it was not paused. Each case in a fresh interpreter: freezing this one's objects would keep
the test session's garbage for good.

Work mapped over forked workers (processes.forked_map, the figure and scenario workers' one
pattern): the results in the items' order from workers that see this process's objects (items that
cannot be pickled), each worker's initializer, a call back here as each ends, a dying worker as
BrokenProcessPool, and nothing left behind (its item list, a frozen collector)."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import pytest

import processes

ROOT = Path(__file__).resolve().parents[1]


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    return out.stdout.strip().splitlines()[-1]


def test_the_collector_is_off_during_the_imports_and_on_after_with_their_objects_frozen():
    code = """
import gc
from processes import imports_done, pause_collector_for_imports
pause_collector_for_imports()
off = not gc.isenabled()
import colorsys
frozen_before = gc.get_freeze_count()
imports_done()
print(off, frozen_before == 0, gc.isenabled(), gc.get_freeze_count() > 0)
"""
    assert _run(code) == "True True True True"


def test_nothing_happens_where_the_collector_was_not_paused():
    code = """
import gc
from processes import imports_done, pause_collector_for_imports
imports_done()
unpaused = (gc.isenabled(), gc.get_freeze_count())
gc.disable()  # paused by someone else: left to them
pause_collector_for_imports()
imports_done()
print(unpaused == (True, 0), gc.isenabled(), gc.get_freeze_count())
"""
    assert _run(code) == "True False 0"


def test_the_runs_imports_end_the_pause_that_python_pipeline_py_starts():
    code = """
import gc
import pipeline
from processes import pause_collector_for_imports
pause_collector_for_imports()  # as `python pipeline.py` does before anything else
pipeline._import_chain_and_outputs(pipeline.parse_cli([]))
print(gc.isenabled(), gc.get_freeze_count() > 0)
"""
    assert _run(code) == "True True"


needs_fork = pytest.mark.skipif(not processes.may_fork_children(), reason="forked workers need fork")

_STARTED_IN: list = []  # a worker's initializer's mark


def _mark_worker() -> None:
    _STARTED_IN.append(os.getpid())


def _square_in_worker(item) -> tuple:
    # item: (a value, a lambda): a lambda cannot be pickled, so the worker saw it at the fork
    value, unpicklable = item
    return unpicklable(value), os.getpid(), list(_STARTED_IN)


@needs_fork
def test_forked_map_gives_each_result_in_order_from_workers_that_share_this_process():
    ended = []
    items = [(i, lambda x: x * x) for i in range(7)]
    out = processes.forked_map(
        _square_in_worker, items, 2, initializer=_mark_worker, on_each=lambda i, r: ended.append((i, r[0]))
    )
    assert [r[0] for r in out] == [i * i for i in range(7)]
    assert {pid for _, pid, _ in out}.isdisjoint({os.getpid()})  # not here
    assert all(started == [pid] for _, pid, started in out)  # each worker's initializer, once, in it
    assert sorted(ended) == [(i, i * i) for i in range(7)]  # every call back here, with its result
    assert processes._FORKED == [] and _STARTED_IN == []


def _exit_in_worker(item) -> None:
    os._exit(3)


@needs_fork
def test_forked_map_says_a_dying_worker_and_leaves_nothing_behind():
    frozen = gc.get_freeze_count()
    with pytest.raises(BrokenProcessPool):
        processes.forked_map(_exit_in_worker, [1, 2], 2, freeze_collector=True)
    assert processes._FORKED == []
    assert gc.get_freeze_count() == frozen  # the collector sees this process's objects again
