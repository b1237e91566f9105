"""Cost growth of the dynamics with the number of links N, observed exponents fitted.

- default solver: simulate(method="exact", periodic steady state), one index cycle of the modified
  sine at 180 rpm, one-degree outputs, every link; dense 2N-state matrix exponential, O(N^3) time and
  O(N^2) memory, so it stops where a run takes about a minute (N = 1000);
- modal sweep engine (dynamics.response.sweep) at one speed and cam, all N modes (dense eigensolve, O(N^3));
- the same engine with the 400 lowest modes from sparse shift-invert Lanczos (about linear in N): the
  path that reaches N = 10,000, from N = 5000 (r <= N/10 for the sparse solver; nearer r = N/10, e.g.
  N = 4000, ARPACK converges slowly: 9.5 s measured). Its truncation error is checked against 800
  modes at the largest N.
Each point is a cold run (new model, caches empty), timed as this process's CPU time with BLAS on
one thread (on a shared machine wall time swung 20x between runs; CPU time is what the run costs),
best of 3 for runs under 0.5 s and of 2 for the modal engine's longer ones.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from dynamics.cams.program import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.reduction import DENSE_LINK_LIMIT, MODES_FOR_LONG_CHAINS, modes_to_keep
from dynamics.response.sweep import chain_modes, rpm_sweep
from dynamics.solvers import cache as solver_cache
from dynamics.solvers import simulate as simulate_module
from dynamics.solvers.simulate import SlackChainWarning, simulate
from verification.workprecision import observed_order

K_N_PER_M, M_KG = 9e7, 2.0
TRUNCATED_MODES = 400  # at N = 10,000: residual vibration and peak acceleration within 1e-4 of 800 modes


def best_of(run, cheap_s: float = 0.5, repeats: int = 3) -> float:
    """CPU time of run(); best of `repeats` when one run is cheaper than `cheap_s` (noise)."""
    times = []
    while True:
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
        if times[0] > cheap_s or len(times) >= repeats:
            return min(times)


def time_default(n: int) -> float:
    cam = CamProgram.indexing("modified-sine")
    t = cam.cycle_s * np.arange(91) / 90

    def run():  # cold: the model's matrices, exponentials and periodic-state LU all recomputed
        simulate_module._system.cache_clear()
        solver_cache.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SlackChainWarning)
            simulate(ChainModel(n, M_KG, K_N_PER_M), cam, t)

    return best_of(run)


def time_pipeline_path(n: int) -> float:
    """What the pipeline runs for a chain of n links: all link coordinates up to
    dynamics.models.reduction.DENSE_LINK_LIMIT, the lowest modes above it."""
    cam = CamProgram.indexing("modified-sine")
    t = cam.cycle_s * np.arange(91) / 90

    def run():
        simulate_module._system.cache_clear()
        solver_cache.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SlackChainWarning)
            simulate(ChainModel(n, M_KG, K_N_PER_M), cam, t, n_modes=modes_to_keep(n))

    return best_of(run)


def time_modal(n: int, n_modes: int | None) -> float:
    def run():
        rpm_sweep(ChainModel(n, M_KG, K_N_PER_M), "modified-sine", [180.0], n_modes=n_modes)

    return min(best_of(run), best_of(run))


def fit(ns, times, n_min=100) -> float:
    sel = [(n, t) for n, t in zip(ns, times) if n >= n_min]
    return observed_order([n for n, _ in sel], [t for _, t in sel])


def make(out_dir: Path, quick: bool) -> list[str]:
    default_ns = (10, 20, 50, 100, 200, 300) if quick else (10, 20, 50, 100, 200, 300, 500, 700, 1000)
    modal_ns = (10, 20, 50, 100, 200, 500, 1000) if quick else (10, 20, 50, 100, 200, 500, 1000, 2000, 3000)
    trunc_ns = (5000, 7000, 10000) if not quick else (5000, 7000)
    pipeline_ns = (500, 1000, 2000, 5000, 10000) if not quick else (500, 1000)
    curves = {
        "default: simulate(exact), periodic steady state, all links": (
            default_ns,
            [time_default(n) for n in default_ns],
        ),
        "modal sweep engine, all N modes (dense eigh)": (modal_ns, [time_modal(n, None) for n in modal_ns]),
        f"modal sweep engine, {TRUNCATED_MODES} lowest modes (sparse Lanczos)": (
            trunc_ns,
            [time_modal(n, TRUNCATED_MODES) for n in trunc_ns],
        ),
        f"pipeline path: simulate(exact) in {MODES_FOR_LONG_CHAINS} modes above {DENSE_LINK_LIMIT} links": (
            pipeline_ns,
            [time_pipeline_path(n) for n in pipeline_ns],
        ),
    }
    fig, ax = plt.subplots(figsize=(8.5, 6), dpi=100)
    lines = []
    for (label, (ns, ts)), marker in zip(curves.items(), "osD^"):
        p = fit(ns, ts)
        ax.loglog(ns, ts, marker=marker, label=f"{label}: time ~ N^{p:.2f}")
        lines.append(
            f"{label}: exponent {p:.2f} (fit over N >= 100); " + ", ".join(f"N={n}: {t:.3g} s" for n, t in zip(ns, ts))
        )
    n_big = trunc_ns[-1]
    model = ChainModel(n_big, M_KG, K_N_PER_M)
    r1 = rpm_sweep(model, "modified-sine", [180.0], modes=chain_modes(model, TRUNCATED_MODES))
    r2 = rpm_sweep(model, "modified-sine", [180.0], modes=chain_modes(model, 2 * TRUNCATED_MODES))
    rel = abs(r1.residual_vibration_m[0, 0] - r2.residual_vibration_m[0, 0]) / r2.residual_vibration_m[0, 0]
    rel_a = abs(r1.peak_acceleration_m_s2[0, 0] - r2.peak_acceleration_m_s2[0, 0]) / r2.peak_acceleration_m_s2[0, 0]
    lines.append(
        f"N={n_big}: {TRUNCATED_MODES} vs {2 * TRUNCATED_MODES} modes: residual vibration differs by "
        f"{rel:.2e}, peak acceleration by {rel_a:.2e} (relative)"
    )
    ax.set_xlabel("number of links N")
    ax.set_ylabel("CPU time (s), one thread, one cam, 180 rpm, cold")
    ax.set_title(
        "Cost growth with N (k = 9e7 N/m, m = 2 kg, modified sine 180 rpm, one index cycle, BLAS 1 thread)\n"
        f"dense exact stopped at N = {default_ns[-1]}; the pipeline's modal path and the sweep engine reach N = {n_big}\n"
        f"(there {TRUNCATED_MODES} vs {2 * TRUNCATED_MODES} modes: residual vibration {rel:.1e}, "
        f"peak acceleration {rel_a:.1e} relative)",
        fontsize=9,
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = out_dir / "dynamics_cost_growth.png"
    fig.savefig(path)
    plt.close(fig)
    return lines + [f"wrote {path}"]
