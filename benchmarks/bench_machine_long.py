"""Long clearance chains on wheels (issue #24): memory and time of the machine's step with the O(N)
global damping (dynamics.models.machine_damping) at N = 500 .. 10,000 links.

    python benchmarks/bench_machine_long.py    (or python benchmarks/run.py --only machine_long)

Each N: the default wheels (12 teeth, 6 wrapped, idler wheel, polygonal feed), a tensioned carriage,
0.094 mm free play, friction 0.1, 180 rpm modified sine; building the model's arrays and 400 steps
from a disturbed state. Memory: the peak of Python-tracked allocations (tracemalloc: numpy arrays)
over both; time: wall and CPU seconds of the 400 steps (numba cache warm: one short run first; the
factors in single precision above machine_damping.SINGLE_PRECISION_FACTORS_ABOVE_LINKS, warmed too).
"""

from __future__ import annotations

import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.defaults import DEFAULT_RUN, PITCH_M  # noqa: E402
from dynamics.cams import CamProgram  # noqa: E402
from dynamics.models.chain import ChainModel  # noqa: E402
from dynamics.models.clearance import Tensioner  # noqa: E402
from dynamics.models.clearance_machine import ClearanceMachine  # noqa: E402
from dynamics.models.layout import MachineLayout  # noqa: E402
from dynamics.models.wheels import Wheel  # noqa: E402
from dynamics.solvers import machine_verlet as mv  # noqa: E402

STEPS = 400


def one(n_links: int) -> tuple[float, float, float]:
    """(peak MB, wall and CPU seconds for STEPS steps) of one machine."""
    wheel = Wheel(12, PITCH_M, 6, 0.688)
    chain = ChainModel(n_links, 2.03, 9.331e7, damping_ratio=DEFAULT_RUN.damping, friction_coefficient=0.1)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=DEFAULT_RUN.rpm)
    tracemalloc.start()
    model = ClearanceMachine.of(
        chain,
        MachineLayout("wheels", wheel, wheel, None, True),
        Tensioner(1e5, 5.0, 100.0),
        DEFAULT_RUN.pin_clearance_m,
    )
    h = mv.stable_step_s(model, 0.25, "euler")
    zr, zd, zdd = mv.cycle_nodes(cam, h, STEPS)
    n = model.arrays.dof_float.shape[0]
    rng = np.random.default_rng(2)
    q0, v0 = 1e-5 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n)
    start, start_cpu = time.perf_counter(), time.process_time()
    mv.integrate(model, zr, zd, zdd, h, q0, v0, out_every=STEPS)
    seconds, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return peak, seconds, cpu


def run(quick: bool) -> list[str]:
    """The table's lines (benchmarks/run.py)."""
    from dynamics.models.machine_damping import SINGLE_PRECISION_FACTORS_ABOVE_LINKS

    one(500)  # warm the numba cache
    one(SINGLE_PRECISION_FACTORS_ABOVE_LINKS + 1)  # and its single-precision factors' step
    lines = ["| N | peak memory | 400 steps (wall) | CPU |", "|---|---|---|---|"]
    for n in (500, 1000) if quick else (500, 1000, 2000, 4000, 10000):
        peak, seconds, cpu = one(n)
        lines.append(f"| {n} | {peak:.1f} MB | {seconds:.2f} s | {cpu:.2f} s |")
    return lines


if __name__ == "__main__":
    print("\n".join(run(quick=False)))
