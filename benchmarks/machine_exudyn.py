"""The machine on its wheels against a planar multibody model in Exudyn (verification/machine_exudyn.py):
station metrics over one index cycle from rest, no seat changes (issue #22).

Chain: aluminium links of the default scene (k 9.33e7 N/m, 2.03 kg), pitch 112.5 mm, two equal
wheels on fixed axles with z/2 + 1 pins seated on each, 8 free links per strand (N = z + 18), wheel
inertia 0.01 kg m^2 each, drive k_theta = k R_m^2, beta 2e-5 s on spans and drive, modified sine.
Scenes: the strands' transverse motion quasi-static (preload 1e5 N, 45 rpm) for z = 6, 12, 24,
where the planar model's only addition is the strands' rise and fall; and the default preload and
speed (2224 N, 180 rpm), where the index excites the strands' transverse modes. Then three cycles
with the seat change at each dwell (z = 12 free strands; z = 12 and 6 guided: a dashpot of
GUIDE_DAMPING_N_S_PER_M across the strand on every free pin).

    PYTHONPATH=. python benchmarks/machine_exudyn.py [--quick]

About 5 minutes on a shared machine (the 1-D reference integrator is the slower of the two).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from dynamics.cams import CamProgram
from dynamics.options import DEFAULT_PRELOAD_N
from verification.machine_exudyn import (
    STATIONS,
    PlanarMachine,
    one_d_response,
    planar_response,
    planar_stations,
    relabelled_windows,
    station_metrics,
    strand_transverse,
)

PITCH_M = 0.1125
K_N_PER_M = 9.33e7
MASS_KG = 2.03
BETA_S = 2e-5
# the guide's dashpot: c / (2 m) = 123 1/s, every transverse mode of a strand decays in 8 ms
GUIDE_DAMPING_N_S_PER_M = 500.0


def planar_machine(teeth: int, preload_N: float) -> PlanarMachine:
    feed_radius = PITCH_M * teeth / (2 * np.pi)
    return PlanarMachine(
        teeth + 18,
        MASS_KG,
        K_N_PER_M,
        preload_N,
        PITCH_M,
        teeth,
        drive_stiffness_N_m_per_rad=K_N_PER_M * feed_radius**2,
        sprocket_inertia_kg_m2=0.01,
        idler_inertia_kg_m2=0.01,
        beta_s=BETA_S,
    )


def compare(teeth: int, preload_N: float, rpm: float, steps: tuple[int, ...] = (20, 40)) -> dict:
    """Metrics of the 1-D model and of the planar model at each step count, the planar model's
    transverse motion and the wall times."""
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=rpm)
    t = np.linspace(0.0, cam.cycle_s, 361)
    machine = planar_machine(teeth, preload_N)
    start = time.perf_counter()
    histories, tension, _ = one_d_response(machine, cam, t)
    out = {"1-D": (station_metrics(histories, tension, cam, t), histories, time.perf_counter() - start)}
    for n in steps:
        response = planar_response(machine, cam, t, steps_per_output=n)
        h, tension = planar_stations(machine, response, cam)
        out[f"planar {n}"] = (station_metrics(h, tension, cam, t), h, response.wall_time_s)
        out["transverse"] = strand_transverse(machine, response)
    out["preload"] = preload_N
    return out


def history_gap(a, b) -> float:
    """Largest difference of the stations' displacement histories relative to the largest |y|."""
    return max(float(np.max(np.abs(a[s].y_m - b[s].y_m))) for s in STATIONS) / max(
        float(np.max(np.abs(b[s].y_m))) for s in STATIONS
    )


def print_comparison(label: str, result: dict) -> None:
    transverse, shortening = result["transverse"]
    print(
        f"\n{label}: strands' transverse motion {transverse * 1e3:.2f} mm, geometric shortening {shortening * 1e6:.1f} um"
    )
    print(
        f"{'model':12s} "
        + " ".join(f"{s[:5] + ' res um':>12s} {s[:5] + ' a':>8s}" for s in STATIONS)
        + f" {'T-P max N':>10s} {'y gap':>8s} {'wall s':>7s}"
    )
    ref = result["1-D"][1]
    for name, value in result.items():
        if name in ("transverse", "preload"):
            continue
        metrics, histories, wall = value
        gap = "-" if name == "1-D" else f"{history_gap(histories, ref):.2e}"
        cells = " ".join(f"{metrics[s][0] * 1e6:12.2f} {metrics[s][1]:8.2f}" for s in STATIONS)
        print(f"{name:12s} {cells} {metrics['tension'] - result['preload']:10.1f} {gap:>8s} {wall:7.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="z = 6 only, quasi-static and default scenes")
    args = parser.parse_args()
    cases = [(6, 1e5, 45.0), (6, DEFAULT_PRELOAD_N, 180.0)]
    if not args.quick:
        cases = [
            (6, 1e5, 45.0),
            (12, 1e5, 45.0),
            (24, 1e5, 45.0),
            (6, DEFAULT_PRELOAD_N, 180.0),
            (12, DEFAULT_PRELOAD_N, 180.0),
        ]
    for teeth, preload, rpm in cases:
        print_comparison(
            f"z = {teeth}, N = {teeth + 18}, preload {preload:g} N, {rpm:g} rpm", compare(teeth, preload, rpm)
        )
    print_seat_changes(12, 1e5, 45.0, 3)
    if not args.quick:
        for teeth in (12, 6):
            print_seat_changes(teeth, 1e5, 45.0, 3, GUIDE_DAMPING_N_S_PER_M)


def print_seat_changes(teeth: int, preload_N: float, rpm: float, n_cycles: int, guide: float = 0.0) -> None:
    """Both models over n_cycles from rest with the seat change at each dwell, per cycle; the planar
    strands guided by a dashpot of `guide` N s/m across them on every free pin (0: free)."""
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=rpm)
    start = time.perf_counter()
    machine = dataclasses.replace(planar_machine(teeth, preload_N), guide_damping_N_s_per_m=guide)
    windows = relabelled_windows(machine, cam, n_cycles)
    strands = f"guided ({guide:g} N s/m across)" if guide else "free strands"
    print(
        f"\nseat changes: z = {teeth}, preload {preload_N:g} N, {rpm:g} rpm, {strands}, {n_cycles} cycles from "
        "rest (1-D / planar)"
    )
    print(
        f"{'cycle':5s} "
        + " ".join(f"{s[:5] + ' res um':>16s} {s[:5] + ' a':>14s}" for s in STATIONS)
        + f" {'T-P N':>14s} {'peak gap':>8s} {'across m/s':>10s}"
    )
    for i, (one_d, planar) in enumerate(windows):
        cells = " ".join(
            f"{one_d[s][0] * 1e6:7.2f}/{planar[s][0] * 1e6:<8.2f} {one_d[s][1]:6.2f}/{planar[s][1]:<7.2f}"
            for s in STATIONS
        )
        gap = max(abs(planar[s][1] / one_d[s][1] - 1) for s in STATIONS)
        print(
            f"{i + 1:5d} {cells} {one_d['tension'] - preload_N:6.1f}/{planar['tension'] - preload_N:<7.1f} "
            f"{gap:8.2%} {planar['across_m_s']:10.2e}"
        )
    print(f"({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
