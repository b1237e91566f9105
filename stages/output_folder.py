"""Whether --out can take a run's outputs, checked before any work (both orchestrators)."""

from __future__ import annotations

import tempfile
from pathlib import Path


def out_folder_problem(out: Path, *, create: bool) -> str | None:
    """Why `out` cannot be written, as a one-line message naming --out, or None when it can.

    create=True makes the folder first (pipeline.py); create=False probes its nearest existing
    parent instead, so that a run refused later (a bad study file) leaves nothing behind."""
    if out.exists() and not out.is_dir():
        return f"--out: {str(out)!r} exists and is not a folder"
    try:
        if create:
            out.mkdir(parents=True, exist_ok=True)
        probe = out if out.exists() else next((p for p in out.absolute().parents if p.exists()), Path("/"))
        with tempfile.NamedTemporaryFile(dir=probe, prefix=".write-test-"):
            pass
    except OSError as e:
        return f"--out: cannot write to {str(out)!r} ({e.strerror or e})"
    return None
