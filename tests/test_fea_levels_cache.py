"""The --tolerance runs' FEA levels in the cache (stages.fea.store_levels / stored_levels): runs that
share a cache keep each other's levels, a reader never sees half a file, and a levels file that cannot
be read is ignored with a warning (its levels are solved again), not a crash."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import pytest

from fem.adaptive import SolvedLevel
from fem.cache import FeaCache
from fem.errors import FemError
from settings import RunConfig
from stages.fea import _levels_key, store_levels, stored_levels

PART = SimpleNamespace(fingerprint="a part of the levels tests")  # what the levels' key reads of a part
STORES_PER_RUN = 40
ROOT = Path(__file__).resolve().parents[1]

# One run's stores: after each (fake) level it solves, it stores its levels so far, as
# stages.tolerance does after each pass. It starts when the test writes a line to its stdin.
RUN = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    from types import SimpleNamespace

    from fem.adaptive import SolvedLevel
    from settings import RunConfig
    from stages.fea import store_levels

    name, cache_dir, stores = sys.argv[1], sys.argv[2], int(sys.argv[3])
    cfg, part = RunConfig(cache_dir=Path(cache_dir)), SimpleNamespace(fingerprint="a part of the levels tests")
    level = SolvedLevel(2, 1e8, 1000, 2000, 0.01, 2.0, 7e-4, 0.1125, 0.01, 1e5, 5e4, {})
    levels = {}
    print("ready", flush=True)
    sys.stdin.readline()
    for i in range(stores):
        levels[f"{name} {i}"] = level
        store_levels(cfg, part, levels)
    """
)


def _level(k: float) -> SolvedLevel:
    return SolvedLevel(2, k, 1000, 2000, 0.01, 2.0, 7e-4, 0.1125, 0.01, 1e5, 5e4, {"solve": 0.5})


def _levels_file(cache_dir: Path) -> Path:
    return cache_dir / _levels_key(PART) / "levels.json"


def test_two_runs_storing_at_once_keep_each_others_levels(tmp_path):
    """Two processes store their growing levels 40 times each at the same time, while this one reads
    them: every read is a whole file, and the cache ends with both runs' levels."""
    runs = [
        subprocess.Popen(
            [sys.executable, "-c", RUN, name, str(tmp_path), str(STORES_PER_RUN)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=ROOT,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
        )
        for name in ("first", "second")
    ]
    for run in runs:
        assert run.stdout.readline() == "ready\n"
    for run in runs:
        run.stdin.write("go\n")
        run.stdin.flush()
    cache = FeaCache(tmp_path)
    while any(run.poll() is None for run in runs):
        cache.load_levels(_levels_key(PART))  # a FemError here: a reader saw half a file
    assert [run.wait() for run in runs] == [0, 0]
    kept = stored_levels(RunConfig(cache_dir=tmp_path), PART)
    assert set(kept) == {f"{name} {i}" for name in ("first", "second") for i in range(STORES_PER_RUN)}
    assert not list(_levels_file(tmp_path).parent.glob(".levels.json.tmp.*"))  # no temporary file left


@pytest.mark.parametrize(
    "text",
    ['{"level at 1 mm": {"order": 2, "stiff', "[]", '{"level at 1 mm": {"k": 1e8}}', '{"level at 1 mm": 3}'],
    ids=["cut short", "not an object", "not a level", "a whole number"],
)
def test_a_levels_file_that_cannot_be_read_is_ignored_with_a_warning(tmp_path, capsys, text):
    cfg = RunConfig(cache_dir=tmp_path)
    store_levels(cfg, PART, {"level at 1 mm": _level(1e8)})
    _levels_file(tmp_path).write_text(text)
    assert stored_levels(cfg, PART) == {}
    warning = capsys.readouterr().err
    assert warning.count("\n") == 1 and "warning: FEA cache:" in warning and "its levels are solved again" in warning
    # the next store replaces it by its own levels, and says so
    store_levels(cfg, PART, {"level at 2 mm": _level(9e7)})
    assert "replaced by this run's levels" in capsys.readouterr().err
    assert stored_levels(cfg, PART) == {"level at 2 mm": _level(9e7)}


def test_stored_levels_are_added_to_not_replaced(tmp_path):
    cfg = RunConfig(cache_dir=tmp_path)
    store_levels(cfg, PART, {"level at 1 mm": _level(1e8), "mesh seconds at 1 mm": 0.25})
    store_levels(cfg, PART, {"level at 2 mm": _level(9e7)})
    assert stored_levels(cfg, PART) == {
        "level at 1 mm": _level(1e8),
        "mesh seconds at 1 mm": 0.25,
        "level at 2 mm": _level(9e7),
    }


def test_a_missing_levels_file_is_no_levels_and_no_warning(tmp_path, capsys):
    assert stored_levels(RunConfig(cache_dir=tmp_path), PART) == {}
    assert capsys.readouterr().err == ""


def test_an_unreadable_levels_file_is_a_fem_error_at_the_cache(tmp_path):
    cache = FeaCache(tmp_path)
    cache.store_levels("key", {})
    (tmp_path / "key" / "levels.json").write_bytes(b"\xff\xfe{")
    with pytest.raises(FemError, match="levels.json: not readable"):
        cache.load_levels("key")
