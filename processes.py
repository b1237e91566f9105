"""What the running process may use beside itself: child processes, and its cores; and the cyclic
garbage collector paused while a process imports its libraries.

Both the FEA beside the run (stages.beside) and the figure workers (reporting.drawing) start
children; this module is below both, so that reporting does not import the stages.
"""

from __future__ import annotations

import gc
import multiprocessing
import os

_collector_paused = False  # by pause_collector_for_imports, until imports_done


def may_start_children() -> bool:
    """Whether a child process can be started here: not in a daemonic process (a Dask worker may not
    have children, and its cores are the cluster's already)."""
    return not multiprocessing.current_process().daemon


def may_fork_children() -> bool:
    """Whether a child process can be forked here: one may be started (`may_start_children`) and the
    platform has the fork start method (the workers that share this process's loaded modules)."""
    return may_start_children() and "fork" in multiprocessing.get_all_start_methods()


def usable_cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def pause_collector_for_imports() -> None:
    """The cyclic garbage collector paused until `imports_done`, at the start of a process that
    imports its libraries before its work. Importing numba, SciPy, matplotlib and the chain's
    modules makes about 170,000 objects that live as long as the process (modules, classes,
    functions, numba's types); the collector's passes over them as they pile up (about 390 passes,
    three of them over everything) took about 0.45 CPU s of the run's process's imports, and found
    almost nothing to free."""
    global _collector_paused
    if gc.isenabled():
        gc.disable()
        _collector_paused = True


def imports_done() -> None:
    """The end of the imports `pause_collector_for_imports` paused the collector for: every object
    made so far moved out of its sight (gc.freeze: later passes, the full ones too, look at the
    objects made after this only), then the collector on again. What the imports left as cyclic
    garbage stays (about 5,800 objects, under 1 MB of their own, in the run's process). Nothing
    happens where the collector was not paused (`pipeline.main` called from Python)."""
    global _collector_paused
    if _collector_paused:
        _collector_paused = False
        gc.freeze()
        gc.enable()
