"""A real Dask cluster for the study tests: `dask scheduler` and `dask worker` processes on
127.0.0.1 (free ports), always torn down; and the small, coarse study they run."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# Coarse on purpose (P1, 14 mm, 12 links on the link drive, 1 sample per degree): each FEA takes a few seconds. A bore
# larger than its lug makes two geometries infeasible; two speeds and two cam laws give the front
# something to choose from.
#: One material, a 12-link chain, P1 FEA at 14 mm: each FEA a few seconds (ends in [sampling]).
COARSE = """
[fixed]
material = "al6061-t6"
links = 12

[settings]
mesh_size_m = 0.014
order = 1
samples_per_degree = 1
drive = "link"

[sampling]
method = "grid"
""".rstrip()

SMALL_STUDY = """
[study]
name = "small"
report_best = {report_best}

[variables]
web_thickness_m = {{min = 0.004, max = 0.009}}
bore_radius_m = [0.009525, 0.017]
cam = ["modified-sine", "poly-345"]
rpm = [150.0, 180.0]

{coarse}
levels = {levels}

[[constraints]]
metric = "yield_safety_factor"
min = 2.5

[objectives]
minimise = ["body_mass_kg", "residual_vibration_m"]
"""


def small_study(report_best: int = 0, levels: int = 2) -> str:
    return SMALL_STUDY.format(report_best=report_best, levels=levels, coarse=COARSE)


def write_study(folder: Path, report_best: int = 0, levels: int = 2) -> Path:
    path = folder / "small.toml"
    path.write_text(small_study(report_best, levels))
    return path


def env(cache: Path) -> dict:
    """The project importable by every process, a private FEA cache, one BLAS thread."""
    return {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        "XDG_CACHE_HOME": str(cache),
        "OMP_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1",
    }


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def study_command(study: Path, out: Path, *options: str) -> list[str]:
    return [sys.executable, "-m", "study", str(study), "--out", str(out), "-q", *options]


class ExternalCluster:
    """`dask scheduler` + `dask worker` processes (no nanny: killing one kills that worker)."""

    def __init__(self, workers: int, cache: Path, worker_cwd: Path = ROOT):
        """worker_cwd: the workers' working directory (elsewhere than the client's: no shared paths)."""
        self.env = env(cache)
        self.worker_cwd = worker_cwd
        self.address = f"tcp://127.0.0.1:{free_port()}"
        self.scheduler = self._start(
            [
                sys.executable,
                "-m",
                "dask",
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                self.address.rsplit(":", 1)[1],
                "--no-dashboard",
            ]
        )
        self.workers = [self.start_worker() for _ in range(workers)]
        self.wait_for_workers(workers)

    def _start(self, command: list[str], cwd: Path = ROOT) -> subprocess.Popen:
        return subprocess.Popen(
            command, cwd=cwd, env=self.env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
        )

    def start_worker(self) -> subprocess.Popen:
        return self._start(
            [
                sys.executable,
                "-m",
                "dask",
                "worker",
                self.address,
                "--nthreads",
                "1",
                "--no-nanny",
                "--no-dashboard",
                "--host",
                "127.0.0.1",
            ],
            cwd=self.worker_cwd,
        )

    def client(self):
        from distributed import Client

        return Client(self.address, timeout="30s")

    def wait_for_workers(self, n: int, timeout_s: float = 60.0) -> None:
        deadline = time.monotonic() + timeout_s
        while True:
            with contextlib.suppress(OSError, TimeoutError):
                with self.client() as c:
                    c.wait_for_workers(n, timeout=max(1.0, deadline - time.monotonic()))
                    return
            if time.monotonic() > deadline:
                raise TimeoutError(f"{n} dask workers did not join {self.address}")
            time.sleep(0.5)

    def close(self) -> None:
        for p in [*self.workers, self.scheduler]:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        for p in [*self.workers, self.scheduler]:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
