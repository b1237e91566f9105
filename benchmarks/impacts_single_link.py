"""The impact statistics of the default scene on the single-link drive (docs/physics.md, "Impacts"):

    python benchmarks/impacts_single_link.py

85 links of the default aluminium link (benchmarks/bench_accuracy.py's first scene: k and mass from
the FEA, friction 0.35), 180 rpm, modified sine, 0.094 mm free play, global damping; the periodic
steady state, 180 cam degrees at 4 samples per degree, stepped by the euler predictor at 0.25 of its
stability limit (the step the physics.md figures were measured with). Prints one line: the impacts
per cycle, the peak span force (N) and the clearance chain's `ImpactStatistics` (closing speeds in
m/s, force spike in N, energies in J per cycle).
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.bench_accuracy import SCENES  # noqa: E402
from dynamics.models.chain import ChainModel  # noqa: E402
from dynamics.models.clearance import ClearanceChain  # noqa: E402
from dynamics.scene import simulate_chain  # noqa: E402

PREDICTOR = "euler"
SAFETY = 0.25  # of the predictor's stability limit


def contact_summary(n_links: int = SCENES[0].n_links, samples: int = 721):
    """The ContactSummary of the default scene with `n_links` links over its first `samples` output
    samples (4 per cam degree)."""
    scene = SCENES[0]
    chain = ChainModel(n_links, scene.link_mass_kg, scene.stiffness_N_per_m, friction_coefficient=0.35)
    cam, t = scene.window()
    model = ClearanceChain(chain, scene.clearance_m, span_damping=scene.span_damping)
    return simulate_chain(model, cam, t[:samples], predictor=PREDICTOR, safety=SAFETY)[1]


if __name__ == "__main__":
    c = contact_summary()
    print(c.impacts_per_cycle, c.peak_tension_N, c.impacts)
