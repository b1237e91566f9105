"""fem.tets' edges and facets by integer keys are scikit-fem's own, to the element; fem.link's curved
cells' Jacobian determinants are scikit-fem's to rounding."""

from __future__ import annotations

import numpy as np
import pytest
from skfem import MeshTet1, MeshTet2

from fem.tets import CurvedTets, Tets, build_entities


def _shuffled_ball() -> MeshTet1:
    """A tetrahedral mesh whose vertices and cells are in no particular order (as gmsh's are)."""
    mesh = MeshTet1.init_ball(2)
    rng = np.random.default_rng(2)
    renumber = rng.permutation(mesh.p.shape[1])
    points = np.empty_like(mesh.p)
    points[:, renumber] = mesh.p
    return MeshTet1(points, renumber[mesh.t][:, rng.permutation(mesh.t.shape[1])])


@pytest.mark.parametrize("sort", [True, False])
@pytest.mark.parametrize("entity", ["edges", "facets"])
def test_the_entities_and_their_map_are_scikit_fems(entity, sort):
    mesh = _shuffled_ball()
    indices = getattr(mesh.elem.refdom, entity)
    ours, theirs = build_entities(mesh.t, indices, sort), MeshTet1.build_entities(mesh.t, indices, sort)
    for a, b in zip(ours, theirs):
        assert a.dtype == b.dtype and np.array_equal(a, b)


def test_the_meshes_topology_and_p2_dofs_are_scikit_fems():
    plain = _shuffled_ball()
    for ours, theirs in ((Tets(plain.p, plain.t), plain), (CurvedTets.from_mesh(plain), MeshTet2.from_mesh(plain))):
        for name in ("edges", "t2e", "facets", "t2f", "f2t", "f2e", "doflocs"):
            assert np.array_equal(getattr(ours, name), getattr(theirs, name)), name
        assert np.array_equal(ours.dofs.element_dofs, theirs.dofs.element_dofs)


def test_keys_that_would_overflow_fall_back_to_scikit_fems_way():
    t = np.array([[0], [1], [2], [3_000_000]], dtype=np.int32)  # 3e6^3 > 2^63
    indices = MeshTet1.elem.refdom.facets
    for a, b in zip(build_entities(t, indices), MeshTet1.build_entities(t, indices)):
        assert np.array_equal(a, b)


def test_the_curved_cells_jacobian_determinants_are_scikit_fems_to_rounding():
    from skfem.quadrature import get_quadrature

    from fem.link import _curved_det_jacobian

    ball = MeshTet2.init_ball(2)  # its boundary's mid-edge nodes on the sphere: curved cells
    rng = np.random.default_rng(4)
    bent = ball.doflocs + 0.02 * rng.standard_normal(ball.doflocs.shape) * (
        np.arange(ball.doflocs.shape[1]) >= ball.nvertices
    )
    mesh = CurvedTets(bent, ball.t)
    points = np.hstack([get_quadrature(mesh.elem.refdom, 4)[0], np.eye(3, 4, 1)])
    ours, theirs = _curved_det_jacobian(mesh, points), MeshTet2(bent, ball.t)._mapping().detDF(points)
    assert ours.shape == theirs.shape
    assert np.max(np.abs(ours - theirs)) <= 1e-12 * np.max(np.abs(theirs))
