"""The garbage collector paused for a process's imports (processes.pause_collector_for_imports,
imports_done): off during them, on after with everything made so far frozen, and nothing done
where it was not paused. Each case in a fresh interpreter: freezing this one's objects would keep
the test session's garbage for good."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    return out.stdout.strip().splitlines()[-1]


def test_the_collector_is_off_during_the_imports_and_on_after_with_their_objects_frozen():
    code = """
import gc
from processes import imports_done, pause_collector_for_imports
pause_collector_for_imports()
off = not gc.isenabled()
import colorsys
frozen_before = gc.get_freeze_count()
imports_done()
print(off, frozen_before == 0, gc.isenabled(), gc.get_freeze_count() > 0)
"""
    assert _run(code) == "True True True True"


def test_nothing_happens_where_the_collector_was_not_paused():
    code = """
import gc
from processes import imports_done, pause_collector_for_imports
imports_done()
unpaused = (gc.isenabled(), gc.get_freeze_count())
gc.disable()  # paused by someone else: left to them
pause_collector_for_imports()
imports_done()
print(unpaused == (True, 0), gc.isenabled(), gc.get_freeze_count())
"""
    assert _run(code) == "True False 0"


def test_the_runs_imports_end_the_pause_that_python_pipeline_py_starts():
    code = """
import gc
import pipeline
from processes import pause_collector_for_imports
pause_collector_for_imports()  # as `python pipeline.py` does before anything else
pipeline._import_chain_and_outputs(pipeline.parse_cli([]))
print(gc.isenabled(), gc.get_freeze_count() > 0)
"""
    assert _run(code) == "True True"
