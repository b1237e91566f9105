"""Where a long chain's steady-state searches spend their index cycles (issue #24): the residual per
cycle of the linear machine's search and of the clearance machine's search from several starts.

    python benchmarks/bench_long_search.py --links 10000 [--linear-starts 0,3,6] [--own-starts 24]
    python benchmarks/run.py --only long_search          # 1,000 and 2,000 links (--quick: 1,000)

The scenario is bench_long_wheels' (default wheels and link, 0.094 mm free play, 180 rpm modified
sine). Both searches run as dynamics.machine_scene.simulate_machine runs them on a long chain: at
SEARCH_SAFETY of the stability limit, Anderson-accelerated (machine_shooting.relabelled_periodic_state),
the linear machine from rest to CHOICE_TOL, the clearance machine to long_search_tol. Printed: the
linear machine's search cycle by cycle (its change per cycle, the cycle's minimum tension, and the
bound 2 k max|q| r / (1 - rho) on that minimum tension's distance from the steady state's: a span's
stretch error is at most twice the largest displacement error, a start whose cycle changes it by r is
within about r / (1 - rho) of the fixed point, rho the slowest mode's decay per cycle), and that
minimum's span stretch (T - P) / k with where it is (span, output); then the
clearance machine's search from rest, from the linear machine's end state after k of its cycles
(`--linear-starts`, 0: rest), from its converged state (today's start), and afresh from the
clearance search's own end state after j of its cycles (`--own-starts`: what a start of that
quality, from any cheaper model, would leave to search). CPU seconds are the process's.

The minimum tension is the linear machine's elastic span force P + k e in N (printed in kN), the least
over every span and step of the cycle: the figure the model choice takes (and the preload for full
contact, P - T). It is only a tension while the stretch e is small against the pitch. At 1,000 links
it is about -50 kN (e about -0.58 mm); at 10,000 links about -6,770 kN, one span (the middle one, the
idler's side) at the cycle's first output, right after the seat change, compressed by 75 mm, two
thirds of a pitch, while the strands lag the cam by up to 0.34 m (their stretch under the preload
alone is 0.12 m): no physical force, the linear model outside its small-stretch assumption there.
The stretch column shows it.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.bench_long_wheels import long_scene  # noqa: E402 (after sys.path)

QUICK_SIZES = (1000,)
SIZES = (1000, 2000)
LINEAR_STARTS = (0, 1, 3)
MAX_CYCLES = 80


@dataclass
class SearchLog:
    """One search, cycle by cycle."""

    residuals: list = field(default_factory=list)  # change per cycle (the acceptance test's measure)
    min_tensions_N: list = field(default_factory=list)
    min_tension_where: list = field(default_factory=list)  # (span, output) of the outputs' least span force
    largest_q_m: list = field(default_factory=list)  # the cycle's largest |q| (the residual's scale)
    ends: list = field(default_factory=list)  # (q, q') after each cycle's seat change
    cycles: int = 0
    found: bool = False
    cpu_s: float = 0.0

    def record(self, residual, end, run) -> None:
        self.residuals.append(residual)
        self.min_tensions_N.append(float(run.min_tension_N))
        output, span = np.unravel_index(np.argmin(run.tension_N), run.tension_N.shape)
        self.min_tension_where.append((int(span), int(output)))
        self.largest_q_m.append(float(np.max(np.abs(run.q))))
        self.ends.append((end[0].copy(), end[1].copy()))


def scenario(links: int):
    """(clearance machine, cam, output times) of bench_long_wheels' scenario at `links` links."""
    from dynamics.machine_scene import machine_model

    chain, scene, cam, t = long_scene(links)
    return machine_model(scene, chain), cam, t


def search(model, cam, t, state, tol: float, max_cycles: int = MAX_CYCLES) -> SearchLog:
    """The relabelled steady state's search from `state` as a long chain's default run takes it (at
    SEARCH_SAFETY, accelerated), logged."""
    from dynamics.machine_scene import SEARCH_SAFETY
    from dynamics.solvers import clearance_verlet as verlet
    from dynamics.solvers import machine_shooting
    from dynamics.solvers import machine_verlet as mv

    h_out = float(t[1] - t[0])
    per_cycle = int(round(cam.period_s / h_out))
    pred = verlet.default_predictor(model)
    sub = mv.substeps_for(model, h_out, SEARCH_SAFETY[model.span_damping], pred)
    log = SearchLog()
    start = time.process_time()
    _, _, log.cycles, _, log.found, _ = machine_shooting.relabelled_periodic_state(
        model,
        cam,
        h_out / sub,
        per_cycle * sub,
        *state,
        tol=tol,
        max_cycles=max_cycles,
        predictor=pred,
        on_cycle=log.record,
    )
    log.cpu_s = time.process_time() - start
    return log


def min_tension_bounds_N(model, cam, log: SearchLog) -> np.ndarray:
    """Per cycle of the linear machine's search: 2 k max|q| r / (1 - rho) (module docstring)."""
    from dynamics.solvers import machine_shooting

    rho = machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s)
    k = model.chain.stiffness_N_per_m
    return 2.0 * k * np.array(log.largest_q_m) * np.array(log.residuals) / (1.0 - rho)


def _residuals(log: SearchLog) -> str:
    return ", ".join(f"{r:.2g}" for r in log.residuals)


def measure(links: int, linear_starts=LINEAR_STARTS, own_starts=()) -> list[str]:
    from dynamics.machine_scene import CHOICE_TOL, linear_machine, long_search_tol

    model, cam, t = scenario(links)
    linear = linear_machine(model)
    rest = (np.zeros(model.n_state), np.zeros(model.n_state))
    lin = search(linear, cam, t, rest, CHOICE_TOL)
    bounds = min_tension_bounds_N(linear, cam, lin)
    lines = [
        f"{links} links: the linear machine's search from rest to {CHOICE_TOL:g}: {lin.cycles} cycles "
        f"({'found' if lin.found else 'NOT found'}), {lin.cpu_s:.1f} s of CPU",
        "",
        "| cycle | change per cycle | minimum tension | its bound 2 k max|q| r / (1 - rho) | its stretch (T - P) / k "
        "| where (span, output) |",
        "|---|---|---|---|---|---|",
    ]
    chain, pitch_m = linear.chain, linear.machine.sprocket.pitch_m
    logged = zip(lin.residuals, lin.min_tensions_N, bounds, lin.min_tension_where)
    for i, (r, tension, bound, (span, output)) in enumerate(logged, 1):
        stretch_m = (tension - chain.preload_N) / chain.stiffness_N_per_m
        lines.append(
            f"| {i} | {r:.2g} | {tension / 1e3:.1f} kN | {bound / 1e3:.3g} kN | {stretch_m * 1e3:.3g} mm "
            f"({stretch_m / pitch_m:.2g} pitch) | {span}, {output} |"
        )
    tol = long_search_tol(model, cam, 1e-6)
    starts = [
        (f"the linear machine after {k} cycles" if k else "rest", lin.ends[k - 1] if k else rest)
        for k in linear_starts
        if k <= lin.cycles
    ]
    starts.append((f"the linear machine's steady state ({lin.cycles} cycles, today's start)", lin.ends[-1]))
    lines += [
        "",
        f"The clearance machine's search to {tol:.2g}:",
        "",
        "| start | cycles | CPU | change per cycle |",
        "|---|---|---|---|",
    ]
    today = None
    for name, state in starts:
        log = search(model, cam, t, state, tol)
        today = log
        lines.append(
            f"| {name} | {log.cycles}{'' if log.found else ' (NOT found)'} | {log.cpu_s:.1f} s | {_residuals(log)} |"
        )
    for j in own_starts:
        if j <= today.cycles:
            log = search(model, cam, t, today.ends[j - 1], tol)
            lines.append(
                f"| afresh from that search's cycle {j} (change per cycle {today.residuals[j - 1]:.2g}) | {log.cycles}"
                f"{'' if log.found else ' (NOT found)'} | {log.cpu_s:.1f} s | {_residuals(log)} |"
            )
    return lines


def run(quick: bool) -> list[str]:
    lines = []
    for links in QUICK_SIZES if quick else SIZES:
        lines += measure(links, own_starts=(5,)) + [""]
    return lines


def _counts(text: str) -> tuple[int, ...]:
    return tuple(int(x) for x in text.split(",") if x.strip())


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description="a long chain's steady-state searches, cycle by cycle")
    parser.add_argument("--links", type=int, required=True)
    parser.add_argument(
        "--linear-starts", type=_counts, default=LINEAR_STARTS, help="k: the linear machine after k cycles (0: rest)"
    )
    parser.add_argument("--own-starts", type=_counts, default=(), help="j: afresh from the clearance search's cycle j")
    args = parser.parse_args(argv)
    print("\n".join(measure(args.links, args.linear_starts, args.own_starts)))


if __name__ == "__main__":
    main(sys.argv[1:])
