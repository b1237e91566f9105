"""Let a Dask worker reuse freed memory for large numpy arrays, as an ordinary process does.

Dask's nanny starts each worker with MALLOC_TRIM_THRESHOLD_=65536 (its
`distributed.nanny.pre-spawn-environ`), and setting any glibc malloc tunable freezes malloc's
dynamic mmap threshold at 128 KiB. Every array above that is then a fresh mapping, page-faulted
in on first touch and unmapped when freed. The FEA allocates large temporaries level after level:
one study FEA task took 3.62 s of CPU in a plain process and 4.47 s with Dask's variable. Raising
the mmap threshold to glibc's maximum (32 MiB on 64-bit) at run time puts those arrays back on the
reused heap: 3.55 s (`python benchmarks/run.py --only study`, medians of three alternating fresh
processes). Dask's trim threshold still returns idle memory.
Done in the task, not in the cluster's environment, so workers started by hand on other machines
(`dask worker ...`) get it too.
"""

from __future__ import annotations

import ctypes
import functools

from fem.heap import libc_function

M_MMAP_THRESHOLD = -3  # glibc's mallopt parameter number (malloc.h)
MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024  # glibc's upper limit for it on 64-bit (DEFAULT_MMAP_THRESHOLD_MAX)


@functools.cache
def keep_large_arrays_on_heap() -> bool:
    """Raise glibc's mmap threshold once per process; False where the C library has no mallopt
    (not glibc: macOS, Windows, musl), which then keeps its own policy."""
    mallopt = libc_function("mallopt", (ctypes.c_int, ctypes.c_int), ctypes.c_int)
    return mallopt is not None and mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
