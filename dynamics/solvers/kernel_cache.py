"""numba's on-disk cache of the compiled kernels keyed on every file a kernel compiles in.

numba keys a kernel's cache entry on its own file's modification time and size (and its own
bytecode): a kernel that inlines or calls compiled functions of other files (the machine's step
inlines the ring's helpers of clearance_verlet.py and friction_tanh.py, and calls
machine_damping.chain_damping_into) keeps its old compiled copy when only one of those files changes.
`key_on_dependencies` adds to each kernel's cache stamp a digest of the contents of every file it
compiles in: an edit of any of them changes the stamp, numba finds its index stale and compiles the
kernel again (the stale entries are overwritten). It runs when the kernel's module is imported,
before any kernel is called (numba reads its cache at the first call): about 2 ms per kernel module
(the walk and one hash of each file), against the 1.3 s the two kernel modules' import takes; the
pipeline imports neither before its FEA's process starts (tests/test_startup.py).

A dependency is found by following the names a kernel's code refers to in its module's globals to
compiled functions (numba dispatchers) or plain Python functions, and on through theirs. The
constants a kernel freezes in (numba takes globals as compile-time constants) are covered where they
live in one of those files, as every constant the kernels import does (TANH_IS_ONE, FASTMATH,
SPEED_CAPACITY).
"""

from __future__ import annotations

import hashlib
import types
from pathlib import Path


def compiled_in_files(function) -> set[str]:
    """The source files of `function` (a numba dispatcher or a plain function) and of every function
    it refers to by a global name, transitively."""
    files: set[str] = set()
    seen: set = set()
    todo = [_py_func(function)]
    while todo:
        func = todo.pop()
        if func in seen:
            continue
        seen.add(func)
        files.add(func.__code__.co_filename)
        for name in _global_names(func.__code__):
            value = _py_func(func.__globals__.get(name))
            if isinstance(value, types.FunctionType):
                todo.append(value)
    return files


def _py_func(value):
    """A dispatcher's Python function; anything else as it is."""
    return getattr(value, "py_func", value)


def _global_names(code) -> set[str]:
    """The names `code` and the code objects nested in it look up (globals among them)."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _global_names(const)
    return names


def files_digest(files, file_digests: dict | None = None) -> str:
    """One digest of the files' paths and contents (sorted by path); `file_digests`: each file's, by
    path, reused and filled in."""
    file_digests = {} if file_digests is None else file_digests
    digest = hashlib.sha256()
    for path in sorted(files):
        if path not in file_digests:
            file_digests[path] = hashlib.sha256(Path(path).read_bytes()).digest()
        digest.update(path.encode())
        digest.update(file_digests[path])
    return digest.hexdigest()


def key_on_dependencies(namespace: dict, module: str) -> None:
    """Key the on-disk cache of every compiled kernel defined in `module` (found in its `namespace`,
    its globals) on the contents of the files it compiles in. Kernels without an on-disk cache (numba
    absent, NUMBA_DISABLE_JIT, cache=False) are left alone."""
    file_digests: dict = {}
    for value in list(namespace.values()):
        cache_file = getattr(getattr(value, "_cache", None), "_cache_file", None)
        if cache_file is None or getattr(_py_func(value), "__module__", None) != module:
            continue
        # numba compares this stamp with the one its index was saved with: another stamp, the index is stale
        digest = files_digest(compiled_in_files(value), file_digests)
        cache_file._source_stamp = (cache_file._source_stamp, digest)
