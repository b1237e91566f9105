"""What a long steady-state search says while it runs.

A long chain's scenario is minutes of index cycles (about two at 10,000 links on the wheels: a
coarse search of the linear machine, then of the machine with free play, then the settle at the
window's step), which the run's progress lines otherwise pass in silence. `SearchProgress` is
handed down to the searches (`progress=`: dynamics.machine_scene's on the wheels, dynamics.scene's
periodic state of the single-link drive's clearance chain) and says, at most every
`every_s` seconds, how far the search in progress has come: its index cycles so far, its last
change per cycle and the change it accepts. Its first line comes `every_s` after it is made, so a
scenario shorter than that (every scenario of the default run) says nothing. It only listens: a
search with it finds the same state to the bit as one without.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

# A line at most this often: a long search's index cycle is 1-10 s at 10,000 links, so a line a cycle
# would be dozens of lines a scenario, and the pipeline's other long work (the FEA levels) says
# something every few seconds to tens of seconds
PROGRESS_EVERY_S = 10.0


@dataclass
class SearchProgress:
    """Says `say(line)` about the searches of one scenario, at most every `every_s` seconds of
    `clock` (time.monotonic: the same clock in a forked worker as in the run)."""

    say: Callable[[str], None]
    every_s: float = field(default_factory=lambda: PROGRESS_EVERY_S)
    clock: Callable[[], float] = time.monotonic
    _last_s: float = field(init=False)
    _cycles: dict[str, int] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        self._last_s = self.clock()

    def observer(self, search: str, tol: float) -> Callable[[float], None]:
        """The `on_period` of one search (dynamics.solvers.shooting: called after each cycle with
        the change per cycle it accepts by): `search` names it in the line ("of the linear
        machine", ...), and its cycles are counted on from the last observer of that name (a search
        continued at another step is one search to the reader)."""
        self._cycles.setdefault(search, 0)

        def on_period(change: float) -> None:
            self._cycles[search] += 1
            now = self.clock()
            if now - self._last_s >= self.every_s:
                self._last_s = now
                cycles = self._cycles[search]
                self.say(
                    f"steady-state search {search}: {cycles} index cycle{'s' if cycles > 1 else ''} so far, "
                    f"change per cycle {change:.1e} (accepted at {tol:.1e})"
                )

        return on_period
