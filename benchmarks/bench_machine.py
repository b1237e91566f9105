"""The clearance chain on its wheels (issue #22): one window's cost and accuracy, and the pipeline's
dynamics stage with the machine.

    python benchmarks/run.py --only machine

1. One 85-link, 180-degree window (two index cycles, 4 samples per degree) of the clearance machine
   from rest: the default layout (12-tooth sprocket and idler wheel, six links seated on each,
   steel-disc inertia, the drive's default compliance, polygonal feed), aluminium, modified sine,
   180 rpm, 0.094 mm free play, global damping. Station metrics (RMS x, v, a, max |a|, residual
   vibration at the machine's four stations; the two peaks over every step, the kernel's station peaks)
   at the default step (ab2 at 0.31 of its limit) and at
   every finer number of steps per sample up to twice it, against the same integrator at 1/16 of the default
   step; the time is the median CPU (thread) time of the repeats, each repeat one process per tree
   (machine_window_worker.py); the worst metric names the metric and
   station that set the error. The target row is the fewest steps per sample
   from which every finer one holds 1e-3 (the window runs from rest: the default run's two-level step does not apply).
   With BENCH_MACHINE_OLD_TREE=<a checkout of older code> (e.g. `git worktree add --detach /tmp/old
   main`; its benchmarks/bench_machine.py must have `_window_run`, as since 13f2a75) that tree's window
   runs too, each tree in a process of its own with only its own tree on the path (its own helpers and
   compiled step, whatever their signatures), the processes alternating (new, old, new, old, ...).
2. The impact statistics (closing speeds, approach energy, force spike) of the default run on wheels
   (steady state, default step) against the same run at 16x the steps: modified sine and cycloidal,
   both materials (modified sine, aluminium and titanium with --quick).
3. The pipeline's dynamics stage as the default run will run it on wheels: 2 materials x 5 cams,
   85 links, relabelled periodic steady state, model chosen automatically (the clearance machine on
   this scene); beside it, in the same run, today's single-link drive (dynamics.scene.simulate_chain).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.defaults import DEFAULT_RUN, MATERIALS, PITCH_M
from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import DEFAULT_PIN_CLEARANCE_M
from dynamics.models.layout import MachineLayout
from dynamics.scene import Scene, simulate_scene
from dynamics.solvers import machine_verlet as mv
from stages.machine import machine_layout

CAMS = ("modified-sine", "modified-trapezoid", "cycloidal", "poly-345", "poly-4567")
RPM, N_LINKS = DEFAULT_RUN.rpm, DEFAULT_RUN.links
TARGET_WINDOW_S, TARGET_STAGE_S = 0.020, 3.0
ROOT = Path(__file__).resolve().parents[1]
WORKER = Path(__file__).resolve().parent / "machine_window_worker.py"


def layout() -> MachineLayout:
    """The default run's machine on its wheels (stages.machine.machine_layout)."""
    return machine_layout(DEFAULT_RUN, PITCH_M)


def _chain(material: str) -> ChainModel:
    k, m = MATERIALS[material]
    return ChainModel(n_links=N_LINKS, link_mass_kg=m, stiffness_N_per_m=k)


def _window_times() -> np.ndarray:
    return np.arange(721) / 4 / (6 * RPM)


METRIC_NAMES = ("RMS x", "RMS v", "RMS a", "max |a|", "residual vibration")


def _station_metrics(model, cam, t, y, v, a, step_peaks=None) -> np.ndarray:
    """RMS x, v, a, max |a| over the window and max |x - z| over the dwell at the four stations; the
    two peaks the kernel's over every step (`step_peaks`, machine_verlet.PEAK_METRICS per station)
    where it tracks them, else the output samples'."""
    dwell = cam.dwell_mask(t)
    dof = model.topology.link_dof()[list(model.machine.stations().values())]
    out = []
    for i, d in enumerate(dof):
        out += [
            np.sqrt(np.mean(y[:, d] ** 2)),
            np.sqrt(np.mean(v[:, d] ** 2)),
            np.sqrt(np.mean(a[:, d] ** 2)),
            np.max(np.abs(a[:, d])) if step_peaks is None else step_peaks[i, 0],
            np.max(np.abs(y[dwell, d])) if step_peaks is None else step_peaks[i, 4],
        ]
    return np.array(out)


def _window_run(model, cam, t, sub):
    """Two index cycles from rest at `sub` steps per output sample, the seat change between them (the
    window ends at the second cycle's end: no seat change after it), with the kernel's station peaks over
    every step. Returns (CPU seconds of this thread, station metrics)."""
    start = time.thread_time()
    h = (t[1] - t[0]) / sub
    per_cycle = (t.size - 1) // 2
    zr, zd, zdd = mv.cycle_nodes(cam, h, per_cycle * sub)
    q = v = np.zeros(model.topology.n_dof)
    ys, vs, accs = [], [], []
    since = h * np.arange(zd.size)  # every node of both cycles is in the window
    stations = model.topology.link_dof()[list(model.machine.stations().values())]
    flags = [mv.IN_WINDOW | np.where(cam.dwell_mask(c * cam.period_s + since), mv.IN_DWELL, 0) for c in (0, 1)]
    step_peaks = []
    for cycle in range(2):
        run = mv.integrate(
            model, zr, zd, zdd, h, q, v, out_every=sub, predictor="ab2", stations=stations, node_flags=flags[cycle]
        )
        step_peaks.append(run.station_peaks)
        take = slice(0, per_cycle + (cycle == 1))
        ys.append(run.q[take])
        vs.append(run.v[take])
        accs.append(run.a[take] + zdd[::sub][take, None] * model.arrays.dof_float[:, 1])
        if cycle == 0:
            q, v, _ = mv.seat_change(model, run.q[-1], run.v[-1], float(zr[-1]))
    seconds = time.thread_time() - start
    return seconds, _station_metrics(
        model, cam, t, np.concatenate(ys), np.concatenate(vs), np.concatenate(accs), np.fmax(*step_peaks)
    )


def _window_in_process(tree: Path, subs: list[int]) -> dict:
    """One round of the window (machine_window_worker.py) in a process of its own started in `tree`
    with only `tree` on the path: its own benchmark helpers and compiled step, whatever their
    signatures. Returns {"seconds": {sub: s}, "metrics": {sub: array}}."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run(
        [sys.executable, str(WORKER), json.dumps({"subs": subs})],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise RuntimeError(f"the window in {tree} failed (exit {done.returncode}): {last}")
    out = json.loads(done.stdout.strip().splitlines()[-1])
    return {
        "seconds": {int(k): x for k, x in out["seconds"].items()},
        "metrics": {int(k): np.array(x) for k, x in out["metrics"].items()},
    }


def _ring_window_s(cam, t, sub) -> float:
    from dynamics.models.clearance import ClearanceChain
    from dynamics.solvers import clearance_verlet

    ring = ClearanceChain(_chain("al6061-t6"), DEFAULT_PIN_CLEARANCE_M)
    tf = np.linspace(t[0], t[-1], sub * (t.size - 1) + 1)
    _, zd, zdd, _ = cam.svaj(tf)
    zeros = np.zeros(N_LINKS)
    start = time.thread_time()
    clearance_verlet.integrate(ring, zd, zdd, tf[1] - tf[0], zeros, zeros, out_every=sub, predictor="ab2")
    return time.thread_time() - start


def _window_table(quick: bool, old_tree: str | None = None, subs: list[int] | None = None) -> list[str]:
    """The window's table; `old_tree` (default BENCH_MACHINE_OLD_TREE) adds that tree's columns, `subs`
    (default: every steps-per-sample from the default to twice it) the rows."""
    from dynamics.models.clearance_machine import ClearanceMachine

    old_tree = old_tree or os.environ.get("BENCH_MACHINE_OLD_TREE")
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=RPM)
    t = _window_times()
    model = ClearanceMachine.of(_chain("al6061-t6"), layout(), None, DEFAULT_PIN_CLEARANCE_M)
    default = mv.substeps_for(model, t[1] - t[0], 0.31, "ab2")
    _, ref = _window_run(model, cam, t, 16 * default)
    scale = np.abs(ref).reshape(4, 5).max(axis=0)  # per metric, its largest over the stations
    trees = {"this tree": ROOT}
    if old_tree:
        trees["old tree"] = Path(old_tree).resolve()
    head = " | ".join(f"{name}: CPU time | per step | error" for name in trees)
    lines = [
        "Clearance machine, one 85-link window (2 index cycles from rest, 4 samples/degree, aluminium, "
        f"modified sine, 180 rpm, {DEFAULT_PIN_CLEARANCE_M * 1e3:g} mm; wheels 12 teeth, 6 seated, polygonal feed); error = worst "
        f"station metric against {16 * default} steps/sample, relative to that metric's largest station value; "
        "time = median CPU (thread) time of the repeats, each tree's window in a process of its own "
        "(its own modules on the path), the processes alternating"
        + (f" (old tree: {old_tree})" if old_tree else "")
        + ":",
        "",
        f"| steps/sample | {head} | worst metric (this tree) |",
        "|---|" + "---|---|---|" * len(trees) + "---|",
    ]
    # every one by default: the error is not monotone below 2x (performance.md)
    subs = subs or list(range(default, 2 * default + 1))
    repeats = 3 if quick else 9
    times = {(name, sub): [] for name in trees for sub in subs}
    errors, worst = {}, {}
    stations = list(model.machine.stations())
    for _ in range(repeats):
        for name, tree in trees.items():  # new, old, new, old, ...: both see the same load
            measured = _window_in_process(tree, subs)
            for sub in subs:
                times[name, sub].append(measured["seconds"][sub])
                relative = np.abs(measured["metrics"][sub] - ref).reshape(4, 5) / scale
                errors[name, sub] = float(np.max(relative))
                station, metric = np.unravel_index(np.argmax(relative), relative.shape)
                worst[name, sub] = f"{METRIC_NAMES[metric]}, {stations[station]}"
    steps = t.size - 1
    for sub in subs:
        cells = []
        for name in trees:
            median = statistics.median(times[name, sub])
            cells.append(f"{1e3 * median:.1f} ms | {1e6 * median / (steps * sub):.2f} us | {errors[name, sub]:.1e}")
        lines.append(f"| {sub} | {' | '.join(cells)} | {worst['this tree', sub]} |")
    ring_s = [_ring_window_s(cam, t, 2 * default) for _ in range(repeats)]
    lines.append(
        f"Yardstick, same run: today's 85-link ring (single-link drive, same chain) over the same window "
        f"at {2 * default} steps/sample, in this process: {1e3 * statistics.median(ring_s):.1f} ms"
    )
    for name in trees:
        # the error is not monotone in the step: a step holds 1e-3 when every finer one here does too
        holding = [sub for i, sub in enumerate(subs) if all(errors[name, s] <= 1e-3 for s in subs[i:])]
        if holding:
            sub = holding[0]
            median = statistics.median(times[name, sub])
            met = median <= TARGET_WINDOW_S
            lines.append(
                f"Target, {name} (1e-3 within {1e3 * TARGET_WINDOW_S:.0f} ms, at {sub} steps/sample, the fewest here "
                f"from which every finer step holds 1e-3: {1e3 * median:.1f} ms): **{'met' if met else 'NOT met'}**"
            )
        else:
            lines.append(
                f"Target, {name} (1e-3 within {1e3 * TARGET_WINDOW_S:.0f} ms): **NOT met** (no step here holds 1e-3)"
            )
    return lines


def _stage_s(scene, cams) -> tuple[float, set, list]:
    t = _window_times()
    models, cycles = set(), []
    start = time.perf_counter()
    for material in MATERIALS:
        chain = _chain(material)
        for law in cams:
            cam = CamProgram.indexing(law, pitch_m=PITCH_M, rpm=RPM)
            _, contact = simulate_scene(scene, chain, cam, t)
            models.add(str(contact.model))
            if contact.steady_state is not None:
                cycles.append(contact.steady_state.cycles)
    return time.perf_counter() - start, models, cycles


def _stage_table(quick: bool) -> list[str]:
    from dynamics.solvers import cache

    cams = CAMS[:2] if quick else CAMS
    wheels = Scene(DEFAULT_PIN_CLEARANCE_M, "global", None, "auto", True, "exact", layout())
    link = Scene(DEFAULT_PIN_CLEARANCE_M, "global", None, "auto", True, "exact")
    _stage_s(wheels, cams[:1])  # compile
    repeats = 1 if quick else 3
    runs = {"wheels": [], "link": []}
    info = {}
    for _ in range(repeats):
        for name, scene in (("wheels", wheels), ("link", link)):
            cache.clear()
            seconds, models, cycles = _stage_s(scene, cams)
            runs[name].append(seconds)
            info[name] = (models, cycles)
    n = len(MATERIALS) * len(cams)
    lines = [
        "",
        f"Pipeline dynamics stage ({len(MATERIALS)} materials x {len(cams)} cams, {N_LINKS} links, steady state, ",
    ]
    lines[-1] += f"median of {repeats} interleaved runs, caches cleared before each):"
    for name in ("wheels", "link"):
        median = statistics.median(runs[name])
        models, cycles = info[name]
        lines.append(
            f"- drive {name}: {median:.2f} s ({1e3 * median / n:.0f} ms per scenario), model "
            f"{'/'.join(sorted(models))}, {min(cycles)}-{max(cycles)} cycles to the steady state"
        )
    met = statistics.median(runs["wheels"]) <= TARGET_STAGE_S
    lines.append(f"Target (wheels stage within {TARGET_STAGE_S:.0f} s): **{'met' if met else 'NOT met'}**")
    return lines


def _impact_table(quick: bool) -> list[str]:
    """The default run's impact statistics on wheels (steady state and window, default step) against
    the same run at 16x the steps (the stability-set safety / 16 / the window's refinement)."""
    from dynamics.machine_scene import WINDOW_REFINEMENT, machine_model, simulate_machine
    from dynamics.solvers import clearance_verlet as verlet

    t = _window_times()
    scene = Scene(DEFAULT_PIN_CLEARANCE_M, "global", None, "auto", True, "exact", layout())
    names = ("closing_speed_max_m_s", "closing_speed_median_m_s", "closing_speed_p90_m_s")
    names += ("energy_per_cycle_J", "force_spike_N")
    lines = [
        "",
        "Impact statistics of the default run on wheels (steady state, default step) against the same run at 16x "
        "the steps, relative error:",
        "",
        "| scenario | steps/sample | closing speed max | median | p90 | energy per cycle | force spike |",
        "|---|---|---|---|---|---|---|",
    ]
    for law in CAMS[:1] if quick else (CAMS[0], CAMS[2]):
        cam = CamProgram.indexing(law, pitch_m=PITCH_M, rpm=RPM)
        for material in MATERIALS:
            model = machine_model(scene, _chain(material))
            _, default = simulate_machine(model, cam, t)
            pred = verlet.default_predictor(model)
            fine = verlet.default_safety(model, pred) / (16 * WINDOW_REFINEMENT[model.span_damping])
            _, ref = simulate_machine(model, cam, t, safety=fine, predictor=pred)
            errors = [getattr(default.impacts, n) / getattr(ref.impacts, n) - 1.0 for n in names]
            cells = " | ".join(f"{100 * e:+.3f} %" for e in errors)
            lines.append(f"| {law}, {material} | {default.steps_per_output} | {cells} |")
    return lines


def run(quick: bool) -> list[str]:
    return _window_table(quick) + _impact_table(quick) + _stage_table(quick)
