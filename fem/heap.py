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
