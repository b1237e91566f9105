"""scikit-fem's tetrahedral meshes with their edges and facets found faster, the same arrays.

scikit-fem finds a mesh's edges and facets (`Mesh.build_entities`) with `np.unique(..., axis=1)`,
which sorts the columns as records; on the default link's two stiffness levels that was about a
third of the CPU of making the curved meshes (`fem.link.skfem_mesh`: the P2 mesh, each round of
straightening, and the basis each build them again). `Tets` and `CurvedTets` number each sorted
column by one integer key, `(a n + b) n + c`, whose order is the columns' lexicographic order, and
take `np.unique` of the keys: the same entities, first occurrences and inverse, to the element
(tests/test_fem_tets.py), so k and the stresses are unchanged to the bit.
"""

from __future__ import annotations

import numpy as np
from skfem import MeshTet1, MeshTet2


def build_entities(t: np.ndarray, indices, sort: bool = True):
    """`skfem.Mesh.build_entities` (entities of the cells `t` given by the local `indices`, e.g.
    the reference tetrahedron's edges), by integer keys."""
    if indices is None:
        return None, None
    indexing = np.hstack(tuple([t[ix] for ix in indices]))
    sorted_indexing = np.sort(indexing, axis=0)
    n = int(sorted_indexing.max()) + 1 if sorted_indexing.size else 1
    if float(n) ** sorted_indexing.shape[0] >= 2.0**63:  # keys that would not fit: scikit-fem's way
        return MeshTet1.build_entities(t, indices, sort)
    keys = sorted_indexing[0].astype(np.int64)
    for row in sorted_indexing[1:]:
        keys = keys * n + row
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    mapping = inverse.reshape((len(indices), t.shape[1]))
    if sort:
        return np.ascontiguousarray(sorted_indexing[:, first]), mapping
    return np.ascontiguousarray(indexing[:, first]), mapping


class Tets(MeshTet1):
    """`skfem.MeshTet1` whose edges and facets come from `build_entities` above."""

    build_entities = staticmethod(build_entities)


class CurvedTets(MeshTet2):
    """`skfem.MeshTet2` whose edges and facets come from `build_entities` above."""

    build_entities = staticmethod(build_entities)
