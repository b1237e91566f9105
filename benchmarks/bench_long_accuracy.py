"""The long chain's default run against tight runs, one ingredient at a time (issue #24, helper acc2k).

    python benchmarks/bench_long_accuracy.py --links 2000                       # every variant
    python benchmarks/bench_long_accuracy.py --links 1000 --variants default tight-5 tight-10
    python benchmarks/bench_long_accuracy.py --links 10000 --reference search-tol --variants default
    python benchmarks/bench_long_accuracy.py --links 4000 --reference tight-5 --variants default --keep DIR

The scenario is benchmarks/bench_long_wheels.py's (default wheels and link, 0.094 mm free play, 180 rpm
modified sine, the pipeline's output grid, `--model auto`, steady state). Each variant runs in its own
process, one after the other (one heavy job at a time). The tight runs are given their step (the
"converged reference" path of dynamics.machine_scene.simulate_machine: search, settle and window all
at it): `tight-5` at the default safety / 5 (finer than the window, at / 3.5), `tight-10` at / 10, all
searched to 1e-8 (in up to TIGHT_MAX_CYCLES) with each mode's damping ratio to 1e-7; `tight-3.5` at
the window's own step (/ 3.5), its fixed point. The other variants are the default run with
ONE ingredient at its tight value (VARIANTS): the search's tolerance (a long chain's coarse search and
the search on at the default safety that settles it), the window's step, the damping's tolerance, the
coarse search's step, the factors' precision; `all-three` the first three together. The settle's
variants (one or more plain settling cycles, as long chains settled before the search took it over)
were measured with this script at 41d9ca3. Reported per variant against the reference: the worst
relative difference of the 20 station metrics as the pipeline has them (stages/chain.py: the kernel's
over every step, the RMS of x, v, a over time, max |a| and the residual vibration its peaks) and as
bench_long_wheels.py computes them (every metric from the output samples), which metric and
station, the CPU seconds and the search's index cycles (and its last change per cycle); then per metric the worst over the stations. `--reference` may also be a variant: where a
tight run takes hours (10,000 links), how far one tight ingredient moves the default run.
"""

from __future__ import annotations

import argparse
import functools
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script in a subprocess
    sys.path.insert(0, str(ROOT))

KEYS = ("rms_displacement_m", "rms_velocity_m_s", "rms_acceleration_m_s2", "max_abs_acceleration_m_s2")
KEYS += ("residual_vibration_m",)
# a tight run: its safety as a fraction of the default safety, the search's tolerance, the damping's
TIGHT = {"tight-3.5": 3.5, "tight-5": 5.0, "tight-10": 10.0}
TIGHT_TOL = 1e-8
TIGHT_DAMPING_TOLERANCE = 1e-7
# a tight run's search budget in index cycles: at 3,000 links the search at safety / 5 had not reached
# its tolerance after the default 60 (its last change per cycle 2.2e-3), and its state is no reference
TIGHT_MAX_CYCLES = 300
# the default run with one ingredient at its tight value
VARIANTS = {
    "default": {},
    "search-tol": {"search_tol": TIGHT_TOL},
    "window-5": {"window_refinement": 5.0},
    "damping-1e-7": {"damping_tol": TIGHT_DAMPING_TOLERANCE},
    "search-at-default-safety": {"search_safety": 0.31},
    "single-factors": {"single": True},
    # the search's tolerance at fixed values between the default's (long_search_tol) and the tight one
    "search-tol-1e-4": {"search_tol": 1e-4},
    "search-tol-3e-5": {"search_tol": 3e-5},
    "search-tol-1e-5": {"search_tol": 1e-5},
    # long_search_tol's state-error bound at every rho (as before LONG_SEARCH_STATE_ERROR_UP_TO_DECAY)
    "state-error-bound-everywhere": {"state_error_up_to_decay": 1.0},
    # above rho 0.92 (dynamics.machine_scene): the state-error bound of the search's tolerance
    # (LONG_SEARCH_SLACK_STATE_ERROR) looser and tighter than the default's, the settle at the default
    # safety instead of the window's step, the damping's ratios to the previous 1e-5 or to 1e-6
    "slack-state-error-1e-3": {"slack_state_error": 1e-3},
    "slack-state-error-2.5e-4": {"slack_state_error": 2.5e-4},
    "settle-at-default-safety": {"settle_at_window_step_above_decay": 1.0},
    "damping-1e-5": {"damping_tol": 1e-5},
    "damping-1e-6": {"damping_tol": 1e-6},
    # the default run as it was before those three (search to LONG_SEARCH_TOL above rho 0.92)
    "before-slack-rule": {
        "damping_tol": 1e-5,
        "settle_at_window_step_above_decay": 1.0,
        "slack_state_error": 0.0,
        "tol_floor": 1e-4,
    },
    "all-three": {"window_refinement": 5.0, "damping_tol": TIGHT_DAMPING_TOLERANCE, "search_tol": TIGHT_TOL},
}


def _apply(knobs: dict) -> None:
    """Set the default run's ingredients named in `knobs` (this process only)."""
    from dynamics import machine_scene as ms
    from dynamics.models import clearance_machine, machine_damping

    if "window_refinement" in knobs:
        ms.WINDOW_REFINEMENT["global"] = knobs["window_refinement"]
    if "search_safety" in knobs:
        ms.SEARCH_SAFETY["global"] = knobs["search_safety"]
    if "search_tol" in knobs:
        ms.long_search_tol = lambda model, cam, tol: knobs["search_tol"]
    if "damping_tol" in knobs:
        clearance_machine.of_machine = functools.partial(machine_damping.of_machine, tolerance=knobs["damping_tol"])
    if "state_error_up_to_decay" in knobs:
        ms.LONG_SEARCH_STATE_ERROR_UP_TO_DECAY = knobs["state_error_up_to_decay"]
    if "slack_state_error" in knobs:
        ms.LONG_SEARCH_SLACK_STATE_ERROR = knobs["slack_state_error"]
    if "tol_floor" in knobs:
        ms.LONG_SEARCH_TOL_FLOOR = knobs["tol_floor"]
    if "settle_at_window_step_above_decay" in knobs:
        ms.SETTLE_AT_WINDOW_STEP_ABOVE_DECAY = knobs["settle_at_window_step_above_decay"]
    if knobs.get("single"):
        machine_damping.SINGLE_PRECISION_FACTORS_ABOVE_LINKS = 0


def _scenario(n: int, variant: str) -> dict:
    """One variant in this process: the 20 station metrics both ways, CPU seconds, index cycles."""
    from benchmarks.bench_long_wheels import long_scene
    from dynamics import machine_scene as ms
    from dynamics.response.metrics import link_metrics
    from dynamics.solvers import clearance_verlet as verlet
    from stages.machine import machine_parts

    _apply(VARIANTS.get(variant, {}))
    if variant in TIGHT:
        _apply({"damping_tol": TIGHT_DAMPING_TOLERANCE})
    chain, scene, cam, t = long_scene(n)
    cols = [link - 1 for link in machine_parts(scene, chain).stations.values()]
    model = ms.machine_model(scene, chain)
    options = {}
    if variant in TIGHT:
        pred = verlet.default_predictor(model)
        safety = verlet.default_safety(model, pred) / TIGHT[variant]
        options = {"safety": safety, "tol": TIGHT_TOL, "max_cycles": TIGHT_MAX_CYCLES}
    start = time.process_time()
    r, contact = ms.simulate_machine(model, cam, t, choice=scene.model, links=cols, **options)
    cpu = time.process_time() - start
    lm = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, cam.dwell_mask(t))
    sampled = [[float(getattr(lm, k)[i]) for k in KEYS] for i in range(len(cols))]
    peaks = ms.every_step_metrics(r)
    pipeline = [[peaks[name].get(k, sampled[i][j]) for j, k in enumerate(KEYS)] for i, name in enumerate(peaks)]
    return {
        "variant": variant,
        "cpu_s": cpu,
        "cycles": contact.steady_state.cycles,
        "found": contact.steady_state.found,
        "residual": contact.steady_state.residual,
        "steps_per_output": contact.steps_per_output,
        "stations": list(peaks),
        "sampled": sampled,
        "pipeline": pipeline,
    }


def _in_subprocess(n: int, variant: str, keep: Path | None = None) -> dict:
    """One variant's run in its own process; with `keep`, its result is stored there as
    <links>-<variant>.json and read back instead of rerun (the tight runs take many minutes)."""
    kept = keep / f"{n}-{variant}.json" if keep is not None else None
    if kept is not None and kept.exists():
        return json.loads(kept.read_text())
    args = [sys.executable, __file__, "--one", str(n), variant]
    out = subprocess.run(args, capture_output=True, text=True, check=True, cwd=ROOT)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if kept is not None:
        keep.mkdir(parents=True, exist_ok=True)
        kept.write_text(json.dumps(result))
    return result


def worst_difference(values, reference) -> tuple[float, int, int]:
    """(the worst relative difference of the station metrics, its station index, its metric index)."""
    a, b = np.asarray(values, dtype=float), np.asarray(reference, dtype=float)
    rel = np.abs(a - b) / np.abs(b)
    station, metric = np.unravel_index(int(np.argmax(rel)), rel.shape)
    return float(rel.max()), int(station), int(metric)


def table(n: int, variants: list[str], reference: str, keep: Path | None = None) -> list[str]:
    runs = {v: _in_subprocess(n, v, keep) for v in [reference, *[v for v in variants if v != reference]]}
    ref = runs[reference]
    if reference in TIGHT:
        what = f"safety / {TIGHT[reference]:g}, tol {TIGHT_TOL:g}, damping {TIGHT_DAMPING_TOLERANCE:g}"
    else:
        what = "a variant of the default run, no tight run"
    lines = [
        f"{n} links, against {reference} ({what})",
        "",
        "| variant | pipeline's station metrics: worst | sampled metrics: worst | CPU | cycles (accepted change) | steps/sample |",
        "|---|---|---|---|---|---|",
    ]
    for v, res in runs.items():
        cells = []
        for kind in ("pipeline", "sampled"):
            worst, station, metric = worst_difference(res[kind], ref[kind])
            cells.append(f"{worst:.2e} ({KEYS[metric]}, {res['stations'][station]})")
        accepted = res.get("residual", float("nan"))  # (runs stored before it was recorded have none)
        lines.append(
            f"| {v} | {cells[0]} | {cells[1]} | {res['cpu_s']:.1f} s | {res['cycles']} ({accepted:.1e}) "
            f"| {res['steps_per_output']} |"
        )
    lines += ["", "pipeline's station metrics, worst over the stations per metric:", ""]
    lines += ["| variant | " + " | ".join(KEYS) + " |", "|---|" + "---|" * len(KEYS)]
    for v, res in runs.items():
        rel = np.abs(np.subtract(res["pipeline"], ref["pipeline"])) / np.abs(ref["pipeline"])
        lines.append(f"| {v} | " + " | ".join(f"{x:.2e}" for x in rel.max(axis=0)) + " |")
    return lines


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description="the long chain's default run against tight runs")
    parser.add_argument("--links", type=int, default=2000)
    parser.add_argument("--reference", default="tight-10", choices=[*TIGHT, *VARIANTS])
    parser.add_argument("--variants", nargs="*", default=[*TIGHT, *VARIANTS])
    parser.add_argument("--keep", type=Path, help="store each run's result in this directory and reuse it")
    args = parser.parse_args(argv)
    unknown = [v for v in args.variants if v not in VARIANTS and v not in TIGHT]
    if unknown:
        raise SystemExit(f"--variants: unknown {', '.join(unknown)}; expected some of {', '.join([*TIGHT, *VARIANTS])}")
    print("\n".join(table(args.links, args.variants, args.reference, args.keep)))


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--one":
        print(json.dumps(_scenario(int(sys.argv[2]), sys.argv[3])))
    else:
        main(sys.argv[1:])
