"""Rigid seating's verdict on the default scene at three tooth phases (docs/physics.md, the table
"Tooth phase | Cam speed at the seat change / peak | ..."):

    python benchmarks/seating_table.py

The default scene (benchmarks/impacts_on_wheels.py's, also tests/test_tooth_phase_validity.py's:
85 aluminium links, the default run's machine on its wheels, 180 rpm, modified sine, 0.094 mm free
play, the clearance machine, 180 cam degrees at 4 samples per degree) at tooth phases 0, 0.25 and
0.75. Prints one line per phase: the phase and `rigid_seating_validity` of the run's seat change
against the window's peak cam speed and acceleration.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.impacts_on_wheels import CAM, DEFAULT_CHAIN, DEFAULT_RUN, PITCH_M, window_s  # noqa: E402
from dynamics.models.chain import ChainModel  # noqa: E402
from dynamics.response.seating import rigid_seating_validity  # noqa: E402
from dynamics.scene import Scene, simulate_scene  # noqa: E402
from stages.chain import chain_scene  # noqa: E402

PHASES = (0.0, 0.25, 0.75)


def default_scene(phase: float, tooth_stiffness_N_per_m: float = np.inf) -> Scene:
    """The default scene with the wheels' teeth at `phase` (of a pitch) and that tooth stiffness
    (inf: rigid seating)."""
    scene = chain_scene(replace(DEFAULT_RUN, tooth_phase=phase), PITCH_M)
    return replace(scene, layout=replace(scene.layout, tooth_stiffness_N_per_m=tooth_stiffness_N_per_m))


def seat_change_run(phase: float, chain: ChainModel = DEFAULT_CHAIN, samples: int | None = None):
    """(the run's seat change, the window's peak cam speed, its peak cam acceleration) at `phase`:
    what rigid seating's verdict is decided on (also tests/test_tooth_phase_validity.py's runs)."""
    response, contact = simulate_scene(default_scene(phase), chain, CAM, window_s(samples))
    return contact.seating, float(np.max(np.abs(response.zdot_m_s))), float(np.max(np.abs(response.zddot_m_s2)))


def verdict(phase: float, chain: ChainModel = DEFAULT_CHAIN, samples: int | None = None):
    """Rigid seating's verdict on the run at `phase`: its seat change against the window's peak cam
    speed and acceleration."""
    return rigid_seating_validity(*seat_change_run(phase, chain, samples))


if __name__ == "__main__":
    for p in PHASES:
        print(p, verdict(p))
