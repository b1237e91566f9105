"""The sections of the mqp2012 preset's report.html, registered as the run's report's are
(reporting.sections): one builder per section, in the registry's order.

    from reporting.replica_sections import PAGE
    PAGE.register("my output", my_builder, before="time histories")
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from reporting import html
from reporting.sections import SectionRegistry
from reporting.tables import Table
from settings import RunConfig


@dataclass(frozen=True)
class ReplicaReport:
    """What a replica section builder reads."""

    cfg: RunConfig
    comparison: Table  # the replica against the report's Tables 1 and 2
    tables: dict[str, Table]  # rms_table and max_acceleration_table, as written
    figures: dict[str, dict[str, Path]]  # material -> caption label -> PNG


def run_section(report: ReplicaReport) -> list[html.Section]:
    cfg = report.cfg
    return [
        html.Section(
            "Run",
            html.paragraph(
                f"Preset mqp2012: the 2012 report's MATLAB model, quirks included (mm units inside, K(1,1) = 3k, "
                f"damping vector from sorted eigenfrequencies, preload acting as 2.224 N, friction ~500x too small). "
                f"N = {cfg.links}, {cfg.rpm:g} rpm, friction {cfg.friction:g}, from rest, 181 one-degree samples. "
                "Table 1's link is round(3N/4); Table 2's is floor(3N/4), as the report printed them."
            ),
        )
    ]


def comparison_section(report: ReplicaReport) -> list[html.Section]:
    return [html.Section("Against the report", html.table_html(report.comparison))]


def report_tables_section(report: ReplicaReport) -> list[html.Section]:
    body = html.table_html(report.tables["rms_table"]) + html.table_html(report.tables["max_acceleration_table"])
    return [html.Section("Tables 1 and 2", body)]


def time_histories_section(report: ReplicaReport) -> list[html.Section]:
    return [
        html.Section(f"Time histories: {m}", "".join(html.image_html(p, f"{m}: {label}") for label, p in f.items()))
        for m, f in report.figures.items()
    ]


PAGE = SectionRegistry()
for _name, _build in (
    ("run", run_section),
    ("against the report", comparison_section),
    ("tables 1 and 2", report_tables_section),
    ("time histories", time_histories_section),
):
    PAGE.register(_name, _build)
