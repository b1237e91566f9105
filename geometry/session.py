"""One gmsh model at a time, in metres, silenced.

gmsh keeps global state and is not thread-safe (two threads meshing at once gave wrong results),
so every use goes through `gmsh_model`, which holds a process-wide lock. OpenCASCADE's
`Geometry.OCCTargetUnit` sticks for the whole process once set (it survives finalize), so it is set
to metres before every use: imports are converted to metres and the STEP writer scales model
metres to the millimetre header it always writes.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass

import gmsh

_LOCK = threading.RLock()


@dataclass
class KeptModel:
    """A model left in gmsh after its `gmsh_model` block (`keep_model`), for one `taken_model`."""

    volumes: list[int]  # its solids, as the block left them
    owns_gmsh: bool = False  # whether its block initialised gmsh (then the model's removal finalises it)


_KEPT: dict[str, KeptModel] = {}


@contextlib.contextmanager
def gmsh_model(name: str = "link") -> Iterator[None]:
    """Open a fresh gmsh model (initialising gmsh if needed) and remove it afterwards, unless the
    block kept it (`keep_model`)."""
    with _LOCK:
        _drop_kept(name)  # a stale model of the same name would shadow the new one
        owns_gmsh = not gmsh.isInitialized()
        if owns_gmsh:
            initialize_gmsh()
        kept = None
        try:
            _set_options()
            gmsh.model.add(name)
            try:
                yield
                kept = _KEPT.get(name)
            finally:
                if kept is None:
                    _KEPT.pop(name, None)
                    gmsh.model.remove()
        finally:
            if kept is not None:
                kept.owns_gmsh = owns_gmsh
            elif owns_gmsh:
                gmsh.finalize()


def initialize_gmsh() -> None:
    """gmsh.initialize as every caller needs it: no config files, Python's SIGINT handler left in
    place (interruptible=False), and Python's SIGPIPE handler put back. gmsh's initialize sets SIGPIPE
    to the default at the C level (Python still reports SIG_IGN), so a later write to a pipe whose
    reader has died would end the process without a word instead of raising BrokenPipeError.
    Only the main thread may set a signal handler; gmsh in another thread leaves it as gmsh set it."""
    on_main_thread = threading.current_thread() is threading.main_thread()
    sigpipe = signal.getsignal(signal.SIGPIPE) if on_main_thread else None
    gmsh.initialize(interruptible=False, readConfigFiles=False)
    if sigpipe is not None:
        signal.signal(signal.SIGPIPE, sigpipe)


def keep_model(name: str, volumes: list[int]) -> None:
    """Inside `gmsh_model(name)`: leave that model in gmsh after the block, with these solids, for
    one `taken_model(name)` (its CAD then need not be built again)."""
    _KEPT[name] = KeptModel(list(volumes))


@contextlib.contextmanager
def taken_model(name: str) -> Iterator[list[int] | None]:
    """The model kept under `name` (`keep_model`) made current for the block, its solids given, and
    removed afterwards; None (and no model) where none is kept."""
    with _LOCK:
        kept = _KEPT.pop(name, None)
        if kept is None:
            yield None
            return
        try:
            _set_options()
            gmsh.model.setCurrent(name)
            yield kept.volumes
        finally:
            _remove_kept(name, kept)


def _set_options() -> None:
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setString("Geometry.OCCTargetUnit", "M")
    # setOrder(2)'s own check of the curved elements' distortion only logs its worst value (silenced
    # above); fem.link checks and straightens the curved cells the FEA takes. Skipped: about 0.02 CPU
    # s a level on the default link, the same mesh (docs/performance.md, "The FEA's CPU in the whole job").
    gmsh.option.setNumber("Mesh.HighOrderSkipQualityCheck", 1)


def _drop_kept(name: str) -> None:
    kept = _KEPT.pop(name, None)
    if kept is not None:
        _remove_kept(name, kept)


def _remove_kept(name: str, kept: KeptModel) -> None:
    gmsh.model.setCurrent(name)
    gmsh.model.remove()
    if kept.owns_gmsh:
        if _KEPT:  # another kept model still needs gmsh: it finalises it when it goes
            next(iter(_KEPT.values())).owns_gmsh = True
        else:
            gmsh.finalize()


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """Silence C-level stdout (OpenCASCADE's STEP banners ignore General.Terminal)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 1)
            try:
                yield
            finally:
                os.dup2(saved, 1)
    finally:
        os.close(saved)
