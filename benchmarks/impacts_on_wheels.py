"""The seating and impact figures of the default scene on its wheels (docs/physics.md, "The machine
on its wheels"):

    python benchmarks/impacts_on_wheels.py

85 aluminium links (k = 9.331e7 N/m, 2.0296 kg with the hardware), the default layout
(benchmarks/bench_machine.py: two 12-tooth wheels, six links seated on each, steel-disc inertia),
180 rpm, modified sine, 0.094 mm free play, global damping, the model chosen automatically, the
periodic steady state, 180 cam degrees at 4 samples per degree. Prints one line: the `Seating`
(seating speeds in m/s, impact energies and the transfer's change of stored energy in J), the
impacts per cycle, the peak span force (N) and the `ImpactStatistics`.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.bench_machine import layout  # noqa: E402
from dynamics.cams import CamProgram  # noqa: E402
from dynamics.models.chain import ChainModel  # noqa: E402
from dynamics.scene import Scene, simulate_scene  # noqa: E402

DEFAULT_CHAIN = ChainModel(85, 2.0296, 9.331e7)
CAM = CamProgram.indexing("modified-sine", pitch_m=0.1125, rpm=180)


def contact_summary(chain: ChainModel = DEFAULT_CHAIN, samples: int = 721):
    """The ContactSummary of `chain` on the default machine over its first `samples` output samples."""
    scene = Scene(94e-6, "global", None, "auto", True, "exact", layout())
    return simulate_scene(scene, chain, CAM, np.arange(samples) / 4 / 1080)[1]


if __name__ == "__main__":
    c = contact_summary()
    print(c.seating, c.impacts_per_cycle, c.peak_tension_N, c.impacts)
