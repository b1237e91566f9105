"""The single-link drive (the ring) on the topology kernel (issue #22, Architecture): the cost per
step of the ring's own compiled step (dynamics.solvers.clearance_verlet) and of the machine's
(dynamics.solvers.machine_verlet on the ring's topology) on the same scene, the machine kernel both
with the whole C (`ClearanceMachine.of(chain, LINK_DRIVE, ...)`: the global law's C w as the machine
on wheels takes it) and as the ring runs on it (ring_on_topology.RingMachine: C w in the two blocks of
the loop's mirror symmetry), and how far apart their station metrics are.

    python benchmarks/run.py --only ring_on_topology

The scene is bench_clearance's window (85 links, the default link's FEA k and lumped mass, aluminium,
180 rpm, modified sine, friction 0.35, 0.094 mm free play, 180 degrees at 4 samples per degree from
rest): the global law with the "ab2" predictor at 20 steps per output sample (issue #11's 1e-3
target), the Kelvin-Voigt law with "euler" at 32, and the global law with the idler tensioner. The
kernels run interleaved (one of each per repeat), so their ratios hold under load; the table gives
the median and the best of the repeats.

Then the dynamics stage as the pipeline runs it on the single-link drive (2 materials x 5 cams, 85
links, periodic steady state, the global law: dynamics.scene.simulate_chain) with each kernel
(`kernel="ring"`, today's, and `kernel="topology"`), every scenario in both orders (ring first, then
topology first: the kernel run second gains about 15 %), the ratio from each order and from both
together, and how far their summaries' impact statistics are apart (both kernels take them at the
crossing interpolated within the step: round-off).

Then above DENSE_LINK_LIMIT links (401, and 1,000 unless --quick; the same scene, aluminium, steady
state): how far the station metrics and the contact summary move from a dense-damping reference (the
topology kernel with the dense C) with the ring's kernel (its O(N) damping, reduced_damping at 1e-4
per mode) and with the topology kernel (the machine's, machine_damping at 1e-5), and each one's time.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time

import numpy as np

from benchmarks.defaults import DEFAULT_RUN, MATERIALS, PITCH_M
from dynamics.cams import CamProgram
from dynamics.models import clearance_machine
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import DEFAULT_PIN_CLEARANCE_M, ClearanceChain, Tensioner
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import LINK_DRIVE
from dynamics.response.metrics import link_metrics, station_metrics
from dynamics.scene import simulate_chain
from dynamics.solvers import cache
from dynamics.solvers import clearance_verlet as cv
from dynamics.solvers import machine_verlet as mv
from dynamics.solvers.ring_on_topology import RingMachine

K_N_PER_M, MASS_KG = MATERIALS["al6061-t6"]
CAMS = ("modified-sine", "modified-trapezoid", "cycloidal", "poly-345", "poly-4567")
RPM, N_LINKS = DEFAULT_RUN.rpm, DEFAULT_RUN.links
CASES = (  # (label, damping law, predictor, steps per output sample, tensioner)
    ("global, ab2, 20 steps/sample (issue #11's 1e-3 target)", "global", "ab2", 20, None),
    ("Kelvin-Voigt, euler, 32 steps/sample", "kelvin-voigt", "euler", 32, None),
    ("global, ab2, 20 steps/sample, idler tensioner", "global", "ab2", 20, Tensioner(1e5, 5.0, 100.0)),
)


def _scene(law: str, tensioner):
    chain = ChainModel(N_LINKS, MASS_KG, K_N_PER_M, friction_coefficient=DEFAULT_RUN.friction)
    ring = ClearanceChain(chain, DEFAULT_PIN_CLEARANCE_M, span_damping=law, tensioner=tensioner)
    machine = ClearanceMachine.of(chain, LINK_DRIVE, tensioner, DEFAULT_PIN_CLEARANCE_M, law)
    mirrored = RingMachine.of(chain, LINK_DRIVE, tensioner, DEFAULT_PIN_CLEARANCE_M, law)
    return ring, machine, mirrored


def _nodes(cam, t, sub):
    tf = np.linspace(t[0], t[-1], sub * (t.size - 1) + 1)
    s, v, a, _ = (np.asarray(x, dtype=float) for x in cam.svaj(tf))
    return s - s[0], v, a, tf[1] - tf[0]


def _stations(cam, t, y, w, a) -> np.ndarray:
    s, v, acc, _ = cam.svaj(t)
    lm = link_metrics(s[:, None] + y, v[:, None] + w, acc[:, None] + a, s, v, acc, cam.dwell_mask(t))
    keys = ("rms_displacement_m", "rms_velocity_m_s", "rms_acceleration_m_s2", "max_abs_acceleration_m_s2")
    return np.array([[getattr(x, k) for k in keys] for x in station_metrics(lm).values()])


def _ring(ring, nodes, sub, predictor):
    zr, zd, zdd, h = nodes
    start = time.perf_counter()
    r = cv.integrate(ring, zd, zdd, h, np.zeros(N_LINKS), -zd[0] * np.ones(N_LINKS), out_every=sub, predictor=predictor)
    return time.perf_counter() - start, (r.y, r.w, r.a)


def _machine(machine, nodes, sub, predictor):
    zr, zd, zdd, h = nodes
    n = machine.topology.n_dof
    v0 = np.where(np.arange(n) < N_LINKS, -zd[0], 0.0)
    start = time.perf_counter()
    r = mv.integrate(machine, zr, zd, zdd, h, np.zeros(n), v0, out_every=sub, predictor=predictor)
    return time.perf_counter() - start, (r.q[:, :N_LINKS], r.v[:, :N_LINKS], r.a[:, :N_LINKS])


def run(quick: bool) -> list[str]:
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=RPM)
    t = np.arange(721) / 4 / (6 * RPM)
    repeats = 3 if quick else 9
    lines = [
        "| case | steps | ring kernel per step (median / best) | machine kernel, whole C (median / best) | "
        "machine kernel, ring's machine (median / best) | ratios of medians to the ring's (whole C, ring's machine) | "
        "station metrics apart (whole C, ring's machine) |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, law, predictor, sub, tensioner in CASES:
        ring, machine, mirrored = _scene(law, tensioner)
        nodes = _nodes(cam, t, sub)
        n_steps = nodes[1].size - 1
        _ring(ring, nodes, sub, predictor)  # compile (or load the cache) outside the timings
        _machine(machine, nodes, sub, predictor)
        _machine(mirrored, nodes, sub, predictor)
        runs = [
            (_ring(ring, nodes, sub, predictor), _machine(machine, nodes, sub, predictor))
            + (_machine(mirrored, nodes, sub, predictor),)
            for _ in range(repeats)
        ]
        ring_s, machine_s, mirrored_s = (np.array([r[i][0] for r in runs]) for i in range(3))
        a = _stations(cam, t, *runs[0][0][1])
        apart = [float(np.max(np.abs(_stations(cam, t, *runs[0][i][1]) - a) / np.abs(a))) for i in (1, 2)]
        us = 1e6 / n_steps
        ratio = [np.median(x) / np.median(ring_s) for x in (machine_s, mirrored_s)]
        lines.append(
            f"| {label} | {n_steps} | {us * np.median(ring_s):.2f} / {us * ring_s.min():.2f} us | "
            f"{us * np.median(machine_s):.2f} / {us * machine_s.min():.2f} us | "
            f"{us * np.median(mirrored_s):.2f} / {us * mirrored_s.min():.2f} us | "
            f"{ratio[0]:.2f}x, {ratio[1]:.2f}x | {apart[0]:.1e}, {apart[1]:.1e} |"
        )
    return lines + _stage(quick) + _long_chains(quick)


ORDERS = (("ring", "topology"), ("topology", "ring"))  # whichever kernel runs second gains ~15 %


def _stage(quick: bool) -> list[str]:
    """Every scenario in both orders (ring first, then topology first), the solvers' cache cleared
    before every run so each kernel pays its own set-up: the kernel run second in a scenario gains
    from what the first left warm (architecture.md, the ring on the topology kernel), so one order's
    ratio is biased and the two orders' together are not."""
    t = np.arange(721) / 4 / (6 * RPM)
    cams = CAMS[:2] if quick else CAMS
    seconds = {(order, kernel): 0.0 for order in ORDERS for kernel in order}
    impact_apart, trajectory_apart = 0.0, 0.0
    for k, m in MATERIALS.values():
        model = ClearanceChain(
            ChainModel(N_LINKS, m, k, friction_coefficient=DEFAULT_RUN.friction), DEFAULT_PIN_CLEARANCE_M
        )
        for law in cams:
            cam = CamProgram.indexing(law, pitch_m=PITCH_M, rpm=RPM)
            out = {}
            for order in ORDERS:
                for kernel in order:
                    cache.clear()
                    start = time.perf_counter()
                    out[kernel] = simulate_chain(model, cam, t, kernel=kernel)
                    seconds[order, kernel] += time.perf_counter() - start
            (ring, ring_c), (ours, ours_c) = out["ring"], out["topology"]
            trajectory_apart = max(
                trajectory_apart,
                float(np.max(np.abs(ours.x_m - ring.x_m)) / np.max(np.abs(ring.x_m - ring.z_m[:, None]))),
            )
            for name in ("closing_speed_max_m_s", "closing_speed_median_m_s", "energy_per_cycle_J"):
                a, b = getattr(ours_c.impacts, name), getattr(ring_c.impacts, name)
                impact_apart = max(impact_apart, abs(a / b - 1.0))
    per_order = []
    for order in ORDERS:
        ring_s, ours_s = seconds[order, "ring"], seconds[order, "topology"]
        per_order.append(
            f"{order[0]} first: ring kernel {ring_s:.2f} s, topology kernel {ours_s:.2f} s, ratio {ours_s / ring_s:.2f}x"
        )
    ring_s = sum(seconds[order, "ring"] for order in ORDERS)
    ours_s = sum(seconds[order, "topology"] for order in ORDERS)
    return [
        "",
        f"Dynamics stage, single-link drive ({len(MATERIALS)} materials x {len(cams)} cams, global law, steady state; "
        f"each scenario in both orders, the solvers' cache cleared before every run): {'; '.join(per_order)}; "
        f"both orders together {ours_s / ring_s:.2f}x; link displacements "
        f"apart by {trajectory_apart:.1e} of their peak, impact statistics (closing speeds max and median, energy per "
        f"cycle) by up to {impact_apart:.1e} of themselves",
    ]


@contextlib.contextmanager
def _dense_damping():
    """The dense C on the topology kernel above DENSE_LINK_LIMIT links (the reference), the solvers'
    cache emptied on the way in and out so that no machine built with the other C is reused."""
    saved = clearance_machine.DENSE_LINK_LIMIT
    clearance_machine.DENSE_LINK_LIMIT = 10**9
    cache.clear()
    try:
        yield
    finally:
        clearance_machine.DENSE_LINK_LIMIT = saved
        cache.clear()


def _summary(contact) -> dict:
    values = {k: getattr(contact, k) for k in ("peak_tension_N", "min_tension_N", "impacts_per_cycle")}
    values.update({k: getattr(contact, k) for k in ("free_play_time_fraction", "impact_force_spike_N")})
    values.update({f.name: getattr(contact.impacts, f.name) for f in dataclasses.fields(contact.impacts)})
    return values


def _long_chains(quick: bool) -> list[str]:
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=RPM)
    t = np.arange(721) / 4 / (6 * RPM)
    lines = [
        "",
        "| links | damping | time | station metrics from the dense C | contact summary from the dense C |",
        "|---|---|---|---|---|",
    ]
    for n in (401,) if quick else (401, 1000):
        model = ClearanceChain(
            ChainModel(n, MASS_KG, K_N_PER_M, friction_coefficient=DEFAULT_RUN.friction), DEFAULT_PIN_CLEARANCE_M
        )
        runs = {}
        for label, kernel in (
            ("dense C (topology kernel)", "topology"),
            ("ring's O(N), 1e-4 (ring kernel)", "ring"),
            ("machine's O(N), 1e-5 (topology kernel)", "topology"),
        ):
            context = _dense_damping() if label.startswith("dense") else contextlib.nullcontext()
            with context:
                cache.clear()
                start = time.perf_counter()
                response, contact = simulate_chain(model, cam, t, kernel=kernel)
                seconds = time.perf_counter() - start
            stations = _stations(cam, t, *(x - y for x, y in _relative(response)))
            runs[label] = (stations, _summary(contact), seconds)
        ref_st, ref_sum, _ = runs["dense C (topology kernel)"]
        for label, (st, summ, seconds) in runs.items():
            st_apart = float(np.max(np.abs(st - ref_st) / np.abs(ref_st)))
            sum_apart = max(abs(summ[k] - ref_sum[k]) / abs(ref_sum[k]) for k in ref_sum if ref_sum[k])
            lines.append(f"| {n} | {label} | {seconds:.1f} s | {st_apart:.1e} | {sum_apart:.1e} |")
    return lines


def _relative(response):
    """(displacement, velocity, acceleration) pairs of a ChainResponse and the cam's, for _stations."""
    return (
        (response.x_m, response.z_m[:, None]),
        (response.v_m_s, response.zdot_m_s[:, None]),
        (response.a_m_s2, response.zddot_m_s2[:, None]),
    )
