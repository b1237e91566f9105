"""Dask workers keep large arrays on the reused heap (study/worker_malloc.py).

Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, which freezes glibc's mmap
threshold at 128 KiB: every larger array becomes its own mapping (counted by mallinfo2's hblks).
The fix must undo exactly that, in a process started the way Dask starts its workers.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

MAPPED_BLOCKS = """
import ctypes, ctypes.util
import numpy as np
from study.worker_malloc import keep_large_arrays_on_heap

class MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]

libc = ctypes.CDLL(ctypes.util.find_library("c"))
libc.mallinfo2.restype = MallInfo2
if {fix}:
    assert keep_large_arrays_on_heap()
before = libc.mallinfo2().hblks
array = np.ones(1 << 20)  # 8 MiB, far above 128 KiB and below the raised threshold
print(libc.mallinfo2().hblks - before)
"""


def _mapped_blocks_for_an_8_MiB_array(fix: bool) -> int:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MALLOC_TRIM_THRESHOLD_": "65536"}
    out = subprocess.run(
        [sys.executable, "-c", MAPPED_BLOCKS.format(fix=fix)], env=env, capture_output=True, text=True, check=True
    )
    return int(out.stdout.split()[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc tunables are Linux-only")
def test_a_worker_environment_maps_large_arrays_and_the_fix_puts_them_on_the_heap():
    assert _mapped_blocks_for_an_8_MiB_array(fix=False) == 1
    assert _mapped_blocks_for_an_8_MiB_array(fix=True) == 0


def test_dask_still_starts_workers_with_a_malloc_tunable():
    """If a Dask release stops setting it, the fix is no longer needed: this says so."""
    import dask
    import distributed  # noqa: F401  (registers the distributed config)

    assert "MALLOC_TRIM_THRESHOLD_" in dask.config.get("distributed.nanny.pre-spawn-environ")
