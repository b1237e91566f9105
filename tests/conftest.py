"""Fixtures shared by the test modules, and the compiled kernels' warm-up before xdist's workers run.

Under pytest-xdist (`make test`: `-n auto`) the controller compiles the kernels' specialisations the
suite calls into numba's on-disk cache (tests/kernel_warm_up.py), one family per process, as many at
once as there are workers, while the workers start and collect; it hands out the first test when the
cache is written. On a clean checkout (CI) this compiles each specialisation once instead of in every
worker and child process that calls it before another has written it; on a warm cache it loads them
(a few seconds). A plain `pytest` run (no workers) compiles as it goes, as before.
"""

import importlib.util
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

_TESTS = Path(__file__).resolve().parent
_ROOT = _TESTS.parent
_warm_up = None  # the controller's running warm-up: (pool, futures, start time)


@pytest.fixture
def existing_out(tmp_path) -> Path:
    """An output folder holding an earlier run's summary.json, which a refused run must leave as it is."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}')
    return out


def _compile_family(name: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(_ROOT), str(_TESTS), env.get("PYTHONPATH")]))
    code = f"import kernel_warm_up; kernel_warm_up.FAMILIES[{name!r}]()"
    return subprocess.run([sys.executable, "-c", code], cwd=_ROOT, env=env, capture_output=True, text=True)


def _is_xdist_controller(config) -> bool:
    return config.pluginmanager.has_plugin("dsession") and not hasattr(config, "workerinput")


def pytest_sessionstart(session):
    """xdist's controller, before it starts the workers: the warm-up's processes started."""
    global _warm_up
    config = session.config
    if not _is_xdist_controller(config) or config.option.collectonly:
        return
    if importlib.util.find_spec("numba") is None or os.environ.get("NUMBA_DISABLE_JIT", "0") != "0":
        return
    from kernel_warm_up import FAMILIES

    pool = ThreadPoolExecutor(max_workers=max(1, len(config.option.tx or [])))
    _warm_up = (pool, {name: pool.submit(_compile_family, name) for name in FAMILIES}, time.perf_counter())


@pytest.hookimpl(hookwrapper=True)
def pytest_runtestloop(session):
    """xdist's controller: no test handed out before the warm-up's processes have ended."""
    if _warm_up is not None:
        pool, futures, start = _warm_up
        failed = [name for name, future in futures.items() if future.result().returncode != 0]
        pool.shutdown()
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.write_line(f"kernels compiled or loaded before the tests: {time.perf_counter() - start:.1f} s")
            for name in failed:
                last = (futures[name].result().stderr.strip().splitlines() or ["no output"])[-1]
                reporter.write_line(f"kernel warm-up {name!r} failed (its tests compile as they go): {last}")
    yield
