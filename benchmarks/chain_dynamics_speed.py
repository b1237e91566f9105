"""Speed of the default chain dynamics: 5 cam laws x 2 materials, N = 85, 1800 one-degree samples.

    .venv/bin/python benchmarks/chain_dynamics_speed.py [--repeat 3]

Prints wall and CPU times for the 10 runs, cold (first call per chain: eigen-
decomposition, matrix exponential, periodic-state factorisation) and warm (cached). Uses the
report's link figures in SI (Al 92696969.7 N/m, 2.03 kg; Ti 143884892.1 N/m, 2.28 kg).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from dynamics.cams.program import CamProgram
from dynamics.chain import ChainModel
from dynamics.simulate import SlackChainWarning, simulate

LAWS = ("modified-sine", "modified-trapezoid", "cycloidal", "poly-345", "poly-4567")
MATERIALS = {"Al": (92696969.7, 2.03), "Ti": (143884892.1, 2.28)}


def sweep(mu: float, t: np.ndarray) -> tuple[float, float]:
    """(wall, CPU) seconds for the 10 runs; CPU time is the steadier figure on a shared machine."""
    wall, cpu = time.perf_counter(), time.process_time()
    for k, m in MATERIALS.values():
        model = ChainModel(85, m, k, friction_coefficient=mu)
        for law in LAWS:
            simulate(model, CamProgram.indexing(law), t)
    return time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    t = np.arange(1800) * ((1 / 3) / 360)
    warnings.simplefilter("ignore", SlackChainWarning)
    for mu in (0.0, 0.35):
        runs = [sweep(mu, t) for _ in range(args.repeat)]
        warm = min(runs[1:] or runs)
        print(
            f"mu = {mu}: 10 runs cold {runs[0][0]:.3f} s wall / {runs[0][1]:.3f} s CPU, "
            f"warm best {warm[0]:.3f} s wall / {warm[1]:.3f} s CPU"
        )


if __name__ == "__main__":
    main()
