"""A stage run in a second process beside the run's next stages, handing over its results in steps.

The FEA's stress study and deformed images feed only the stress lines of the outputs, not the
chain: `pipeline.py` runs the FEA in a child process that hands over the stiffness first (what the
chain needs), goes on with the stress study while the dynamics and the figures run here, and hands
over the stresses last. The stage is a generator: each value it yields is one step handed over.

The child is a fresh interpreter (multiprocessing's "spawn"), not a fork of this process: gmsh
(its OpenCASCADE and OpenMP thread pools) hangs in a child forked from a process that has meshed
before (measured: the child's first mesh waited forever on a thread of the parent's pool that
does not exist in the child), and a process cannot know whether a library it loaded has. What
goes in (the part, the settings, the materials) and each step coming back are pickled, a few kB;
the child's imports run on the other core while this process imports its own. An exception in the
child is raised again here; a child that dies without handing over a step (killed, out of memory)
is one `BesideError`.

A child can also be started before its work is known (`Beside.waiting`): it imports the modules it
is told to, then waits to be handed its steps (`hand`), so that its interpreter's start-up and its
imports run while this process is still reading its command line. That child is a plain `python -c`
of its own (`_WaitingInterpreter`), not multiprocessing's spawn: spawn starts multiprocessing's
resource tracker, a third interpreter (0.05-0.09 CPU s) watching for semaphores and shared memory
that neither process makes, and runs this process's main script again in the child; and the child
ends with `os._exit` once its last step is handed over, without the interpreter's teardown of its
libraries (SciPy, scikit-fem, gmsh), which the run waits for before its summary.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import subprocess
import sys
import traceback
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection


class BesideError(RuntimeError):
    """The process beside the run ended without a result; the message says what it was doing."""


class Beside:
    """The generator `steps()` (picklable: a module-level function or a partial of one) running in
    a child process: `next()` waits for its next step and returns it (the child's exception is
    raised again here), `close()` waits for the child to end after its last one, `cancel()` stops
    it. `what` names the work in messages. `start_method` "fork" (where the caller knows that the
    child uses nothing the fork leaves broken, such as gmsh, see above) starts the child without
    importing anything again and without pickling `steps`."""

    def __init__(self, steps: Callable[[], Iterator], what: str, start_method: str = "spawn"):
        self._hand_over = None
        self._start(what, start_method, _run_child, steps, thread_limits())

    @classmethod
    def waiting(cls, what: str, modules: tuple[str, ...]) -> Beside:
        """A fresh interpreter that imports `modules`, then waits for `hand`. Not handed its steps,
        it ends when this process closes its end of the pipe (or ends) or at `cancel()`."""
        beside = cls.__new__(cls)
        receive_steps, beside._hand_over = _pipe()
        beside._receive, send = _pipe()
        beside.what = what
        beside._process = _WaitingInterpreter(receive_steps, send, what, modules)
        receive_steps.close()
        send.close()
        beside._running = True
        return beside

    def hand(self, steps: Callable[[], Iterator], what: str) -> None:
        """Give a `waiting` child its steps (pickled now, run there on this process's thread limits).
        A child that has ended already (its imports failed, or it was killed) is not written to: a
        process that has used gmsh no longer ignores SIGPIPE (gmsh.initialize sets it back to the
        default; the run's process resolves the part with gmsh before it hands the FEA over), so a
        write to the dead child's pipe would end this process without a word; `next` then raises
        what the child sent, or that it ended early."""
        self.what = what
        try:
            if self._process.is_alive():
                self._hand_over.send((steps, thread_limits()))
        except OSError:  # it ended between the check and the write
            pass
        finally:
            self._hand_over.close()

    def _start(self, what: str, start_method: str, target, *args) -> None:
        """The child running target(send, *args), `send` its end of the pipe its steps come back by."""
        self.what = what
        context = multiprocessing.get_context(start_method)
        receive, send = context.Pipe(duplex=False)
        self._process = context.Process(target=target, args=(send, *args), name=what)
        self._process.start()
        send.close()
        self._receive = receive
        self._running = True

    @property
    def pid(self) -> int:
        return self._process.pid

    def next(self):
        """The child's next step (waiting for it)."""
        kind, value = self._receive_one()
        if kind == "end":
            self._wait()
            raise BesideError(f"{self.what}: it has no further step")
        return value

    def close(self) -> None:
        """Wait for the child to end after its last step."""
        if self._running:
            self._receive_one()
            self._wait()

    def cancel(self) -> None:
        """Stop the child if it still runs (a failure elsewhere in the run: nothing waits for it; or
        a `waiting` child the run had no work for)."""
        if self._hand_over is not None:
            self._hand_over.close()
        if self._running:
            self._process.terminate()
            self._wait()

    def _receive_one(self) -> tuple[str, object]:
        if not self._running:
            raise BesideError(f"{self.what}: it has ended already")
        try:
            kind, value = self._receive.recv()
        except EOFError:
            raise BesideError(f"{self.what}: its process ended early ({self._wait()})") from None
        if kind == "error":
            self._wait()
            raise value
        return kind, value

    def _wait(self) -> str:
        self._running = False
        self._receive.close()
        self._process.join()
        code = self._process.exitcode
        if code is not None and code < 0:
            return f"signal {-code}" + (", killed: out of memory?" if code == -9 else "")
        return f"exit code {code}"


def _pipe() -> tuple[Connection, Connection]:
    """(receiving end, sending end) of a pipe, as multiprocessing.Pipe(duplex=False) makes one."""
    receiving, sending = os.pipe()
    return Connection(receiving, writable=False), Connection(sending, readable=False)


class _WaitingInterpreter:
    """`python -c` running `_waiting_child` with this process's interpreter options and sys.path (as
    multiprocessing's spawn passes them), the pipes' child ends inherited by their descriptors; with
    the part of multiprocessing.Process's interface that Beside uses."""

    def __init__(self, receive_steps: Connection, send: Connection, what: str, modules: tuple[str, ...]):
        code = f"import sys; sys.path[:] = {sys.path!r}; from stages.beside import _waiting_child; _waiting_child()"
        fds = (receive_steps.fileno(), send.fileno())
        self._popen = subprocess.Popen(
            [sys.executable, *subprocess._args_from_interpreter_flags(), "-c", code, *map(str, fds), what, *modules],
            pass_fds=fds,
            stdin=subprocess.DEVNULL,  # as multiprocessing's child: the terminal's input stays the run's
        )
        self.pid = self._popen.pid

    def is_alive(self) -> bool:
        return self._popen.poll() is None

    def terminate(self) -> None:
        self._popen.terminate()

    def join(self, timeout: float | None = None) -> None:
        try:
            self._popen.wait(timeout)
        except subprocess.TimeoutExpired:
            pass

    @property
    def exitcode(self) -> int | None:
        return self._popen.poll()


def _waiting_child() -> None:
    """The main of `_WaitingInterpreter`'s child (its arguments: the descriptors of the steps' pipe
    and of the pipe back, what it runs, the modules to import): `_run_handed_child`, then the end of
    the process without the interpreter's teardown, its output flushed."""
    receive_steps, send, what, *modules = sys.argv[1:]
    code = 1  # what escapes `_run_handed_child` (its errors go back by the pipe) is a failure
    try:
        _run_handed_child(
            Connection(int(send), readable=False), Connection(int(receive_steps), writable=False), tuple(modules), what
        )
        code = 0
    except BaseException:
        traceback.print_exc()
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def thread_limits() -> dict[str, int]:
    """The thread pools' sizes of the libraries loaded in this process, per library kind
    ("openblas", "mkl", "openmp"; threadpoolctl), the smallest of each: the child's main thread
    runs them as this one would (a caller limited to one thread for reproducible sums, e.g.
    tests/test_pipeline_machine.py's snapshot, gets the numbers it got in one process)."""
    from threadpoolctl import threadpool_info

    limits: dict[str, int] = {}
    for pool in threadpool_info():
        kind = pool["internal_api"]
        limits[kind] = min(limits.get(kind, pool["num_threads"]), pool["num_threads"])
    return limits


def _run_child(send, steps: Callable[[], Iterator], limits: dict[str, int]) -> None:
    from threadpoolctl import threadpool_limits

    try:
        # on this thread, as threadpoolctl limits the caller's: the stiffness levels' own threads and
        # the libraries loaded later (MKL, with PARDISO) run at their defaults in either process
        with threadpool_limits(limits=limits):
            for step in steps():
                send.send(("step", step))
        send.send(("end", None))
    except BaseException as exc:  # KeyboardInterrupt too: the parent reports it
        _send_error(send, exc)


def _send_error(send, exc: BaseException) -> None:
    try:
        send.send(("error", exc))
    except Exception:  # an exception that does not pickle: its words
        send.send(("error", BesideError(f"{type(exc).__name__}: {exc}")))


def _run_handed_child(send, receive_steps, modules: tuple[str, ...], what: str) -> None:
    """A `Beside.waiting` child: its imports, then the steps it is handed, run as `_run_child` runs
    them. Not handed any (the pipe closed), it ends quietly. A failure before its steps (an import,
    or the steps that do not unpickle here) is a `BesideError` that says so. The garbage collector
    is paused for the imports (processes.pause_collector_for_imports)."""
    from processes import imports_done, pause_collector_for_imports

    try:
        pause_collector_for_imports()
        try:
            for name in modules:
                importlib.import_module(name)
        finally:
            imports_done()
        try:
            steps, limits = receive_steps.recv()
        except EOFError:
            return
        finally:
            receive_steps.close()
    except BaseException as exc:
        _send_error(send, BesideError(f"{what}: its process failed to start: {type(exc).__name__}: {exc}"))
        return
    _run_child(send, steps, limits)
