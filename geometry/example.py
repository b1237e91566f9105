"""The shipped example STEP file: the default link as an exporter might write it.

Its bores are split into half-cylinder faces, their top edges chamfered and bottom edges filleted
(1 mm), and it is written in millimetres, so `load_link(EXAMPLE_STEP)` exercises the real import
path (units, face grouping, holes told from the coaxial lug ends, cones and tori ignored).
Regenerate it with
`python -c "from geometry.example import write_example_step; write_example_step()"`.
"""

from __future__ import annotations

import os
from pathlib import Path

from geometry.dimensions import DEFAULT_LINK
from geometry.parametric import LinkFeatures
from geometry.step_io import write_step

EXAMPLE_STEP = Path(__file__).with_name("data") / "example_link.step"
EXAMPLE_FEATURES = LinkFeatures(split_bores=True, bore_edge_break_m=0.001)


def write_example_step(path: str | os.PathLike = EXAMPLE_STEP) -> Path:
    return write_step(DEFAULT_LINK, path, unit="mm", features=EXAMPLE_FEATURES)
