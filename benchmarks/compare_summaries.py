"""Two runs' summary.json compared number by number (docs/verification.md: a change that must keep
the default run's numbers):

    python benchmarks/compare_summaries.py OLD/summary.json NEW/summary.json [--ignore KEY ...]

Both files are flattened to their leaves (`materials.al6061-t6.cams.poly-345.peak_tension_N`, ...);
the keys given with --ignore (default: `timing_s`, the stages' wall times) are left out wherever they
are. Prints each leaf that differs (numbers with their relative difference) and a last line: the
number of differing leaves and the largest relative difference, or that the two are identical.
Exit status 0 when identical, 1 when not.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

IGNORED = ("timing_s",)


def leaves(tree, ignore: tuple[str, ...] = IGNORED, prefix: str = "") -> dict[str, object]:
    """{dotted path: value} of every leaf of a JSON tree (list items by index), `ignore`d keys left out."""
    if isinstance(tree, dict):
        items = ((str(k), v) for k, v in tree.items() if k not in ignore)
    elif isinstance(tree, list):
        items = ((str(i), v) for i, v in enumerate(tree))
    else:
        return {prefix: tree}
    out: dict[str, object] = {}
    for key, value in items:
        out.update(leaves(value, ignore, f"{prefix}.{key}" if prefix else key))
    return out


def relative_difference(old, new) -> float | None:
    """|new - old| / |old| of two numbers (inf where old is 0 and new is not); None: not both numbers."""
    numbers = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (old, new))
    if not numbers:
        return None
    if old == new:
        return 0.0
    return abs(new - old) / abs(old) if old != 0 else math.inf


def differences(
    old: dict, new: dict, ignore: tuple[str, ...] = IGNORED
) -> list[tuple[str, object, object, float | None]]:
    """(path, old, new, relative difference or None) of every leaf that differs or is in one file only."""
    a, b = leaves(old, ignore), leaves(new, ignore)
    missing = object()
    out = []
    for path in sorted(a.keys() | b.keys()):
        x, y = a.get(path, missing), b.get(path, missing)
        if x != y or type(x) is not type(y):
            x, y = (None if v is missing else v for v in (x, y))
            out.append((path, x, y, relative_difference(x, y)))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--ignore", nargs="*", default=list(IGNORED), help="keys left out wherever they are")
    args = parser.parse_args(argv)
    old, new = (json.loads(p.read_text()) for p in (args.old, args.new))
    found = differences(old, new, tuple(args.ignore))
    for path, x, y, rel in found:
        print(f"{path}: {x!r} -> {y!r}" + ("" if rel is None else f" (relative difference {rel:.3g})"))
    ignored = ", ".join(args.ignore) or "nothing"
    if not found:
        print(f"identical (ignoring {ignored})")
        return 0
    rels = [rel for *_, rel in found if rel is not None]
    largest = f", largest relative difference {max(rels):.3g}" if rels else ""
    print(f"{len(found)} leaves differ (ignoring {ignored}){largest}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
