"""What a long chain's scenario on wheels costs at the least, whatever its searches (issue #24's 20 s
at 10,000 links): one index cycle at each of the steps a scenario takes, timed from a state near the
clearance machine's steady state.

    python benchmarks/bench_long_floor.py --links 10000 [--repeats 3]

The scene is bench_long_wheels.long_scene(N) (the pipeline's default scenario on wheels). The state is
the clearance machine's coarse search from rest to 1e-3 (machine_shooting.relabelled_periodic_state at
SEARCH_SAFETY: impacts and slack zones as in the steady state). From it, CPU seconds (time.process_time,
the median of REPEATS) of: a coarse cycle (the searches' step), a cycle at the window's step (the
settle's, above rho 0.92: what accepts the state) and the window (machine_scene._window, its outputs
recorded). A scenario that meets its accuracy steps the window and at least one cycle at the window's
step after its searches: their sum is its floor, and what is left of a budget is what the searches may
spend, in coarse cycles.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.bench_long_wheels import long_scene  # noqa: E402 (after sys.path)

BUDGET_S = 20.0  # issue #24's target for one 10,000-link scenario


def _cpu_s(run, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return statistics.median(times)


def main(argv=None) -> None:
    from dynamics import machine_scene as ms
    from dynamics.solvers import clearance_verlet as verlet
    from dynamics.solvers import machine_shooting, shooting
    from dynamics.solvers import machine_verlet as mv

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--links", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)

    chain, scene, cam, t = long_scene(args.links)
    model = ms.machine_model(scene, chain)
    h_out = float(t[1] - t[0])
    per_cycle = int(round(cam.period_s / h_out))
    pred = verlet.default_predictor(model)
    safety = verlet.default_safety(model, pred)
    coarse = mv.substeps_for(model, h_out, ms.SEARCH_SAFETY[model.span_damping], pred)
    fine = mv.substeps_for(model, h_out, safety / ms.WINDOW_REFINEMENT[model.span_damping], pred)
    rest = np.zeros(model.n_state)

    start = time.process_time()
    q0, v0, cycles, _, found, _ = machine_shooting.relabelled_periodic_state(
        model, cam, h_out / coarse, per_cycle * coarse, rest, rest, tol=1e-3, max_cycles=60, predictor=pred
    )
    search_s = time.process_time() - start
    print(
        f"{args.links} links: the coarse search from rest to 1e-3, {cycles} cycles, {search_s:.1f} CPU s (found: {found})"
    )

    def cycle(sub):
        h = h_out / sub
        nodes = mv.cycle_nodes(cam, h, per_cycle * sub)
        every = shooting.search_out_every(per_cycle * sub)
        return lambda: mv.next_index_start(model, cam, nodes, h, q0, v0, out_every=every, predictor=pred, seating=False)

    coarse_s = _cpu_s(cycle(coarse), args.repeats)
    settle_s = _cpu_s(cycle(fine), args.repeats)
    window_s = _cpu_s(lambda: ms._window(model, cam, t, per_cycle, fine, (q0, v0), pred, True), args.repeats)
    floor_s = settle_s + window_s
    print(f"a coarse cycle ({coarse * per_cycle} steps): {coarse_s:.3g} CPU s")
    print(f"a cycle at the window's step ({fine * per_cycle} steps): {settle_s:.3g} CPU s")
    print(f"the window: {window_s:.3g} CPU s")
    left_s = max(BUDGET_S - floor_s, 0.0)
    print(
        f"floor (the window and one accepting cycle): {floor_s:.3g} CPU s; of {BUDGET_S:g} s that leaves "
        f"{left_s:.3g} s, {left_s / coarse_s:.0f} coarse cycles for the searches"
    )


if __name__ == "__main__":
    main()
