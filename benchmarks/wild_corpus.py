"""Where the wild STEP corpus is: eleven public STEP files made by others, read in place from the
shared folder beside the repository (../shared/wild/, its README), never copied into it.

The one home of that path for the tests and the benchmarks that read the corpus. A git worktree
that is not beside the shared folder finds it beside its main checkout; anything else wherever
LINK_CONVEYOR_WILD names.
"""

from __future__ import annotations

import os
from pathlib import Path

WILD_ENV = "LINK_CONVEYOR_WILD"
ROOT = Path(__file__).resolve().parents[1]


def main_checkout(root: Path) -> Path:
    """The main checkout of the git worktree at `root` (`root` itself for a main checkout or a plain
    folder): a worktree's .git is a file naming its git directory, whose `commondir` leads to the
    main checkout's .git."""
    try:
        gitdir = Path((root / ".git").read_text().split("gitdir:", 1)[1].strip())
        return (gitdir / (gitdir / "commondir").read_text().strip()).resolve().parent
    except (OSError, IndexError):
        return root


def wild_corpus_dir(root: Path = ROOT) -> Path | None:
    """The corpus folder: $LINK_CONVEYOR_WILD if set, else ../shared/wild beside the checkout, else
    beside its main checkout (a git worktree elsewhere); None when none of them is a folder."""
    candidates = [Path(os.environ[WILD_ENV])] if os.environ.get(WILD_ENV) else []
    candidates += [root.parent / "shared" / "wild", main_checkout(root).parent / "shared" / "wild"]
    return next((p for p in candidates if p.is_dir()), None)


WILD = wild_corpus_dir()
ABSENT = f"the wild STEP corpus (../shared/wild/) is absent; set {WILD_ENV} to its folder"
