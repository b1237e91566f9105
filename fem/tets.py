"""scikit-fem's tetrahedral meshes with their edges and facets found faster, the same arrays.

scikit-fem finds a mesh's edges and facets (`Mesh.build_entities`) with `np.unique(..., axis=1)`,
which sorts the columns as records; on the default link's two stiffness levels that was about a
third of the CPU of making the curved meshes (`fem.link.skfem_mesh`: the P2 mesh, each round of
straightening, and the basis each build them again). `Tets` and `CurvedTets` number each sorted
column by one integer key, `(a n + b) n + c`, whose order is the columns' lexicographic order, and
take `np.unique` of the keys: the same entities, first occurrences and inverse, to the element
(tests/test_fem_tets.py), so k and the stresses are unchanged to the bit.

`CurvedTets` maps its cells with `CurvedMapping`: scikit-fem's isoparametric map, the same arrays to
the bit, each formed in one pass and kept for the bases of a level that ask for it again.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from skfem import MeshTet1, MeshTet2
from skfem.mapping import MappingIsoparametric


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
    """`skfem.MeshTet2` whose edges and facets come from `build_entities` above and whose map is
    `CurvedMapping` below."""

    build_entities = staticmethod(build_entities)

    @property
    def kept_arrays(self) -> dict:
        """Arrays of this mesh worked out once (`kept`)."""
        if not hasattr(self, "_kept_arrays"):
            self._kept_arrays = {}
        return self._kept_arrays

    def _mapping(self):
        if not hasattr(self, "_cached_mapping"):
            self._cached_mapping = CurvedMapping(self, self.elem(), self.bndelem)
        return self._cached_mapping


# The cells' entities scikit-fem keeps on a mesh once found (`Mesh.edges`, `t2e`, `facets`, ...).
_ENTITIES = ("_edges", "_t2e", "_facets", "_t2f", "_f2t", "_f2e")


def with_nodes(mesh, doflocs: np.ndarray):
    """The mesh with its nodes moved to `doflocs` (`dataclasses.replace`: a new mesh), given the
    edges and faces its cells had (moving nodes does not change them) instead of finding them again:
    0.015 CPU s a default level's straightened mesh."""
    moved = replace(mesh, doflocs=doflocs)
    for name in _ENTITIES:
        if hasattr(mesh, name):
            setattr(moved, name, getattr(mesh, name))
    return moved


def kept(mesh, name: str, compute):
    """`compute()` of a mesh, worked out once on a `CurvedTets` (a straightened mesh is a new one,
    `dataclasses.replace`): another mesh's is worked out at each call."""
    if not isinstance(mesh, CurvedTets):
        return compute()
    if name not in mesh.kept_arrays:
        mesh.kept_arrays[name] = compute()
    return mesh.kept_arrays[name]


def _array_key(a) -> tuple:
    a = np.asarray(a)
    return a.shape, a.dtype.str, a.tobytes()


class CurvedMapping(MappingIsoparametric):
    """scikit-fem's isoparametric mapping with each array formed in one pass over the cells' nodes
    and kept per point set.

    scikit-fem forms each of the Jacobian's nine components (and each coordinate of the map) in a
    pass of its own over the ten nodes, evaluating the element's basis again in each, and forms the
    inverse Jacobian again for every basis function of a `Basis` (ten times on P2). Here one pass
    over the nodes adds the same products in the same order into all nine components (all three
    coordinates), so every array is scikit-fem's to the bit (tests/test_fem_tets.py), and the map,
    the Jacobian, its inverse and its determinant are each kept for the points (and cells) they
    were asked at, read-only, so that a level's bases (the stiffness's, the stress points') and
    their node locations share them."""

    def __init__(self, mesh, elem, bndelem=None):
        super().__init__(mesh, elem, bndelem)
        self._kept: dict[tuple, np.ndarray] = {}

    def _once(self, name: str, X: np.ndarray, tind, compute) -> np.ndarray:
        # keyed by the arrays' bytes themselves, not a hash of them: no collision can hand back
        # another point set's array
        cells = None if tind is None else _array_key(tind)
        key = (name, _array_key(X), cells)
        if key not in self._kept:
            value = np.asarray(compute())
            value.flags.writeable = False
            self._kept[key] = value
        return self._kept[key]

    def _over_nodes(self, X: np.ndarray, tind, derivatives: bool) -> np.ndarray:
        """sum over nodes n of x_n phi_n(X) (3, cells, points) or of x_n dphi_n/dX (3, 3, cells,
        points), the nodes' terms added in scikit-fem's order."""
        nodes = self.mesh.dofs.element_dofs
        if tind is not None:
            nodes = nodes[:, tind]
        points = X.shape[1:] if X.ndim == 3 else (1, X.shape[1])  # a cell axis for (3, points)
        components = (self.dim, self.dim) if derivatives else (self.dim,)
        out = np.zeros(components + (nodes.shape[1], points[-1]))
        for node in range(nodes.shape[0]):
            phi, dphi = self.elem.lbasis(X, node)
            at_node = self.mesh.doflocs[:, nodes[node]]  # (3, cells)
            if derivatives:
                out += at_node[:, None, :, None] * np.reshape(dphi, (1, self.dim) + points)
            else:
                out += at_node[:, :, None] * np.reshape(phi, (1,) + points)
        return out

    def F(self, X, tind=None):
        return self._once("F", X, tind, lambda: self._over_nodes(np.asarray(X), tind, derivatives=False))

    def _jacobian(self, X, tind=None) -> np.ndarray:
        return self._once("DF", X, tind, lambda: self._over_nodes(np.asarray(X), tind, derivatives=True))

    def J(self, i, j, X, tind=None):
        return self._jacobian(X, tind)[i, j]

    def DF(self, X, tind=None, J=None):
        return self._jacobian(X, tind) if J is None else super().DF(X, tind, J)

    def detDF(self, X, tind=None, J=None):
        if J is not None:
            return super().detDF(X, tind, J)
        return self._once("detDF", X, tind, lambda: super(CurvedMapping, self).detDF(X, tind))

    def invDF(self, X, tind=None):
        return self._once("invDF", X, tind, lambda: super(CurvedMapping, self).invDF(X, tind))
