"""On-disk cache of FEA results, so a run that changes only the cam, speed or chain does not re-solve.

An entry is keyed by everything the FEA result depends on: the geometry file's bytes (or the
default link's dimensions: `geometry.Part.fingerprint`), the material's properties, the mesh and element settings, and the
cache format version. It holds the result as JSON and, when made, the rendered image.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from geometry.atomic import atomic_target

from .errors import FemError

CACHE_FORMAT = 5  # 2: k is the Richardson-extrapolated value; 3: FEA warnings stored; 4: finest level on the mirror half; 5: small holes refined locally, curved cells kept away from the bores, memory budget


def default_cache_dir() -> Path:
    root = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(root) / "link-conveyor" / "fea"


def cache_key(geometry_fingerprint: str, settings: dict) -> str:
    payload = json.dumps(
        {"format": CACHE_FORMAT, "geometry": geometry_fingerprint, "settings": settings},
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:32]


@dataclass(frozen=True)
class FeaCache:
    directory: Path

    def _entry(self, key: str) -> Path:
        return self.directory / key

    def load(self, key: str) -> dict | None:
        try:
            return json.loads((self._entry(key) / "result.json").read_text())
        except (OSError, ValueError):
            return None

    def load_levels(self, key: str) -> dict:
        """The solved levels' records kept under `key` (fem.adaptive.level_records; empty: none). A
        file there that is not a JSON object (cut short, or written by something else) is a FemError
        naming it: the caller decides whether to go on without it."""
        path = self._entry(key) / "levels.json"
        try:
            text = path.read_text()
        except FileNotFoundError:
            return {}
        except (OSError, UnicodeDecodeError) as exc:
            raise FemError(f"{path}: not readable ({exc})") from None
        try:
            records = json.loads(text)
        except ValueError as exc:
            raise FemError(f"{path}: not JSON ({exc})") from None
        if not isinstance(records, dict):
            raise FemError(f"{path}: expected a JSON object of solved levels, got a {type(records).__name__}")
        return records

    def store_levels(self, key: str, records: dict) -> None:
        """Replace the levels kept under `key` by `records`, atomically (a reader sees the old file or
        the new one, whole); to add to them, hold `levels_locked(key)` across the load and the store."""
        entry = self._entry(key)
        entry.mkdir(parents=True, exist_ok=True)
        write_text_atomic(entry / "levels.json", json.dumps(records, sort_keys=True))

    @contextmanager
    def levels_locked(self, key: str) -> Iterator[None]:
        """An exclusive lock on the levels kept under `key` (fcntl.flock on a lock file beside them,
        released when the block ends or the process dies): runs that share the cache and each load,
        add to and store the levels under it keep each other's levels."""
        entry = self._entry(key)
        entry.mkdir(parents=True, exist_ok=True)
        with open(entry / "levels.lock", "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def image_path(self, key: str) -> Path:
        return self._entry(key) / "deformed.png"

    def store(self, key: str, result: dict) -> None:
        entry = self._entry(key)
        entry.mkdir(parents=True, exist_ok=True)
        write_text_atomic(entry / "result.json", json.dumps(result, indent=1, sort_keys=True))


def write_text_atomic(path: Path, text: str) -> None:
    with atomic_target(path) as tmp:
        tmp.write_text(text)
