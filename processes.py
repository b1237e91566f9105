"""What the running process may use beside itself: child processes, and its cores; work mapped over
processes forked from it; and the cyclic garbage collector paused while a process imports its
libraries.

The FEA beside the run (stages.beside), the figure workers (reporting.drawing) and a long chain's
scenario workers (stages.chain) start children; this module is below them all, so that reporting
does not import the stages.
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


# The forked_map call in progress, (function, items), for its forked workers: set before they fork,
# so that a worker is sent an item's number, not the item
_FORKED: list = []


def forked_map(function, items, workers: int, *, initializer=None, on_each=None, freeze_collector=False) -> list:
    """[function(item) for item in items], the calls spread over `workers` processes forked from this
    one: the modules and objects loaded here are the workers' at the fork (nothing imported again,
    nothing pickled to them but an item's number), each result is pickled back. `function`: a
    module-level function (the workers look it up by name). `initializer`: run once in each worker
    as it starts. `on_each(i, result)`: called here as each call ends, in the order they end (a
    progress line). `freeze_collector`: this process's objects moved out of the cyclic collector's
    sight while the workers run (gc.freeze): a worker's collections would otherwise touch every one of
    them and copy the pages they are on (copy on write). Returns the results in the items' order; a
    worker that dies raises concurrent.futures.process.BrokenProcessPool. Only where
    `may_fork_children`."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    _FORKED[:] = [function, list(items)]
    if freeze_collector:
        gc.freeze()
    try:
        with ProcessPoolExecutor(
            workers, mp_context=multiprocessing.get_context("fork"), initializer=initializer
        ) as pool:
            pending = {pool.submit(_forked_call, i): i for i in range(len(_FORKED[1]))}
            results = {}
            while pending:
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in finished:
                    i = pending.pop(future)
                    results[i] = future.result()
                    if on_each is not None:
                        on_each(i, results[i])
        return [results[i] for i in range(len(results))]
    finally:
        if freeze_collector:
            gc.unfreeze()
        _FORKED.clear()


def _forked_call(index: int):
    """In a forked worker: the function of the forked_map call that forked it, on its index-th item."""
    function, items = _FORKED
    return function(items[index])


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
