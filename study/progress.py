"""A progress bar on stderr: points and FEA tasks done, elapsed and estimated time left."""

from __future__ import annotations

import sys
import time


def _clock(seconds: float | None) -> str:
    if seconds is None:
        return "--:--"
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    return f"{h}:{rest // 60:02d}:{rest % 60:02d}" if h else f"{rest // 60:02d}:{rest % 60:02d}"


class ProgressBar:
    """The time left is estimated from the tasks' measured times: the remaining FEA and chain
    tasks, each at the mean time of its kind so far, shared over the workers."""

    def __init__(self, points: int, fea_tasks: int, workers: int, quiet: bool, stream=None):
        self.points, self.fea_tasks, self.workers = points, fea_tasks, max(1, workers)
        self.points_done = self.fea_done = 0
        self.chain_tasks = 0
        self.chain_done = 0
        self.seconds: dict[str, list[float]] = {"fea": [], "chain": []}
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.start = time.perf_counter()
        self.last_line = -1.0

    def task_done(self, kind: str, seconds: float, points: int = 0) -> None:
        self.seconds[kind].append(seconds)
        if kind == "fea":
            self.fea_done += 1
        else:
            self.chain_done += 1
        self.points_done += points
        self.show()

    def points_skipped(self, points: int) -> None:
        self.points_done += points
        self.show()

    def eta_s(self) -> float | None:
        if not self.seconds["fea"] and self.fea_tasks > self.fea_done:
            return None
        mean = {k: sum(v) / len(v) if v else 0.0 for k, v in self.seconds.items()}
        left = (self.fea_tasks - self.fea_done) * mean["fea"] + (self.chain_tasks - self.chain_done) * mean["chain"]
        return left / self.workers

    def line(self) -> str:
        width = 30
        frac = self.points_done / self.points if self.points else 1.0
        bar = "#" * int(width * frac) + "." * (width - int(width * frac))
        return (
            f"[{bar}] {self.points_done}/{self.points} points, FEA {self.fea_done}/{self.fea_tasks}, "
            f"elapsed {_clock(time.perf_counter() - self.start)}, left ~{_clock(self.eta_s())}"
        )

    def show(self, final: bool = False) -> None:
        if self.quiet:
            return
        now = time.perf_counter()
        if self.tty:
            print("\r" + self.line(), end="\n" if final else "", file=self.stream, flush=True)
        elif final or now - self.last_line >= 2.0:  # a log, not a flood
            print(self.line(), file=self.stream, flush=True)
            self.last_line = now

    def message(self, text: str) -> None:
        if not self.quiet:
            print(("\n" if self.tty else "") + text, file=self.stream, flush=True)
