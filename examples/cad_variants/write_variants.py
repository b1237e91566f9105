"""Write the three CAD variants of examples/cad_variants.toml: the built-in link with a 5 mm,
6.858 mm (the default) and 9 mm web, everything else the default link's. Each is written as the
shipped example STEP file is (geometry/example.py: millimetres, split bores, 1 mm edge breaks), so
the study reads them through the real import path. Regenerate them from the repository's root with

    python examples/cad_variants/write_variants.py
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # run as a script from anywhere

from geometry.dimensions import DEFAULT_LINK  # noqa: E402
from geometry.example import EXAMPLE_FEATURES  # noqa: E402
from geometry.step_io import write_step  # noqa: E402

HERE = Path(__file__).parent
WEBS_M = {
    "link_web_5mm.step": 0.005,
    "link_web_6.858mm.step": DEFAULT_LINK.web_thickness_m,  # the default link's web
    "link_web_9mm.step": 0.009,
}


def write_variants(folder: Path = HERE) -> list[Path]:
    return [
        write_step(replace(DEFAULT_LINK, web_thickness_m=web), folder / name, unit="mm", features=EXAMPLE_FEATURES)
        for name, web in WEBS_M.items()
    ]


if __name__ == "__main__":
    for path in write_variants():
        print(f"{path.name}: {path.stat().st_size / 1000:.0f} kB")
