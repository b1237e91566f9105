"""report.html is built from a list of section builders: one registered builder is one new section;
the chain model's warning style comes from the result's validity field, not from its words."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

import pipeline
from dynamics.scene import ChainModelKind, Validity
from reporting import html, sections

COARSE = [
    "--mesh-size",
    "10",
    "--drive",
    "link",
    "--links",
    "12",
    "--samples-per-degree",
    "2",
    "--no-images",
    "-q",
    "--materials",
    "al6061-t6",
    "--cams",
    "modified-sine,cycloidal",
]


@pytest.fixture
def registry(monkeypatch):
    """The section list, restored after the test."""
    monkeypatch.setattr(sections.PAGE, "entries", list(sections.PAGE.entries))


def _cam_count(report: sections.Report) -> list[html.Section]:
    cams = sorted({cam for _, cam in report.results.scenarios})
    return [html.Section("Cam laws simulated", html.paragraph(f"{len(cams)} cam laws: {', '.join(cams)}"))]


def test_a_registered_section_builder_shows_up_in_the_report(registry, tmp_path):
    sections.register_section("cam count", _cam_count, before="timing")
    assert sections.section_names()[-2:] == ("cam count", "timing")
    out = tmp_path / "out"
    assert pipeline.main([*COARSE, "--out", str(out), "--cache-dir", str(tmp_path / "cache")]) == 0
    page = (out / "report.html").read_text()
    assert ">Cam laws simulated</h2><p>2 cam laws: cycloidal, modified-sine</p>" in page
    assert page.index("Cam laws simulated</h2>") < page.index(">Timing</h2>")


def test_section_names_are_unique_and_before_must_exist(registry):
    with pytest.raises(ValueError, match="already registered"):
        sections.register_section("timing", _cam_count)
    with pytest.raises(ValueError, match="no section 'appendix'"):
        sections.register_section("cam count", _cam_count, before="appendix")


def _results(validity: Validity, reason: str):
    contact = SimpleNamespace(
        model=ChainModelKind.LINEAR,
        reason=reason,
        validity=validity,
        linear_min_tension_N=-500.0,
        steady_state=None,
        linear_model_validity=None,
    )
    return SimpleNamespace(scenarios={("al6061-t6", "modified-sine"): SimpleNamespace(contact=contact)})


@pytest.mark.parametrize(
    "validity, warned", [(Validity.VALID, False), (Validity.NOT_VALID_WHERE_TENSION_NEGATIVE, True)]
)
def test_the_model_paragraph_is_a_warning_by_the_validity_field(validity, warned):
    # the same words either way: the style follows the data
    text = sections._model_paragraphs(_results(validity, "a reason that says nothing of validity"))
    assert text.startswith('<p class="warn">') == warned and "Model: linear chain" in text


def _replica_note(report) -> list[html.Section]:
    return [html.Section("Replica note", html.paragraph(f"{report.cfg.links} links, as the 2012 script"))]


def test_the_replica_page_is_built_from_its_own_registered_sections(monkeypatch, tmp_path):
    from reporting import replica_sections

    assert replica_sections.PAGE.names() == ("run", "against the report", "tables 1 and 2", "time histories")
    monkeypatch.setattr(replica_sections.PAGE, "entries", list(replica_sections.PAGE.entries))
    replica_sections.PAGE.register("replica note", _replica_note, before="time histories")
    out = tmp_path / "replica"
    args = ["--preset", "mqp2012", "--links", "24", "--cams", "modified-sine", "-q", "--out", str(out)]
    assert pipeline.main(args) == 0
    page = (out / "report.html").read_text()
    titles = ["Run", "Against the report", "Tables 1 and 2", "Replica note", "Time histories: al6061-t6"]
    positions = [page.index(f">{title}</h2>") for title in titles]
    assert positions == sorted(positions)
    assert "<p>24 links, as the 2012 script</p>" in page
