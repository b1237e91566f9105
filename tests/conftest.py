"""Fixtures shared by the test modules."""

from pathlib import Path

import pytest


@pytest.fixture
def existing_out(tmp_path) -> Path:
    """An output folder holding an earlier run's summary.json, which a refused run must leave as it is."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}')
    return out
