"""A stage run in a forked process beside the run's next stages, handing over its results in steps.

The FEA's stress study and deformed images feed only the stress lines of the outputs, not the
chain: `pipeline.py` runs the FEA in a child process that hands over the stiffness first (what the
chain needs), goes on with the stress study while the dynamics and the figures run here, and hands
over the stresses last. The stage is a generator: each value it yields is one step handed over.

Why the whole FEA and not only the stress study: the child is forked before this process has
meshed anything. gmsh's mesher runs OpenMP regions, and a child forked after them hangs at its first
one (measured: the stress study's first mesh waited forever in gmsh's thread pool); the stiffness
levels mesh too, so they run in the child. Forked, the child starts with everything this process
holds (the part, the imported modules): nothing is pickled on the way in, only the (small) steps on
the way back, through a pipe. An exception in the child is raised again here; a child that dies
without handing over a step (killed, out of memory) is one `BesideError`.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Iterator


class BesideError(RuntimeError):
    """The process beside the run ended without a result; the message says what it was doing."""


def can_fork() -> bool:
    """Whether a child can be forked here: POSIX, and not a daemonic process (a Dask worker drawing a
    study's designs may not have children, and its cores are the cluster's already)."""
    return hasattr(os, "fork") and not multiprocessing.current_process().daemon


class Beside:
    """The generator `steps()` running in a forked child: `next()` waits for its next step and returns
    it (the child's exception is raised again here), `close()` waits for the child to end after its
    last one, `cancel()` stops it. `what` names the work in messages."""

    def __init__(self, steps: Callable[[], Iterator], what: str):
        self.what = what
        receive, send = multiprocessing.Pipe(duplex=False)
        sys.stdout.flush()
        sys.stderr.flush()
        self.pid = os.fork()
        if self.pid == 0:  # the child: never returns into the parent's stack
            receive.close()
            _run_child(steps, send)
        send.close()
        self._receive = receive
        self._running = True

    def next(self):
        """The child's next step (waiting for it)."""
        if not self._running:
            raise BesideError(f"{self.what}: it has ended already")
        try:
            kind, value = self._receive.recv()
        except EOFError:
            raise BesideError(f"{self.what}: its process ended early ({self._wait()})") from None
        if kind == "error":
            self._wait()
            raise value
        if kind == "end":
            self._wait()
            raise BesideError(f"{self.what}: it has no further step")
        return value

    def close(self) -> None:
        """Wait for the child to end after its last step."""
        if not self._running:
            return
        try:
            kind, value = self._receive.recv()
        except EOFError:
            raise BesideError(f"{self.what}: its process ended early ({self._wait()})") from None
        self._wait()
        if kind == "error":
            raise value

    def cancel(self) -> None:
        """Stop the child if it still runs (a failure elsewhere in the run: nothing waits for it)."""
        if not self._running:
            return
        try:
            os.kill(self.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        self._wait()

    def _wait(self) -> str:
        self._running = False
        self._receive.close()
        _, status = os.waitpid(self.pid, 0)
        return _status_text(status)


def _run_child(steps: Callable[[], Iterator], send) -> None:
    code = 1
    try:
        try:
            for step in steps():
                send.send(("step", step))
            send.send(("end", None))
        except BaseException as exc:  # KeyboardInterrupt too: the parent reports it
            _send_error(send, exc)
        code = 0
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)  # no parent's atexit handlers, finally blocks or buffers run twice


def _send_error(send, exc: BaseException) -> None:
    try:
        send.send(("error", exc))
    except Exception:  # an exception that does not pickle: its words
        send.send(("error", BesideError(f"{type(exc).__name__}: {exc}")))


def _status_text(status: int) -> str:
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        killed = ", killed: out of memory?" if number == signal.SIGKILL else ""
        return f"signal {signal.Signals(number).name}{killed}"
    return f"exit code {os.waitstatus_to_exitcode(status)}"
