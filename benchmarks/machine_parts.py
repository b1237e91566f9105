"""What each part of the machine on its wheels changes on the default scene (issue #22).

Default scene: 85 aluminium links (k and body mass from `python -m fem`, built-in link, plus the
default hardware and nest masses), modified sine, 180 rpm, modal zeta 0.13, friction 0, no pin
clearance, 4 samples per cam degree. Parts: six links seated on a 12-tooth sprocket, the drive's
torsional compliance (default k_d R_m^2), the sprocket's inertia (solid steel disc of the pitch radius,
25 mm thick), an idler wheel of the same size seating six links on a fixed axle, the polygonal feed.
Each row is a periodic steady state; "relabelled" moves every link one place per index (the machine
as it runs), "labelled" keeps the same links seated (the frame of the issue's first figures).

    PYTHONPATH=. python benchmarks/machine_parts.py [--no-polygon]
    PYTHONPATH=. python benchmarks/machine_parts.py --tooth-phases 0 0.25 0.5 0.75

The polygonal rows run the DOP853 reference integrator (about a minute each on a quiet machine).
`--tooth-phases` instead runs the whole machine ("all together") at each tooth phase: the seat change
at the dwell (0) or inside the index, when the cam has lifted (1 - phase) of a pitch.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.defaults import DEFAULT_RUN, PITCH_M  # noqa: E402
from dynamics.cams import CamProgram  # noqa: E402
from dynamics.models.chain import ChainModel  # noqa: E402
from dynamics.models.machine import MachineOnWheels  # noqa: E402
from dynamics.models.wheels import Wheel, pitch_radius_m, steel_disc_inertia_kg_m2  # noqa: E402
from dynamics.solvers.machine_steady import link_residual_and_peak, periodic_state  # noqa: E402
from geometry.dimensions import DEFAULT_HARDWARE_MASS_KG, NEST_MASS_KG  # noqa: E402

K_AL_N_PER_M = 93309880.76383373  # python -m fem --json: stiffness_N_per_m (al6061-t6, built-in link)
BODY_MASS_AL_KG = 0.3729267739202092  # python -m fem --json: mass_kg
TEETH = DEFAULT_RUN.sprocket_teeth
WRAP = DEFAULT_RUN.sprocket_wrap_links
DISC_THICKNESS_M = 0.025


def machines(with_polygon: bool):
    chain = ChainModel(DEFAULT_RUN.links, BODY_MASS_AL_KG + DEFAULT_HARDWARE_MASS_KG + NEST_MASS_KG, K_AL_N_PER_M)
    j = steel_disc_inertia_kg_m2(pitch_radius_m(PITCH_M, TEETH), DISC_THICKNESS_M)
    bare = Wheel(TEETH, PITCH_M, WRAP)
    heavy = Wheel(TEETH, PITCH_M, WRAP, inertia_kg_m2=j)
    rows = [
        ("today: link 1 driven through k_d", MachineOnWheels(chain, drive="link"), False),
        (
            "six seated links held to the cam",
            MachineOnWheels(chain, sprocket=bare, polygonal=False, drive_torsional_stiffness_N_m_per_rad=np.inf),
            None,
        ),
        ("+ drive compliance k_d R_m^2", MachineOnWheels(chain, sprocket=bare, polygonal=False), True),
        ("+ sprocket inertia", MachineOnWheels(chain, sprocket=heavy, polygonal=False), True),
        (
            "+ idler wheel (6 seated, inertia, fixed axle)",
            MachineOnWheels(chain, sprocket=heavy, idler=heavy, polygonal=False),
            True,
        ),
    ]
    if with_polygon:
        rows += [
            (
                "polygonal action alone (held sprocket)",
                MachineOnWheels(chain, sprocket=bare, drive_torsional_stiffness_N_m_per_rad=np.inf),
                True,
            ),
            ("all together (+ polygonal action)", MachineOnWheels(chain, sprocket=heavy, idler=heavy), True),
        ]
    return rows, j


def metrics(machine: MachineOnWheels, cam, relabel: bool, links: tuple[int, ...]):
    """Per link: residual vibration (max |x - z| over the dwell samples), peak |absolute acceleration|."""
    r = periodic_state(machine, cam, 360, relabel=relabel)
    dwell = cam.dwell_mask(r.t_s)
    return [link_residual_and_peak(machine, r, dwell, link) for link in links], r


def readme_rows(cam) -> list[tuple[str, float, float, float]]:
    """README.md's table "What each part changes": per configuration (machines(True)'s order) f1 (Hz,
    of the polygon-free linearisation), the residual (m) and peak |absolute acceleration| (m/s^2) at
    the tight strand's middle, in the relabelled steady state where the machine relabels (the
    labelled one for `--drive link`). tests/test_machine_parts_table.py checks the README against it."""
    rows, _ = machines(True)
    out = []
    for name, machine, relabel_only in rows:
        ((res, peak),), _ = metrics(machine, cam, relabel_only is not False, (machine.stations()["tight-side"],))
        out.append((name, float(machine.natural_frequencies_Hz()[0]), res, peak))
    return out


def print_tooth_phases(cam, phases) -> None:
    """The whole machine (all parts, polygonal action) at each tooth phase, relabelled steady state."""
    chain = ChainModel(DEFAULT_RUN.links, BODY_MASS_AL_KG + DEFAULT_HARDWARE_MASS_KG + NEST_MASS_KG, K_AL_N_PER_M)
    j = steel_disc_inertia_kg_m2(pitch_radius_m(PITCH_M, TEETH), DISC_THICKNESS_M)
    print("all together (polygonal action), relabelled steady state; station: the tight strand's middle")
    print(
        f"{'phase':>6s} {'resid mm':>9s} {'peak a':>8s} {'max peak a':>10s} {'seat m/s':>9s} {'impact J':>9s} "
        f"{'dE J':>9s} {'s':>5s}"
    )
    for phase in phases:
        wheel = Wheel(TEETH, PITCH_M, WRAP, inertia_kg_m2=j, tooth_phase=phase)
        machine = MachineOnWheels(chain, sprocket=wheel, idler=wheel)
        start = time.perf_counter()
        ((res, peak),), r = metrics(machine, cam, True, (machine.stations()["tight-side"],))
        top = float(np.max(np.abs(r.a_m_s2 + r.zddot_m_s2[:, None])))
        print(
            f"{phase:6.2f} {res * 1e3:9.3f} {peak:8.1f} {top:10.1f} {max(r.seating_speed_m_s):9.2e} "
            f"{sum(r.seating_impact_J):9.2e} {r.transfer_energy_change_J:9.2e} {time.perf_counter() - start:5.1f}",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-polygon", action="store_true", help="leave out the polygonal rows (integrator)")
    parser.add_argument(
        "--tooth-phases", type=float, nargs="+", metavar="F", help="run the whole machine at these tooth phases"
    )
    args = parser.parse_args()
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=DEFAULT_RUN.rpm)
    if args.tooth_phases:
        print_tooth_phases(cam, args.tooth_phases)
        return
    rows, j = machines(not args.no_polygon)
    print(
        f"sprocket/idler: z = {TEETH}, R = {pitch_radius_m(PITCH_M, TEETH) * 1e3:.1f} mm, "
        f"R_m = {PITCH_M * TEETH / (2 * np.pi) * 1e3:.1f} mm, J = {j:.3f} kg m^2 (steel disc, "
        f"{DISC_THICKNESS_M * 1e3:.0f} mm); k_theta default = "
        f"{rows[2][1].drive_stiffness_N_m_per_rad:.4g} N m/rad"
    )
    print("station: the tight strand's middle (machine) / link 64 (today's tight-side station)")
    print(
        f"{'configuration':48s} {'f1 Hz':>7s} {'frame':>10s} {'resid mm':>9s} {'peak a':>8s} "
        f"{'resid@64':>9s} {'peak@64':>8s} {'seat m/s':>9s} {'impact J':>9s} {'dE J':>9s} {'s':>5s}"
    )
    for name, machine, relabel_only in rows:
        f1 = machine.natural_frequencies_Hz()[0]  # of the polygon-free linearisation
        frames = [False] if relabel_only is False else ([True] if relabel_only else [False, True])
        for relabel in frames:
            start = time.perf_counter()
            station = machine.stations()["tight-side"]
            ((res, peak), (res64, peak64)), r = metrics(machine, cam, relabel, (station, 63))
            seat = max(r.seating_speed_m_s) if r.seating_speed_m_s else float("nan")
            impact = sum(r.seating_impact_J) if r.seating_impact_J else float("nan")
            change = r.transfer_energy_change_J if relabel else float("nan")
            frame = "relabelled" if relabel else "labelled"
            print(
                f"{name:48s} {f1:7.2f} {frame:>10s} {res * 1e3:9.3f} {peak:8.1f} {res64 * 1e3:9.3f} "
                f"{peak64:8.1f} {seat:9.2e} {impact:9.2e} {change:9.2e} {time.perf_counter() - start:5.1f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
