"""The default run's numbers the benchmarks run on, read from their homes, and the default link's FEA
figures they take as inputs.

The settings come from `settings.RunConfig()` (links, speed, friction, free play, samples per
degree) and the built-in link's dimensions (`geometry.dimensions`: its pitch, which its FEA
reports); a benchmark that departs from one says so where it does. The FEA figures are measured
(the built-in link's k and lumped mass per material as `python pipeline.py` computes them), not
settings: the benchmarks keep them fixed so that their times and errors compare across trees and
runs, and tests/test_benchmark_defaults.py (slow: it runs the pipeline's FEA, or reads its cache)
fails when the pipeline's k moves from them by more than its estimated error.
"""

from __future__ import annotations

from geometry.dimensions import LinkDimensions
from settings import RunConfig

DEFAULT_RUN = RunConfig()
PITCH_M = LinkDimensions().pitch_m
# FEA k (N/m) and lumped mass (kg: link body + default hardware + nest) per material: the pipeline's
# (python pipeline.py, 2026-11-26; its k estimated to 0.9 %)
MATERIALS = {"al6061-t6": (9.3249560e7, 2.0299986), "ti-grade2": (1.4155947e8, 2.2799977)}
