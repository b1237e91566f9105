"""The Kelvin-Voigt law on the default scene on its wheels (docs/physics.md, "Damping laws"): why the
aluminium machine's span forces reach 412-849 kN, measured:

    python benchmarks/kelvin_voigt_scene.py [step cams speeds linear frames energy]

The pipeline's default machine (settings.RunConfig() through stages.chain.chain_scene, 85 links, 180
rpm, 0.094 mm free play, friction 0.35) with `--span-damping kelvin-voigt`, on the default link's
FEA figures (benchmarks.defaults.MATERIALS: k and lumped mass per material as `python pipeline.py`
computes them). Every periodic state is searched by plain cycling of the relabelled map
(machine_verlet.index_cycles) from the linear machine's state (as simulate_machine starts it), euler
at a fraction of its stability limit, until the state changes by at most TOL per cycle or MAX_CYCLES.
Sections (all by default):

- step: aluminium, modified sine, the periodic state at 0.5, 0.25, 0.125, 0.0625 of the limit;
- cams: the five cam laws, both materials, at 0.25: cycles, the change over 1 and 2 cycles, peaks;
- speeds: aluminium, modified sine, the clearance machine's periodic state from 150 to 190 rpm;
- linear: the linear machine at free play 0 under Rayleigh (0, beta) (the law in full contact),
  polygon-free, its exact relabelled periodic state (machine_steady) against the speed, both materials;
  at 5 f_1 rpm (the third harmonic on f_1) relabelled against labelled; machine_verlet's periodic
  state of that machine under the Kelvin-Voigt law at 180 rpm against the exact one;
- frames: aluminium at 180 rpm cycled in the labelled frame (no seat change), and with the tooth model;
- energy: aluminium, per cycle of the periodic state: the cam's work, the dashpots' and friction's
  dissipation, the seat change's change of stored energy, the imbalance (at 0.25 and 0.0625).
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.defaults import DEFAULT_RUN, MATERIALS, PITCH_M  # noqa: E402
from dynamics import machine_scene as ms  # noqa: E402
from dynamics.cams import CamProgram  # noqa: E402
from dynamics.models.chain import ChainModel  # noqa: E402
from dynamics.models.clearance import kelvin_voigt_beta_s  # noqa: E402
from dynamics.models.wheels import DEFAULT_TOOTH_STIFFNESS_N_PER_M  # noqa: E402
from dynamics.solvers import machine_verlet as mv  # noqa: E402
from dynamics.solvers.clearance_verlet import DEFAULT_SAFETIES  # noqa: E402
from dynamics.solvers.machine_steady import periodic_state  # noqa: E402
from stages.chain import chain_scene, output_times_s  # noqa: E402

CAMS = ("modified-sine", "modified-trapezoid", "cycloidal", "poly-345", "poly-4567")
TOL, MAX_CYCLES = 1e-7, 400
SAFETY = DEFAULT_SAFETIES[("kelvin-voigt", "euler")]  # the Kelvin-Voigt law's default safety


def chain(material: str, **changes) -> ChainModel:
    k, m = MATERIALS[material]
    return replace(
        ChainModel(
            DEFAULT_RUN.links,
            m,
            k,
            damping_ratio=DEFAULT_RUN.damping,
            preload_N=DEFAULT_RUN.preload_N,
            friction_coefficient=DEFAULT_RUN.friction,
        ),
        **changes,
    )


def machine(material: str, **cfg):
    scene = chain_scene(replace(DEFAULT_RUN, span_damping="kelvin-voigt", **cfg), PITCH_M)
    return ms.machine_model(scene, chain(material))


def cam(law: str = "modified-sine", rpm: float = DEFAULT_RUN.rpm):
    return CamProgram.indexing(law, pitch_m=PITCH_M, rpm=rpm)


def linear_start(model, c, rpm: float):
    """The linear machine's relabelled state to CHOICE_TOL, where simulate_machine starts the search."""
    t = output_times_s(rpm, DEFAULT_RUN.samples_per_degree)
    h_out = t[1] - t[0]
    per = int(round(c.period_s / h_out))
    linear = ms.linear_machine(model)
    search = ms.SearchSettings.of(linear, tol=ms.CHOICE_TOL)
    sub = mv.substeps_for(linear, h_out, search.safety, search.predictor)
    zeros = np.zeros(model.n_state)
    state, _, _ = ms.start_state(linear, c, h_out, per, sub, (zeros, zeros), search)
    return state, h_out, per


def cycled(model, c, rpm: float = DEFAULT_RUN.rpm, safety: float = SAFETY, relabel: bool = True, energy=False):
    """Plain cycling from the linear machine's state: (cycles, change over the last cycle, over the last
    two, peak span force N, min span force N, the last cycle's run, its Seating, the state it ends at)."""
    start, h_out, per = linear_start(model, c, rpm)
    sub = mv.substeps_for(model, h_out, safety, "euler")
    cycles = mv.index_cycles(
        model, c, h_out / sub, per * sub, *start, out_every=sub, predictor="euler", relabel=relabel, track_energy=energy
    )
    previous = start  # the previous cycle's start: the change over two cycles
    for cycle in range(1, MAX_CYCLES + 1):
        q1, v1, run, seating, change = next(cycles)
        two = mv.cycle_change(run, previous, (q1, v1)) if cycle > 1 else np.inf
        previous, start = start, (q1, v1)
        if change <= TOL:
            break
    return cycle, change, two, run.peak_tension_N, run.min_tension_N, run, seating, start


def step_section() -> list[str]:
    model = machine("al6061-t6")
    rows = []
    for safety in (0.5, 0.25, 0.125, 0.0625):
        n, change, _, peak, low, *_ = cycled(model, cam(), safety=safety)
        rows.append(
            f"step {safety:g} of the limit: {n} cycles (change {change:.1e}), {peak / 1e3:.1f} / {low / 1e3:.1f} kN"
        )
    return rows


def cams_section() -> list[str]:
    rows = []
    for material in MATERIALS:
        model = machine(material)
        for law in CAMS:
            n, one, two, peak, low, *_ = cycled(model, cam(law))
            rows.append(
                f"{material} {law}: {n} cycles, change over 1 cycle {one:.1e}, over 2 {two:.1e}, "
                f"{peak / 1e3:.1f} / {low / 1e3:.1f} kN"
            )
    return rows


def speeds_section() -> list[str]:
    rows = []
    for rpm in (150.0, 170.0, 175.0, 180.0, 185.0, 190.0):
        model = machine("al6061-t6")
        n, one, _, peak, low, *_ = cycled(model, cam(rpm=rpm), rpm=rpm)
        rows.append(f"{rpm:g} rpm: {n} cycles (change {one:.1e}), {peak / 1e3:.1f} / {low / 1e3:.1f} kN")
    return rows


def linear_section() -> list[str]:
    rows = []
    speeds_by_material = {
        "al6061-t6": (150, 170, 180, 185, 186, 190, 200, 210),
        "ti-grade2": (180, 210, 215, 218, 220, 230),
    }
    for material, speeds in speeds_by_material.items():
        base = chain(material, friction_coefficient=0.0)
        beta = kelvin_voigt_beta_s(base, None)
        layout = chain_scene(replace(DEFAULT_RUN, polygonal_action=False), PITCH_M).layout
        kv = layout.machine(replace(base, rayleigh_coefficients=(0.0, beta)), None)
        spans = kv.topology.incidence().toarray()
        k_span = np.asarray(kv.topology.span_stiffness_N_per_m)
        f1 = kv.lowest_natural_frequencies_Hz(1)[0]
        for rpm in speeds:
            q = periodic_state(kv, cam(rpm=float(rpm)), 720).q_m
            tension = base.preload_N + (q @ spans.T) * k_span
            rows.append(
                f"{material} {rpm} rpm (f1 / f_index {f1 / (rpm / 15):.3f}): {tension.max() / 1e3:.1f} / "
                f"{tension.min() / 1e3:.1f} kN"
            )
        on = cam(rpm=5.0 * f1)  # the third harmonic of the index rate (rpm / 15) on f1
        relabelled, labelled = (np.max(np.abs(periodic_state(kv, on, 720, relabel=r).q_m)) for r in (True, False))
        rows.append(
            f"{material} at {5 * f1:.1f} rpm: largest |q| {relabelled:.4f} m relabelled, {labelled:.4f} m labelled"
        )
        rows.append(
            f"{material} at 180 rpm: machine_verlet against it, {_verlet_against_exact(kv, base, beta):.1e} of |q|"
        )
    return rows


def _verlet_against_exact(kv, base, beta) -> float:
    """The largest difference over an index between machine_verlet's relabelled periodic state of the
    clearance machine at free play 0 under the Kelvin-Voigt law and machine_steady's of `kv`, relative
    to the latter's largest |q| (the default step, 720 samples per cycle)."""
    from dynamics.models.clearance_machine import ClearanceMachine

    c = cam()
    exact = periodic_state(kv, c, 720).q_m
    model = ClearanceMachine(kv, 0.0, "kelvin-voigt", beta, base)
    h = c.cycle_s / 720
    sub = mv.substeps_for(model, h, SAFETY, "euler")
    q, v, *_ = mv.relabelled_periodic_state(
        model,
        c,
        h / sub,
        720 * sub,
        np.zeros(model.n_state),
        np.zeros(model.n_state),
        tol=1e-9,
        max_cycles=600,
        predictor="euler",
    )
    run = mv.integrate(model, *mv.cycle_nodes(c, h / sub, 720 * sub), h / sub, q, v, out_every=sub, predictor="euler")
    return float(np.max(np.abs(run.q - exact)) / np.max(np.abs(exact)))


def frames_section() -> list[str]:
    labelled = cycled(machine("al6061-t6"), cam(), relabel=False)
    teeth = cycled(machine("al6061-t6", tooth_stiffness_N_per_m=DEFAULT_TOOTH_STIFFNESS_N_PER_M), cam())
    return [
        f"labelled frame: {labelled[0]} cycles, {labelled[3] / 1e3:.1f} / {labelled[4] / 1e3:.1f} kN",
        f"tooth model: {teeth[0]} cycles, {teeth[3] / 1e3:.1f} / {teeth[4] / 1e3:.1f} kN",
    ]


def energy_section() -> list[str]:
    model = machine("al6061-t6")
    rows = []
    for safety in (SAFETY, SAFETY / 4):
        *_, run, seating, (q, v) = cycled(model, cam(), safety=safety, energy=True)
        # the start of the last cycle stepped is its end before the seat change, carried back: the
        # periodic state's stored energy at an index start
        stored = model.stored_energy_J(q, v, 0.0, 0.0)
        change = seating.transfer_energy_change_J
        imbalance = run.cam_work_J + change - run.dissipated_damping_J - run.dissipated_friction_J
        rows.append(
            f"{safety:g} of the limit: stored at the index start {stored:.0f} J; per cycle cam work "
            f"{run.cam_work_J:.0f} J, seat change {change:+.0f} J, dashpots {run.dissipated_damping_J:.0f} J, "
            f"friction {run.dissipated_friction_J:.0f} J, imbalance {imbalance / run.cam_work_J:.1e} of the cam work"
        )
    return rows


SECTIONS = {
    "step": step_section,
    "cams": cams_section,
    "speeds": speeds_section,
    "linear": linear_section,
    "frames": frames_section,
    "energy": energy_section,
}


if __name__ == "__main__":
    for name in sys.argv[1:] or SECTIONS:
        print(f"== {name}")
        for line in SECTIONS[name]():
            print(line, flush=True)
