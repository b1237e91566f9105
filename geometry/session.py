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
import sys
import threading
from collections.abc import Iterator

import gmsh

_LOCK = threading.RLock()


@contextlib.contextmanager
def gmsh_model(name: str = "link") -> Iterator[None]:
    """Open a fresh gmsh model (initialising gmsh if needed) and remove it afterwards."""
    with _LOCK:
        owns_gmsh = not gmsh.isInitialized()
        if owns_gmsh:
            # interruptible=False keeps gmsh from replacing the SIGINT handler for good.
            gmsh.initialize(interruptible=False, readConfigFiles=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.option.setString("Geometry.OCCTargetUnit", "M")
            gmsh.model.add(name)
            try:
                yield
            finally:
                gmsh.model.remove()
        finally:
            if owns_gmsh:
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
