"""Where the clearance machine's step goes at long lengths (issue #24): the step, the force evaluation,
the O(N) damping product and the step loop's own passes, each timed in a compiled loop.

    python benchmarks/bench_step_parts.py --links 10000 [--old-tree DIR] [--samples 7]

The machine is bench_long_wheels.py's scenario (the default wheels, tensioned carriage, 0.094 mm
free play, friction, global law) at N links, from its state after WARM_STEPS steps of a cycle from
rest. Each part is timed over STEPS repetitions (CPU seconds, time.process_time), SAMPLES times
alternately, and its median per step printed. With --old-tree the same parts of that checkout's
machine_verlet and machine_damping (loaded beside this tree's, on the same model and state) are
timed in the same rounds (medians, the samples' range in brackets), and the two trees' damping
products compared.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.bench_long_wheels import long_scene  # noqa: E402
from dynamics.machine_scene import machine_model  # noqa: E402
from dynamics.solvers import machine_verlet as mv  # noqa: E402

WARM_STEPS = 1000
STEPS = 400


def _load(path: Path, name: str, replacing: dict | None = None):
    """The module at `path` as `name`; `replacing` {module name: module} while it imports."""
    saved = {k: sys.modules.get(k) for k in (replacing or {})}
    sys.modules.update(replacing or {})
    try:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    finally:
        for k, v in saved.items():
            sys.modules[k] = v
    return module


def _trees(old_tree: str | None) -> dict:
    """{label: (machine_verlet, machine_damping)} of this tree and the old one."""
    from dynamics.models import machine_damping as md

    trees = {"new": (mv, md)}
    if old_tree:
        root = Path(old_tree)
        old_md = _load(root / "dynamics/models/machine_damping.py", "old_machine_damping")
        old_mv = _load(
            root / "dynamics/solvers/machine_verlet.py",
            "old_machine_verlet",
            {"dynamics.models.machine_damping": old_md},
        )
        trees["old"] = (old_mv, old_md)
    return trees


class _Model:
    """The model as integrate takes it, its arrays' O(N) damping built by one tree's machine_damping."""

    def __init__(self, model, md):
        from dataclasses import replace

        self._model = model
        r = md.of_machine(model.machine)
        self.arrays = replace(
            model.arrays, reduced=(r.dofs, r.tri, r.scalars, r.factors, r.sm, r.weights, r.scratch(), r.border)
        )

    def __getattr__(self, name):
        return getattr(self._model, name)


def _parts(model, mvm, mdm, state, nodes, h):
    """{part: callable running it STEPS times}."""
    import numba

    arr = model.arrays
    q, v = state
    zr, zd, zdd = nodes
    n, ns = q.size, arr.span_int.shape[0]
    red = arr.reduced
    dof_float = np.asfortranarray(arr.dof_float)
    wheel_float = mvm._step_wheels(arr.wheel_float)
    if hasattr(mvm, "kernel_damping"):  # the step's damping arguments, one type signature for every machine
        cmat, kernel_red = mvm.kernel_damping(arr, "single")
    else:  # a tree before it: the dense C alone, the factors in their own precision
        cmat, kernel_red = np.ascontiguousarray(arr.cmat, dtype=np.float32), red
    work = mvm._accel_work(n, wheel_float, cmat)
    t_el, ed, e_out, a = np.zeros(ns), np.zeros(ns), np.zeros(ns), np.zeros(n)
    contact = np.zeros(ns, dtype=np.bool_)
    accel = mvm._accel_into
    damp = mdm.chain_damping_into

    @numba.njit
    def accel_loop(steps, q, v, zr, zd, zdd, si, sf, dfl, wfl, par, cmat, red, work, t_el, ed, contact, e_out, a):
        for _ in range(steps):
            accel(q, v, zr, zd, zdd, si, sf, dfl, wfl, par, cmat, red, work, t_el, ed, contact, e_out, a)

    @numba.njit
    def damping_loop(steps, tri, scalars, factors, sm, weights, border, w, out, scratch):
        for _ in range(steps):
            damp(tri, scalars, factors, sm, weights, border, w, out, scratch)

    wv = v[red[0]].copy()
    cw = np.zeros(wv.size)
    scratch = red[6].copy()
    return {
        "step (integrate)": lambda: mvm.integrate(
            model, zr[: STEPS + 1], zd[: STEPS + 1], zdd[: STEPS + 1], h, q, v, out_every=STEPS
        ),
        "force evaluation": lambda: accel_loop(
            STEPS,
            q,
            v,
            zr[1],
            zd[1],
            zdd[1],
            arr.span_int,
            arr.span_float,
            dof_float,
            wheel_float,
            arr.par,
            cmat,
            kernel_red,
            work,
            t_el,
            ed,
            contact,
            e_out,
            a,
        ),
        "damping product": lambda: damping_loop(STEPS, red[1], red[2], red[3], red[4], red[5], red[7], wv, cw, scratch),
    }, cw


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--links", type=int, default=10000)
    parser.add_argument("--old-tree", default=None)
    parser.add_argument("--samples", type=int, default=7)
    args = parser.parse_args()
    chain, scene, cam, _ = long_scene(args.links)
    model = machine_model(scene, chain)
    h = mv.stable_step_s(model, 0.25, "euler")
    nodes = mv.cycle_nodes(cam, h, WARM_STEPS + STEPS)
    n = model.arrays.dof_float.shape[0]
    run = mv.integrate(model, *(x[: WARM_STEPS + 1] for x in nodes), h, np.zeros(n), np.zeros(n), out_every=WARM_STEPS)
    state = (run.q[-1].copy(), run.v[-1].copy())
    after = tuple(x[WARM_STEPS:] for x in nodes)
    parts, products = {}, {}
    for label, (mvm, mdm) in _trees(args.old_tree).items():
        m = _Model(model, mdm)
        parts[label], products[label] = _parts(m, mvm, mdm, state, after, h)
        for f in parts[label].values():  # compile, warm
            f()
    times = {(label, part): [] for label in parts for part in parts[label]}
    for _ in range(args.samples):
        for label in parts:
            for part, f in parts[label].items():
                start = time.process_time()
                f()
                times[label, part].append((time.process_time() - start) / STEPS)
    load = open("/proc/loadavg").read().split()[:3]
    print(
        f"{args.links} links, {n} DOFs, {model.arrays.span_int.shape[0]} spans; CPU per step, median of "
        f"{args.samples} samples of {STEPS}; load {' '.join(load)}"
    )
    for part in parts["new"]:
        cells = [
            f"{label} {1e6 * statistics.median(times[label, part]):.1f} us"
            f" ({1e6 * min(times[label, part]):.0f}-{1e6 * max(times[label, part]):.0f})"
            for label in parts
        ]
        print(f"  {part}: " + ", ".join(cells))
    if "old" in products:
        ref = products["old"]
        print(
            f"  damping product: new against old, max |diff| / max |old| = "
            f"{np.max(np.abs(products['new'] - ref)) / np.max(np.abs(ref)):.2e}"
        )


if __name__ == "__main__":
    main()
