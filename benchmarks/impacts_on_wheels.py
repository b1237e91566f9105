"""The seating and impact figures of the default scene on its wheels (docs/physics.md, "The machine
on its wheels"):

    python benchmarks/impacts_on_wheels.py

85 aluminium links (k = 9.331e7 N/m, 2.0296 kg with the hardware), the default run's scene on its
wheels (settings.RunConfig() through stages.chain.chain_scene: two 12-tooth wheels, six links seated
on each, the default wheel inertia, 0.094 mm free play, global damping, the model chosen
automatically, the periodic steady state), its damping ratio and preload but no guide friction,
180 rpm, modified sine, the pipeline's output grid (180 cam degrees at 4 samples per degree). Prints
one line: the `Seating` (seating speeds in m/s, impact energies and the transfer's change of stored
energy in J), the impacts per cycle, the peak span force (N) and the `ImpactStatistics`.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from benchmarks.defaults import DEFAULT_RUN, PITCH_M  # noqa: E402
from dynamics.cams import CamProgram  # noqa: E402
from dynamics.models.chain import ChainModel  # noqa: E402
from dynamics.scene import simulate_scene  # noqa: E402
from stages.chain import chain_scene, output_times_s  # noqa: E402

# The default aluminium link's FEA figures (python -m fem): k, and the lumped mass with the default
# hardware and nest; measured inputs of docs/physics.md's figures, not settings.
LINK_STIFFNESS_N_PER_M, LINK_MASS_KG = 9.331e7, 2.0296
# without guide friction (RunConfig's is 0.35): the figures in docs/physics.md are the impacts alone
DEFAULT_CHAIN = ChainModel(
    DEFAULT_RUN.links,
    LINK_MASS_KG,
    LINK_STIFFNESS_N_PER_M,
    damping_ratio=DEFAULT_RUN.damping,
    preload_N=DEFAULT_RUN.preload_N,
    friction_coefficient=0.0,
)
CAM = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=DEFAULT_RUN.rpm)


def window_s(samples: int | None = None):
    """The pipeline's output grid (180 cam degrees at the default samples per degree), its first
    `samples` (None: all)."""
    return output_times_s(DEFAULT_RUN.rpm, DEFAULT_RUN.samples_per_degree)[:samples]


def contact_summary(chain: ChainModel = DEFAULT_CHAIN, samples: int | None = None):
    """The ContactSummary of `chain` on the default machine over its first `samples` output samples."""
    return simulate_scene(chain_scene(DEFAULT_RUN, PITCH_M), chain, CAM, window_s(samples))[1]


if __name__ == "__main__":
    c = contact_summary()
    print(c.seating, c.impacts_per_cycle, c.peak_tension_N, c.impacts)
