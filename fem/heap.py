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


@functools.cache
def _malloc_trim():
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        trim = ctypes.CDLL(name).malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


def release_free_memory() -> bool:
    """Return the heap's free pages to the OS; False where the C library has no malloc_trim (not
    glibc), which keeps its own policy."""
    trim = _malloc_trim()
    return trim is not None and trim(0) == 1
