"""README.md's table of what each part of the machine changes on the default scene (issue #22) is the
output of benchmarks/machine_parts.py: every row's f1, residual and peak recomputed
(`machine_parts.readme_rows`, the script's own computation) and compared with the README's printed
figures to their printed rounding, so a change of the model that changes the table fails here. About
a minute (the two polygonal rows run the reference integrator), so slow."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from benchmarks import machine_parts
from dynamics.cams import CamProgram
from dynamics.models.wheels import pitch_radius_m, steel_disc_inertia_kg_m2

README = Path(__file__).resolve().parent.parent / "README.md"
HEADER = "| Machine | f1 (Hz) | Residual (mm) | Peak (m/s²) |"
# what names each row in the README, in the script's order
ROW_KEYS = (
    "--drive link",
    "held to the cam",
    "drive compliance",
    "sprocket inertia",
    "idler wheel",
    "polygonal action alone",
    "all together",
)


def readme_table() -> list[list[str]]:
    """The table's rows (cells, stripped) under its header, up to the first line that is no row."""
    lines = README.read_text(encoding="utf-8").splitlines()
    start = lines.index(HEADER) + 2  # past the header and its |---| line
    rows = []
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
    return rows


def printed(cell: str) -> tuple[float, float]:
    """A printed figure (a footnote's * dropped) and half a unit of its last digit."""
    number = cell.rstrip("*")
    decimals = len(number.split(".")[1]) if "." in number else 0
    return float(number), 0.5 * 10.0**-decimals


def test_the_readme_table_has_one_row_per_configuration_of_the_script():
    rows = readme_table()
    assert len(rows) == len(ROW_KEYS) == len(machine_parts.machines(True)[0])
    for cells, key in zip(rows, ROW_KEYS):
        assert key in cells[0] and len(cells) == 4
    j = steel_disc_inertia_kg_m2(pitch_radius_m(machine_parts.PITCH_M, machine_parts.TEETH), 0.025)
    inertia = re.search(r"steel disc, ([0-9.]+) kg", rows[3][0])
    assert inertia and abs(j - float(inertia.group(1))) <= printed(inertia.group(1))[1]


@pytest.mark.slow
def test_every_row_of_the_readme_table_is_what_the_script_computes():
    cam = CamProgram.indexing("modified-sine", pitch_m=machine_parts.PITCH_M, rpm=180.0)
    computed = machine_parts.readme_rows(cam)
    for cells, (name, f1_Hz, residual_m, peak_m_s2) in zip(readme_table(), computed):
        for cell, value in zip(cells[1:], (f1_Hz, residual_m * 1e3, peak_m_s2)):
            figure, half_unit = printed(cell)
            assert abs(value - figure) <= half_unit * (1 + 1e-9), (
                f"README row {cells[0]!r} ({name}): {cell} against {value}"
            )
