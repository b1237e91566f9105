"""What the running process may use beside itself: child processes, and its cores.

Both the FEA beside the run (stages.beside) and the figure workers (reporting.drawing) start
children; this module is below both, so that reporting does not import the stages.
"""

from __future__ import annotations

import multiprocessing
import os


def may_start_children() -> bool:
    """Whether a child process can be started here: not in a daemonic process (a Dask worker may not
    have children, and its cores are the cluster's already)."""
    return not multiprocessing.current_process().daemon


def usable_cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
