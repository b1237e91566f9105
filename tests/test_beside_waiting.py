"""A process started before its work is known (stages.beside.Beside.waiting, the FEA's process of
`python pipeline.py`): it imports what it is told, runs the steps it is handed as a process started
on them would, ends quietly when it is handed none, and a failure before its steps is one
BesideError that says what failed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from functools import partial
from pathlib import Path

import pytest

from stages.beside import Beside, BesideError


def modules_and_numbers(count: int):
    """Steps that report whether the waiting child imported its modules before them."""
    yield "json" in sys.modules and "colorsys" in sys.modules
    yield from range(count)


def test_a_waiting_process_imports_its_modules_then_runs_the_steps_it_is_handed():
    beside = Beside.waiting("the test's work", ("json", "colorsys"))
    beside.hand(partial(modules_and_numbers, 2), "the test's work")
    assert [beside.next(), beside.next(), beside.next()] == [True, 0, 1]
    beside.close()
    assert beside._process.exitcode == 0


def collector_state():
    """Steps that report the waiting child's garbage collector: on, and the imported modules frozen."""
    import gc

    yield gc.isenabled(), gc.get_freeze_count() > 0, gc.is_tracked(sys.modules["colorsys"].__dict__)


def test_a_waiting_process_runs_its_steps_with_the_collector_on_and_its_imports_frozen():
    beside = Beside.waiting("the test's work", ("json", "colorsys"))
    beside.hand(collector_state, "the test's work")
    assert beside.next() == (True, True, True)
    beside.close()


def test_a_waiting_process_handed_nothing_ends_quietly_when_its_pipe_closes():
    beside = Beside.waiting("the test's work", ())
    beside._hand_over.close()  # as when this process ends without handing it anything
    beside._process.join(timeout=30)
    assert beside._process.exitcode == 0


def test_a_waiting_process_is_cancelled_without_an_error():
    beside = Beside.waiting("the test's work", ("json",))
    beside.cancel()
    assert not beside._process.is_alive()
    beside.cancel()  # a second cancel (the run's own, after start_fea's) does nothing


def test_a_failed_import_in_a_waiting_process_is_one_beside_error():
    beside = Beside.waiting("the test's work", ("no_such_module_anywhere",))
    beside.hand(partial(modules_and_numbers, 1), "the test's work")
    with pytest.raises(BesideError, match="^the test's work: its process failed to start: ModuleNotFoundError"):
        beside.next()


def test_a_waiting_process_killed_before_its_steps_is_one_beside_error():
    beside = Beside.waiting("the test's work", ())
    os.kill(beside.pid, signal.SIGKILL)
    beside._process.join(timeout=30)
    beside.hand(partial(modules_and_numbers, 1), "the test's work")  # the pipe's other end is gone: no error here
    with pytest.raises(BesideError, match=r"^the test's work: its process ended early \(signal 9"):
        beside.next()


def test_a_killed_waiting_process_is_one_beside_error_after_gmsh_has_run_here():
    """gmsh.initialize sets SIGPIPE back to the default (the run's process resolves its part with
    gmsh before it hands the FEA over): handing steps to a dead child must not write to its pipe,
    which would end this process without a word. Checked in a fresh process, whose death would
    otherwise take the test runner's worker with it."""
    probe = (
        "import os, signal, sys\n"
        "from functools import partial\n"
        "import gmsh\n"
        "gmsh.initialize(); gmsh.finalize()\n"
        "from stages.beside import Beside, BesideError\n"
        "beside = Beside.waiting('the work', ())\n"
        "os.kill(beside.pid, signal.SIGKILL)\n"
        "beside._process.join(timeout=30)\n"
        "beside.hand(partial(range, 1), 'the work')\n"
        "try:\n"
        "    beside.next()\n"
        "except BesideError as exc:\n"
        "    print('one line:', exc)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr)
    assert done.stdout.startswith("one line: the work: its process ended early (signal 9")


def test_a_waiting_process_starts_no_resource_tracker_and_ends_without_teardown_its_output_flushed():
    """The waiting child is a plain interpreter (no multiprocessing resource tracker beside it) that
    ends with os._exit after its last step: an exit handler it registered does not run, what it
    printed unflushed still comes out. In a fresh process, whose tracker state is its own."""
    probe = (
        "from functools import partial\n"
        "from multiprocessing import resource_tracker\n"
        "from stages.beside import Beside\n"
        "beside = Beside.waiting('the work', ())\n"
        "beside.hand(partial(exit_handler_and_print), 'the work')\n"
        "print(beside.next(), flush=True)\n"
        "beside.close()\n"
        "print('tracker', resource_tracker._resource_tracker._pid, 'exit code', beside._process.exitcode)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # the child's print stays buffered
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1])
    done = subprocess.run(
        [sys.executable, "-c", f"from tests.test_beside_waiting import exit_handler_and_print\n{probe}"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, (done.returncode, done.stderr)
    assert sorted(done.stdout.splitlines()) == ["printed", "stepped", "tracker None exit code 0"]


def exit_handler_and_print():
    """One step, after registering an exit handler that would fail the test and printing unflushed."""
    import atexit

    atexit.register(print, "the interpreter's teardown ran")
    sys.stdout.write("printed\n")
    yield "stepped"
