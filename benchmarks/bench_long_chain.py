"""Long clearance chains (issue 24): the global damping law's O(N) form at N = 100 .. 10,000.

    python benchmarks/run.py --only long_chain

Each N: the default scene's link (aluminium FEA k and lumped mass, friction 0.35), 0.094 mm free play,
180 rpm modified sine, the pipeline's output grid (180 degrees at 4 per degree), periodic steady
state, `simulate_chain` with the model chosen automatically and the linear chain solved as the
pipeline does (its 400 lowest modes above 400 links). Time: wall seconds of one scenario (numba
cache warm), the linear part included; memory: the peak of Python-tracked allocations (tracemalloc:
numpy arrays) during it. Check: where the dense damping runs (N <= 400), the same run with the dense
modal C, and the worst relative difference of the 20 station metrics.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain
from dynamics.models.reduction import DENSE_LINK_LIMIT, modes_to_keep
from dynamics.response.metrics import link_metrics, station_links
from dynamics.scene import simulate_chain

KEYS = (
    "rms_displacement_m",
    "rms_velocity_m_s",
    "rms_acceleration_m_s2",
    "max_abs_acceleration_m_s2",
    "residual_vibration_m",
)
SIZES = (100, 400, 1000, 2000, 10000)
# Above this the steady-state search (about 60 cam cycles at N = 1000) takes too long for a benchmark
# run: the window alone is timed (two cam cycles from the linear chain's periodic state), and the
# time per cam cycle printed, from which a steady-state run's time follows (cycles x that).
STEADY_STATE_UP_TO = 2000
TARGETS_S = {1000: 2.0, 10000: 20.0}


def _run(n: int, damping_tolerance=None, steady_state=True):
    chain = ChainModel(n_links=n, link_mass_kg=2.03, stiffness_N_per_m=9.0092e7, friction_coefficient=0.35)
    model = ClearanceChain(chain, 94e-6, damping_tolerance=damping_tolerance)
    t = np.arange(721) / 4 / (6 * 180.0)
    cam = CamProgram.indexing("modified-sine", pitch_m=0.1125, rpm=180.0)
    cols = [link - 1 for link in station_links(n).values()]
    tracemalloc.start()
    start = time.perf_counter()
    r, contact = simulate_chain(model, cam, t, n_modes=modes_to_keep(n), links=cols, steady_state=steady_state)
    wall = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    lm = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, cam.dwell_mask(t))
    values = np.array([[getattr(lm, k)[i] for k in KEYS] for i in range(len(cols))])
    return wall, peak, contact, values


def run(quick: bool) -> list[str]:
    sizes = SIZES[:3] if quick else SIZES
    _run(40)  # compile / load the numba cache
    _run(40, 1e-4)
    lines = [
        "Long clearance chains, one scenario each (default link, 0.094 mm, 180 rpm, steady state); the "
        "global damping law in its O(N) form above 400 links (dynamics/models/reduced_damping.py)",
        "",
        "| N | model | damping form | time (whole scenario) | peak memory | steady state | steps/sample | "
        "check vs dense C |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for n in sizes:
        steady = n <= STEADY_STATE_UP_TO
        wall, peak, contact, values = _run(n, steady_state=steady)
        form = "O(N), 1e-4" if n > DENSE_LINK_LIMIT else "dense"
        check = "-"
        if n <= DENSE_LINK_LIMIT:
            _, _, _, reduced = _run(n, 1e-4)
            check = f"O(N) form: worst station metric {np.max(np.abs(reduced - values) / np.abs(values)):.1e}"
        ss = contact.steady_state
        target = TARGETS_S.get(n)
        cycles = (ss.cycles if ss else 0) + 2  # the window is two cam cycles
        mark = "" if target is None else f" (target {target:g} s: {'met' if wall <= target else 'NOT met'})"
        state = (
            f"{'found' if ss.found else 'NOT found'} after {ss.cycles} cycles"
            if steady
            else "not searched (window only)"
        )
        lines.append(
            f"| {n} | {contact.model} | {form} | {wall:.2f} s{mark}, {wall / cycles:.2f} s per cam cycle | "
            f"{peak / 1e6:.0f} MB | {state} | {contact.steps_per_output} | {check} |"
        )
    return lines


if __name__ == "__main__":
    print("\n".join(run(quick=False)))
