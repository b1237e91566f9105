"""Where the wild STEP corpus is: eleven public STEP files made by others, read in place from the
shared folder beside the repository (../shared/wild/, its README), never copied into it.

The one home of that path for the tests and the benchmarks that read the corpus. A worktree or a
clone that is not beside the shared folder finds it at /work/shared/wild, or wherever
LINK_CONVEYOR_WILD names.
"""

from __future__ import annotations

import os
from pathlib import Path

WILD_ENV = "LINK_CONVEYOR_WILD"
ROOT = Path(__file__).resolve().parents[1]
# the workplace's shared folder, for worktrees (/work/wt/NAME) that are not beside it
SHARED_WILD = Path("/work/shared/wild")


def wild_corpus_dir() -> Path | None:
    """The corpus folder: $LINK_CONVEYOR_WILD if set, else ../shared/wild beside the checkout, else
    /work/shared/wild; None when none of them is a folder."""
    candidates = [Path(os.environ[WILD_ENV])] if os.environ.get(WILD_ENV) else []
    candidates += [ROOT.parent / "shared" / "wild", SHARED_WILD]
    return next((p for p in candidates if p.is_dir()), None)


WILD = wild_corpus_dir()
ABSENT = f"the wild STEP corpus (../shared/wild/) is absent; set {WILD_ENV} to its folder"
