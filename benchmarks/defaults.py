"""The default run's numbers the benchmarks run on, read from their homes, and the default link's FEA
figures they take as inputs.

The settings come from `settings.RunConfig()` (links, speed, friction, free play, samples per
degree) and the built-in link's dimensions (`geometry.dimensions`: its pitch, which its FEA
reports); a benchmark that departs from one says so where it does. The FEA figures are measured
(`python -m fem` on the built-in link), not settings: the benchmarks keep them fixed so that their
times and errors compare across trees and runs.
"""

from __future__ import annotations

from geometry.dimensions import LinkDimensions
from settings import RunConfig

DEFAULT_RUN = RunConfig()
PITCH_M = LinkDimensions().pitch_m
# FEA k (N/m) and lumped mass (kg: link body + default hardware + nest) per material
MATERIALS = {"al6061-t6": (9.0092e7, 2.03), "ti-grade2": (1.3696e8, 2.28)}
