"""Rigid seating against seating through the tooth stiffness on the default scene at three tooth
phases (docs/physics.md, the table "Tooth phase | Seating | Residual, station (mm) | ..."):

    python benchmarks/tooth_phase_table.py

The scene of benchmarks/seating_table.py at tooth phases 0, 0.25 and 0.75, each with rigid seating
(k_t = inf) and with the default tooth stiffness. Prints one line per row: phase, k_t (N/m), the
residual vibration at the tight strand's middle in the dwells (mm, max |x - z|), the peak |a| there
and at any place (m/s^2), the peak span force (N) and the `Seating` (the snap is its
`transfer_energy_change_J` plus its `impact_energy_J`).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.seating_table import CAM, DEFAULT_CHAIN, PHASES, default_scene, window_s  # noqa: E402
from dynamics.models.chain import ChainModel  # noqa: E402
from dynamics.models.wheels import DEFAULT_TOOTH_STIFFNESS_N_PER_M  # noqa: E402
from dynamics.scene import simulate_scene  # noqa: E402
from stages.machine import scene_machine  # noqa: E402

TOOTH_STIFFNESSES_N_PER_M = (np.inf, DEFAULT_TOOTH_STIFFNESS_N_PER_M)


def row(
    phase: float, tooth_stiffness_N_per_m: float, chain: ChainModel = DEFAULT_CHAIN, samples: int | None = None
) -> tuple:
    """(phase, k_t, residual at the station in mm, peak |a| at the station, peak |a| anywhere, peak
    span force, Seating) of one run over the window's first `samples` samples."""
    scene = default_scene(phase, tooth_stiffness_N_per_m)
    station = scene_machine(scene, chain).stations()["tight-side"]
    t = window_s(samples)
    dwell = CAM.dwell_mask(t)
    r, c = simulate_scene(scene, chain, CAM, t)
    residual_mm = 1e3 * np.max(np.abs(r.x_m[dwell, station] - r.z_m[dwell]))
    return (
        phase,
        tooth_stiffness_N_per_m,
        residual_mm,
        np.max(np.abs(r.a_m_s2[:, station])),
        np.max(np.abs(r.a_m_s2)),
        c.peak_tension_N,
        c.seating,
    )


if __name__ == "__main__":
    for p in PHASES:
        for k in TOOTH_STIFFNESSES_N_PER_M:
            print(*row(p, k))
