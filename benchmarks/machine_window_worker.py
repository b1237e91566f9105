"""One round of bench_machine's window in a process of its own, for the tree it is started in.

    cd TREE && PYTHONPATH=TREE python <this tree>/benchmarks/machine_window_worker.py '{"subs": [9, 10]}'

Imports TREE's benchmarks/bench_machine.py helpers (`_window_run`, `_window_times`, `_chain`,
`layout`; present since 13f2a75) and TREE's dynamics, so an old tree's compiled step runs with its
own modules (its damping product's signature, its window), never this tree's. Runs the window once
at the first steps-per-sample to compile (or load the cache), then once at each, and prints one JSON
line: {"seconds": {sub: CPU seconds}, "metrics": {sub: station metrics}}. bench_machine starts it for
this tree and for BENCH_MACHINE_OLD_TREE alternately, so both are measured the same way.
"""

from __future__ import annotations

import json
import os
import sys


def main(argv: list[str]) -> int:
    # this script's own directory is sys.path[0] when run by path: the tree's modules must come from
    # PYTHONPATH (the tree being measured), not from beside this file
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != here]
    from benchmarks import bench_machine as bench
    from dynamics.cams import CamProgram
    from dynamics.models.clearance import DEFAULT_PIN_CLEARANCE_M
    from dynamics.models.clearance_machine import ClearanceMachine

    subs = [int(s) for s in json.loads(argv[0])["subs"]]
    cam = CamProgram.indexing("modified-sine", pitch_m=bench.PITCH_M, rpm=bench.RPM)
    t = bench._window_times()
    model = ClearanceMachine.of(bench._chain("al6061-t6"), bench.layout(), None, DEFAULT_PIN_CLEARANCE_M)
    bench._window_run(model, cam, t, subs[0])  # compile (or load the cache) outside the timings
    seconds, metrics = {}, {}
    for sub in subs:
        seconds[sub], values = bench._window_run(model, cam, t, sub)
        metrics[sub] = [float(x) for x in values]
    print(json.dumps({"seconds": seconds, "metrics": metrics}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
