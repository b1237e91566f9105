"""Fixtures shared by the test modules, and the compiled kernels' warm-up before xdist's workers run.

Under pytest-xdist (`make test`: `-n auto`) the controller compiles the kernels' specialisations the
suite calls into numba's on-disk cache (tests/kernel_warm_up.py), one family per process, all at once
(the operating system shares the cores among them and the workers, which start and collect meanwhile);
it hands out the first test when the cache is written. On a clean checkout (CI) this compiles each specialisation once instead of in every
worker and child process that calls it before another has written it; on a warm cache it loads them
(a few seconds). A plain `pytest` run (no workers) compiles as it goes, as before.
"""

import importlib.util
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

_TESTS = Path(__file__).resolve().parent
_ROOT = _TESTS.parent
_warm_up = None  # the controller's running warm-up: ({family: process}, start time)


@pytest.fixture
def existing_out(tmp_path) -> Path:
    """An output folder holding an earlier run's summary.json, which a refused run must leave as it is."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}')
    return out


def _start_family(name: str) -> subprocess.Popen:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(_ROOT), str(_TESTS), env.get("PYTHONPATH")]))
    code = f"import kernel_warm_up; kernel_warm_up.FAMILIES[{name!r}]()"
    return subprocess.Popen(
        [sys.executable, "-c", code], cwd=_ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )


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

    _warm_up = ({name: _start_family(name) for name in FAMILIES}, time.perf_counter())


@pytest.hookimpl(hookwrapper=True)
def pytest_runtestloop(session):
    """xdist's controller: no test handed out before the warm-up's processes have ended."""
    if _warm_up is not None:
        processes, start = _warm_up
        try:
            errors = {name: process.communicate()[1] for name, process in processes.items()}
        except BaseException:  # interrupted: no family left compiling behind the session
            for process in processes.values():
                process.kill()
            raise
        failed = [name for name, process in processes.items() if process.returncode != 0]
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.write_line(f"kernels compiled or loaded before the tests: {time.perf_counter() - start:.1f} s")
            for name in failed:
                last = (errors[name].strip().splitlines() or ["no output"])[-1]
                reporter.write_line(f"kernel warm-up {name!r} failed (its tests compile as they go): {last}")
    yield
