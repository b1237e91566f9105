"""A long chain's settle (issue #24): the steady state searched at SEARCH_SAFETY carried to the default
safety's fixed point by defect correction with coarse cycles (today's,
machine_shooting.defect_corrected_periodic_state) beside the accelerated search at the default
safety from the same coarse state (the settle before it), in one process.

    python benchmarks/bench_long_settle.py --links 2000 [--links 10000 ...]

The scenario is bench_long_wheels' (default wheels and link, 0.094 mm free play, 180 rpm modified
sine), run by dynamics.scene.simulate_scene as the pipeline runs it (the defect correction taken
wherever the settle is searched, SETTLE_SEARCH_ABOVE_DECAY), twice: the first run steps the
coarse search once and both settles from its end state, and its window starts from the fine search's
state; the second run's settle returns the defect-corrected state (not stepped again), and its window
starts there (with --tight a third run's window starts from the fine step's fixed point searched on
from there to that tolerance: the reference). Printed per N: the slowest mode's decay per cycle, the search's tolerance, the coarse
search's cycles and CPU seconds, each settle's coarse and fine cycles and CPU seconds (the process's,
time.process_time), the residual each was accepted with, and the worst relative difference of the 20
station metrics (bench_long_wheels' KEYS, as the pipeline has them: the kernel's peaks and RMS over
every step) between the two windows, with the load average.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.bench_long_chain import KEYS  # noqa: E402 (after sys.path)
from benchmarks.bench_long_wheels import long_scene  # noqa: E402


def _settles(links: int, tight: float | None) -> dict:
    """Both settles at `links` links and the station metrics of the windows they start; with `tight`,
    a third window from the fine step's fixed point searched on from the defect-corrected state to
    that tolerance (the reference both are compared with)."""
    from dynamics import machine_scene
    from dynamics.machine_scene import every_step_metrics
    from dynamics.response.metrics import link_metrics
    from dynamics.scene import simulate_scene
    from dynamics.solvers import machine_shooting, shooting
    from stages.machine import machine_parts

    chain, scene, cam, t = long_scene(links)
    cols = [link - 1 for link in machine_parts(scene, chain).stations.values()]
    real = machine_shooting.defect_corrected_periodic_state
    out: dict = {}
    runs: list = []

    def both(model, cam, coarse, fine, q0, v0, *, tol, max_cycles, predictor):
        n = np.asarray(q0).size
        if "tight" in out:
            return out["tight"]
        if "new" in out:
            new = out["new"]
            if tight is None:
                return new
            q, v, cycles, residual, found, run = machine_shooting.relabelled_periodic_state(
                model, cam, *fine, new.q0, new.v0, tol=tight, max_cycles=80, predictor=predictor
            )
            out["tight"] = _as_state(q, v, found, cycles, residual, new, run)
            out["tight_search"] = (cycles, residual, found)
            return new
        log = []
        start = time.process_time()
        new = real(
            model,
            cam,
            coarse,
            fine,
            q0,
            v0,
            tol=tol,
            max_cycles=max_cycles,
            predictor=predictor,
            on_cycle=lambda r, end, run, step: log.append(time.process_time()),
        )
        total = time.process_time() - start
        coarse_cpu = log[new.coarse.periods - 1] - start
        start = time.process_time()
        q, v, cycles, residual, found, run = machine_shooting.relabelled_periodic_state(
            model,
            cam,
            *fine,
            new.coarse.state[:n],
            new.coarse.state[n:],
            tol=tol,
            max_cycles=max_cycles - new.coarse.periods,
            predictor=predictor,
        )
        old_cpu = time.process_time() - start
        settled = new.settled
        out.update(
            new=new,
            decay=machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s),
            tol=tol,
            coarse=(new.coarse.periods, coarse_cpu),
            defect=(settled.coarse_periods, settled.fine_periods, total - coarse_cpu, settled.search.residual),
            search=(cycles, old_cpu, residual, found),
        )
        return _as_state(q, v, found, cycles, residual, new, run)

    def _as_state(q, v, found, cycles, residual, new, run):
        search = shooting.FixedPointSearch(np.concatenate([q, v]), found, cycles, residual, [], None)
        return machine_shooting.DefectCorrectedState(
            q, v, new.coarse, shooting.DefectCorrectedSearch(search, 0, cycles), run
        )

    machine_shooting.defect_corrected_periodic_state = both
    # both settles wherever the settle is searched, also below SETTLE_DEFECT_CORRECTED_ABOVE_DECAY
    machine_scene.SETTLE_DEFECT_CORRECTED_ABOVE_DECAY = machine_scene.SETTLE_SEARCH_ABOVE_DECAY
    try:
        for _ in range(2 if tight is None else 3):
            r, contact = simulate_scene(scene, chain, cam, t, links=cols)
            lm = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, cam.dwell_mask(t))
            sampled = [[float(getattr(lm, k)[i]) for k in KEYS] for i in range(len(cols))]
            # the pipeline's: the kernel's peaks and RMS over every step where it has them
            every_step = every_step_metrics(r)
            runs.append(
                np.array(
                    [
                        [every_step[name].get(k, sampled[i][j]) for j, k in enumerate(KEYS)]
                        for i, name in enumerate(every_step)
                    ]
                )
            )
    finally:
        machine_shooting.defect_corrected_periodic_state = real

    def worst(values, reference):
        rel = np.abs(values - reference) / np.maximum(np.abs(reference), 1e-300)
        station, metric = np.unravel_index(int(np.argmax(rel)), rel.shape)
        return float(rel.max()), KEYS[metric], int(cols[station]) + 1

    out["worst"] = worst(runs[1], runs[0])
    if tight is not None:
        out["from_tight"] = (worst(runs[0], runs[2]), worst(runs[1], runs[2]))
    return out


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description="a long chain's settle: defect correction beside the fine search")
    parser.add_argument("--links", type=int, action="append", required=True)
    parser.add_argument("--tight", type=float, default=None, help="also a reference searched on to this tolerance")
    args = parser.parse_args(argv)
    for links in args.links:
        load = os.getloadavg()[0]
        res = _settles(links, args.tight)
        if "new" not in res:
            print(f"{links} links: the settle is not searched here (one plain cycle)")
            continue
        cc, ccpu = res["coarse"]
        dc, df, dcpu, dres = res["defect"]
        sc, scpu, sres, sfound = res["search"]
        worst, key, link = res["worst"]
        print(
            f"{links} links (load {load:.1f}): rho {res['decay']:.3f}, tol {res['tol']:.2g}; coarse search {cc} cycles "
            f"{ccpu:.1f} s; settle by defect correction {dc} coarse + {df} fine cycles {dcpu:.1f} s (residual "
            f"{dres:.2g}); by the fine search {sc} fine cycles {scpu:.1f} s (residual {sres:.2g}, found {sfound}); "
            f"station metrics worst difference {worst:.2e} ({key}, link {link})",
            flush=True,
        )
        if args.tight is not None:
            (old_worst, old_key, old_link), (new_worst, new_key, new_link) = res["from_tight"]
            cycles, residual, found = res["tight_search"]
            print(
                f"  reference: the fine search on to {args.tight:g} ({cycles} cycles, residual {residual:.2g}, "
                f"found {found}): the fine search's window {old_worst:.2e} ({old_key}, link {old_link}) from it, "
                f"the defect correction's {new_worst:.2e} ({new_key}, link {new_link})",
                flush=True,
            )


if __name__ == "__main__":
    main(sys.argv[1:])
