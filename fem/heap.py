"""Give the C heap's free pages back to the operating system between FEA levels.

A level's solve allocates and frees hundreds of MB (assembly, PARDISO's factor, stresses), much of
it in the levels' threads, whose glibc arenas keep their freed pages. The process's resident memory
then grows level after level and stays high after the FEA, under the dynamics and the figures:
the default run peaked at 0.99 GB after its FEA had finished. `malloc_trim(0)` returns the free
pages of every arena (milliseconds).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import threading


@functools.cache
def libc_function(name: str, argtypes: tuple, restype):
    """The C library's function `name` with its signature, or None where the library or the
    function does not exist (not glibc: macOS, Windows, musl)."""
    library = ctypes.util.find_library("c")
    if library is None:
        return None
    try:
        function = getattr(ctypes.CDLL(library), name)
    except (OSError, AttributeError):
        return None
    function.argtypes = list(argtypes)
    function.restype = restype
    return function


def release_free_memory() -> bool:
    """Return the heap's free pages to the OS; False where the C library has no malloc_trim (not
    glibc), which keeps its own policy."""
    trim = libc_function("malloc_trim", (ctypes.c_size_t,), ctypes.c_int)
    return trim is not None and trim(0) == 1


class TrimmingLock:
    """A lock (a context manager) whose waiter first gives the heap's free pages back
    (`release_free_memory`): a thread that must wait has freed its temporaries into its own malloc
    arena, which the holder's thread does not reuse, so that they would stay resident beside the
    holder's work for the whole wait. A thread that finds the lock free takes it at once."""

    def __init__(self):
        self._lock = threading.Lock()
        self.trimmed_waits = 0  # how many waiters trimmed the heap (for tests and measurements)

    def __enter__(self) -> TrimmingLock:
        if not self._lock.acquire(blocking=False):
            release_free_memory()
            self.trimmed_waits += 1
            self._lock.acquire()
        return self

    def __exit__(self, *exc) -> bool:
        self._lock.release()
        return False
