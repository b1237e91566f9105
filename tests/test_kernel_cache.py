"""numba's on-disk cache keyed on the files a kernel compiles in (dynamics.solvers.kernel_cache): an
edit of an inlined file alone recompiles the kernel; numba alone keeps the old copy."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from dynamics.models import machine_damping
from dynamics.solvers import clearance_verlet, friction_tanh, kernel_cache
from dynamics.solvers import machine_verlet as mv

numba = pytest.importorskip("numba")


# the dependency (plain Python, compiled and inlined by the kernel's module, as friction_tanh.py is)
DEPENDENCY = """
def scale(x):
    return {factor} * x
"""
# a kernel's module inlining the dependency; {stamped}: with kernel_cache.key_on_dependencies
KERNEL = """
import numba
import kernel_cache
from dependency import scale as _scale

_scale = numba.njit(cache=True, inline="always")(_scale)


def _kernel(x):
    return _scale(x) + 1.0


kernel = numba.njit(cache=True)(_kernel)
if {stamped}:
    kernel_cache.key_on_dependencies(globals(), __name__)
"""
# each kernel's result at 1.0 and its cache misses (compilations)
RUN = "import plain, stamped; print(*(f'{k.kernel(1.0)}/{sum(k.kernel.stats.cache_misses.values())}' for k in (stamped, plain)))"


def _kernels_of(tree: Path) -> list[str]:
    """The stamped and the plain kernel's 'result/misses' in a fresh process importing the temp tree's
    modules (numba's cache beside them; kernel_cache copied there, so that it imports numba alone)."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    env.pop("NUMBA_CACHE_DIR", None)  # the cache beside the files, in the temp tree
    env.pop("NUMBA_DISABLE_JIT", None)
    done = subprocess.run([sys.executable, "-c", RUN], env=env, capture_output=True, text=True, timeout=120, check=True)
    return done.stdout.split()


def test_an_edit_of_an_inlined_file_alone_recompiles_a_stamped_kernel(tmp_path):
    """Both kernels compiled and cached with the dependency's factor 2, loaded from the cache on the next
    run (no miss), then the dependency alone edited to 3: the stamped kernel recompiles and returns the
    new result; numba's own stamp (the kernel's file unchanged) keeps the plain kernel's old copy."""
    (tmp_path / "dependency.py").write_text(DEPENDENCY.format(factor=2.0))
    (tmp_path / "kernel_cache.py").write_text(Path(kernel_cache.__file__).read_text())
    for name, stamped in (("stamped", True), ("plain", False)):
        (tmp_path / f"{name}.py").write_text(textwrap.dedent(KERNEL.format(stamped=stamped)))
    assert _kernels_of(tmp_path) == ["3.0/1", "3.0/1"]  # compiled
    assert _kernels_of(tmp_path) == ["3.0/0", "3.0/0"]  # loaded from the cache
    (tmp_path / "dependency.py").write_text(DEPENDENCY.format(factor=3.0))
    assert _kernels_of(tmp_path) == ["4.0/1", "3.0/0"]


def test_the_machines_kernels_are_keyed_on_the_files_they_compile_in():
    """The machine's step compiles in the ring's helpers, the friction law's tanh and the O(N) damping;
    its cache stamp holds those files' digest (the ring's step: its file and the tanh's)."""
    files = kernel_cache.compiled_in_files(mv._run)
    expected = {mv.__file__, clearance_verlet.__file__, friction_tanh.__file__, machine_damping.__file__}
    assert {Path(f).resolve() for f in files} == {Path(f).resolve() for f in expected}
    ring = kernel_cache.compiled_in_files(clearance_verlet._run_compiled)
    assert {Path(f).resolve() for f in ring} == {Path(clearance_verlet.__file__), Path(friction_tanh.__file__)}
    for kernel in (mv._run, clearance_verlet._run_compiled):
        stamp = kernel._cache._cache_file._source_stamp
        assert stamp[1] == kernel_cache.files_digest(kernel_cache.compiled_in_files(kernel))
