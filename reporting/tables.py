"""The report's tables (1, 2 and 4 layout) and the cam ranking, as CSV and Markdown.

Values are passed in SI; the tables show mm, mm/s and mm/s^2 like the 2012 report, so the two can
be read side by side. Percent difference is (link - input) / input * 100 (the report's Table 3
convention).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

QUANTITY_UNITS = {
    "displacement": ("mm", 1e3),
    "velocity": ("mm/s", 1e3),
    "acceleration": ("mm/s²", 1e3),
}


@dataclass(frozen=True)
class Table:
    """A titled table; `header` and each row have the same length. Numbers stay numbers until written."""

    title: str
    header: tuple[str, ...]
    rows: tuple[tuple, ...]

    def to_csv(self) -> str:
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(self.header)
        writer.writerows(self.rows)
        return buf.getvalue()

    def to_markdown(self) -> str:
        lines = [f"### {self.title}", "", _md_row(self.header), "|" + "|".join("---" for _ in self.header) + "|"]
        lines += [_md_row(_fmt(v) for v in row) for row in self.rows]
        return "\n".join(lines) + "\n"


def _md_row(cells) -> str:
    return "| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |"


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) < 1e5 else f"{value:.3e}"
    return str(value)


def percent_difference(link: float, reference: float) -> float:
    return (link - reference) / reference * 100.0


def rms_table(
    input_rms: dict[str, dict[str, float]], link_rms: dict[str, dict[str, dict[str, float]]], link: int
) -> Table:
    """Table 1/4 layout. input_rms[cam][quantity], link_rms[material][cam][quantity], SI values."""
    materials = list(link_rms)
    header = ("quantity", "cam law", "cam input")
    header += tuple(f"{m} link {link}" for m in materials)
    header += tuple(f"{m} % difference" for m in materials)
    rows = []
    for quantity, (unit, scale) in QUANTITY_UNITS.items():
        for cam, values in input_rms.items():
            ref = values[quantity]
            links = [link_rms[m][cam][quantity] for m in materials]
            rows.append(
                (
                    f"RMS {quantity} ({unit})",
                    cam,
                    ref * scale,
                    *[v * scale for v in links],
                    *[round(percent_difference(v, ref), 2) for v in links],
                )
            )
    return Table(f"RMS of the cam input and of link {link}", header, tuple(rows))


def max_acceleration_table(max_acc_m_s2: dict[str, dict[str, float]], link: int) -> Table:
    """Table 2 layout: max |acceleration| of one link, max_acc_m_s2[material][cam]."""
    materials = list(max_acc_m_s2)
    cams = list(next(iter(max_acc_m_s2.values())))
    rows = tuple((cam, *[max_acc_m_s2[m][cam] * 1e3 for m in materials]) for cam in cams)
    return Table(f"Maximum acceleration of link {link} (mm/s²)", ("cam law", *materials), rows)
