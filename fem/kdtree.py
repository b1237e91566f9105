"""SciPy's `cKDTree` (the nearest rim and element searches of fem.link, fem.submodel and fem.quality)
without the rest of `scipy.spatial`.

`from scipy.spatial import cKDTree` runs `scipy.spatial`'s `__init__`, which imports Delaunay's
`_qhull`, `scipy.spatial.distance` (and `scipy.special`) and `scipy.spatial.transform` (and
`scipy.constants`), none of which the FEA uses: about 0.1 CPU s of the FEA process's imports
(docs/performance.md, "The whole job"). The tree's extension module,
`scipy.spatial._ckdtree`, is loaded here from `scipy.spatial`'s folder by its own name and kept in
`sys.modules`, so that a later `import scipy.spatial` (a test, a benchmark) takes that same module
and its `cKDTree` is this one. Where SciPy's layout is not the expected one (no such module file),
`scipy.spatial` is imported as usual.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys

_MODULE = "scipy.spatial._ckdtree"


def _extension_spec() -> importlib.machinery.ModuleSpec | None:
    """The spec of `scipy.spatial._ckdtree`'s file in scipy/spatial, found without importing
    `scipy.spatial` (importlib.util.find_spec of a submodule imports its package first)."""
    for folder in importlib.util.find_spec("scipy").submodule_search_locations:
        finder = importlib.machinery.FileFinder(
            f"{folder}/spatial",
            (importlib.machinery.ExtensionFileLoader, importlib.machinery.EXTENSION_SUFFIXES),
        )
        spec = finder.find_spec(_MODULE)
        if spec is not None:
            return spec
    return None


def _tree_class() -> type:
    spec = None if "scipy.spatial" in sys.modules or _MODULE in sys.modules else _extension_spec()
    if spec is None:
        from scipy.spatial import cKDTree

        return cKDTree
    module = importlib.util.module_from_spec(spec)
    sys.modules[_MODULE] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[_MODULE]
        raise
    return module.cKDTree


cKDTree = _tree_class()
