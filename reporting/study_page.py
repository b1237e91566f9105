"""The design study's HTML page: counts, the constraints and objectives, the Pareto front (table
and plot), metrics against variables, the parallel-coordinates view, why points were infeasible,
the optimiser's history and links to the best designs' full reports. Same HTML and table code as
pipeline.py's report.html (reporting.html, reporting.tables)."""

from __future__ import annotations

import html as _html
from pathlib import Path

from reporting.html import Section, image_html, paragraph, render_page, table_html
from reporting.study_plots import display_unit
from reporting.tables import Table


def design_table(title: str, rows: list[dict], columns: list[str], limit: int = 50) -> Table:
    """Rows of the study table in display units (mm, MPa, kN), at most `limit` of them."""
    header, factors = zip(
        *(display_unit(c) if c not in ("point", "geometry_file", "material", "cam") else (c, None) for c in columns)
    )
    body = tuple(
        tuple(
            r.get(c) if f is None or r.get(c) is None or isinstance(r.get(c), bool) else float(r[c]) * f
            for c, f in zip(columns, factors)
        )
        for r in rows[:limit]
    )
    more = f" (first {limit} of {len(rows)})" if len(rows) > limit else ""
    return Table(title + more, tuple(header), body)


def reason_table(counts: dict[str, int]) -> Table:
    return Table("Points not computed, by reason", ("reason", "points"), tuple(sorted(counts.items())))


def links_html(links: list[tuple[str, str]]) -> str:
    items = "".join(f'<li><a href="{_html.escape(href)}">{_html.escape(text)}</a></li>' for text, href in links)
    return f"<ul>{items}</ul>"


def write_study_page(
    path: Path,
    title: str,
    intro: list[str],
    tables: list[Table],
    figures: list[tuple[str, Path, str]],
    reports: list[tuple[str, str]],
    optimiser: tuple[list[str], Table | None, Path | None] | None,
) -> Path:
    """figures: (section title, png, caption); reports: (label, relative href)."""
    sections = [Section("Summary", "".join(paragraph(t) for t in intro) + "".join(table_html(t) for t in tables))]
    sections += [Section(name, image_html(png, caption)) for name, png, caption in figures]
    if optimiser is not None:
        notes, table, png = optimiser
        body = "".join(paragraph(n) for n in notes) + (table_html(table) if table else "")
        sections.append(
            Section("Optimisation", body + (image_html(png, "best objective per generation") if png else ""))
        )
    if reports:
        sections.append(Section("Full reports of the best designs", links_html(reports)))
    path.write_text(render_page(title, sections))
    return path
