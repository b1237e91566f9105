"""One bounded cache for what the solvers derive from a system: modes, step matrices, periodic LUs.

Keys start with a label and hold the system's `cache_key` (its matrices' contents, computed once
per system), so equal systems share entries and a speed sweep or a set of cams on one chain
computes each derived matrix once. Least recently used entries go first.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import TypeVar

SIZE = 32

_entries: OrderedDict = OrderedDict()
_MISSING = object()
T = TypeVar("T")


def cached(key: tuple, compute: Callable[[], T]) -> T:
    hit = _entries.get(key, _MISSING)
    if hit is not _MISSING:  # None is a result too (a system without classical modes)
        _entries.move_to_end(key)
        return hit
    result = compute()
    _entries[key] = result
    if len(_entries) > SIZE:
        _entries.popitem(last=False)
    return result


def clear() -> None:
    """Forget every entry (benchmarks time cold runs after this)."""
    _entries.clear()


def size() -> int:
    return len(_entries)
