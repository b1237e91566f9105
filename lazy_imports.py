"""A package's public names imported on first use (PEP 562 module `__getattr__` and `__dir__`).

`fem` and `geometry` export names from their modules this way: `pipeline.py`'s own process needs only
a few light modules of each (their errors, options, the part's resolution), while importing the
whole packages would load scikit-fem, SciPy's solvers and gmsh there (docs/performance.md, "The
whole job")."""

from __future__ import annotations

import sys
from collections.abc import Callable
from importlib import import_module


def lazy_exports(package: str, module_of: dict[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """(`__getattr__`, `__dir__`) for `package`, whose name N lives in its module `module_of[N]`:
    N's module is imported at N's first use and N kept in the package's namespace."""

    def __getattr__(name: str):
        if name not in module_of:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(import_module(f"{package}.{module_of[name]}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(module_of))

    return __getattr__, __dir__
