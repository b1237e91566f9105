"""fem.tets' edges and facets by integer keys are scikit-fem's own, to the element, and so are its
curved map's arrays and the bases on it, to the bit; fem.link's curved cells' Jacobian determinants
are scikit-fem's to rounding."""

from __future__ import annotations

import numpy as np
import pytest
from skfem import Basis, MeshTet1, MeshTet2
from skfem.mapping import MappingIsoparametric

from fem.tets import CurvedMapping, CurvedTets, Tets, build_entities, with_nodes


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


def _bent_ball() -> tuple[np.ndarray, np.ndarray]:
    """Nodes and cells of a P2 ball whose mid-edge nodes are moved off their chords: curved cells."""
    ball = MeshTet2.init_ball(2)  # its boundary's mid-edge nodes on the sphere
    rng = np.random.default_rng(4)
    bent = ball.doflocs + 0.02 * rng.standard_normal(ball.doflocs.shape) * (
        np.arange(ball.doflocs.shape[1]) >= ball.nvertices
    )
    return bent, ball.t


def test_the_curved_maps_arrays_are_scikit_fems_to_the_bit():
    bent, cells = _bent_ball()
    ours, theirs = CurvedTets(bent, cells)._mapping(), MappingIsoparametric(MeshTet2(bent, cells), MeshTet2.elem())
    assert isinstance(ours, CurvedMapping)
    rng = np.random.default_rng(5)
    some = np.sort(rng.choice(cells.shape[1], 20, replace=False))
    for X, tind in ((rng.random((3, 6)) / 3, None), (rng.random((3, some.size, 4)) / 3, some)):
        for name in ("F", "DF", "detDF", "invDF"):
            for _ in range(2):  # worked out, then kept
                a, b = getattr(ours, name)(X, tind), getattr(theirs, name)(X, tind)
                assert a.shape == b.shape and np.array_equal(a, b), name
        assert np.array_equal(ours.J(2, 1, X, tind), theirs.J(2, 1, X, tind))
    assert not ours.invDF(X, tind).flags.writeable  # kept arrays are shared: nobody may write them


def test_bases_on_curved_tets_are_scikit_fems_to_the_bit():
    bent, cells = _bent_ball()
    ours_mesh, theirs_mesh = CurvedTets(bent, cells), MeshTet2(bent, cells)
    local = MeshTet2.elem.doflocs.T
    for options in ({"intorder": 2}, {"quadrature": (local, np.ones(local.shape[1]))}):
        ours, theirs = Basis(ours_mesh, MeshTet2.elem(), **options), Basis(theirs_mesh, MeshTet2.elem(), **options)
        assert np.array_equal(ours.dx, theirs.dx) and np.array_equal(ours.doflocs, theirs.doflocs)
        for a, b in zip(ours.basis, theirs.basis):
            assert np.array_equal(np.asarray(a[0]), np.asarray(b[0])) and np.array_equal(a[0].grad, b[0].grad)


def test_the_curved_cells_jacobian_determinants_are_scikit_fems_to_rounding():
    from skfem.quadrature import get_quadrature

    from fem.link import _curved_det_jacobian

    bent, cells = _bent_ball()
    mesh = CurvedTets(bent, cells)
    points = np.hstack([get_quadrature(mesh.elem.refdom, 4)[0], np.eye(3, 4, 1)])
    ours, theirs = _curved_det_jacobian(mesh, points), MeshTet2(bent, cells)._mapping().detDF(points)
    assert ours.shape == theirs.shape
    assert np.max(np.abs(ours - theirs)) <= 1e-12 * np.max(np.abs(theirs))


def test_the_check_determinants_are_kept_per_mesh_and_give_its_volume():
    from dataclasses import replace

    from skfem.quadrature import get_quadrature

    from fem.link import _checked_det_jacobian, _curved_det_jacobian, _curved_volume_m3, straighten_distorted

    bent, cells = _bent_ball()
    mesh = CurvedTets(bent, cells)
    assert _checked_det_jacobian(mesh) is _checked_det_jacobian(mesh)  # worked out once
    assert mesh.f2e.shape == (3, mesh.f2t.shape[1])  # its entities found, to be handed on
    points, weights = get_quadrature(mesh.elem.refdom, 4)
    volume = np.sum(np.abs(_curved_det_jacobian(mesh, points)) @ weights)
    assert _curved_volume_m3(mesh) == pytest.approx(volume, rel=1e-14)
    # a mesh straightened (a new one, with other mid-edge nodes) has its own
    vertices = mesh.doflocs[:, : mesh.nvertices]
    midpoints = 0.5 * (vertices[:, mesh.edges[0]] + vertices[:, mesh.edges[1]])
    straight = with_nodes(mesh, np.hstack([vertices, midpoints]))
    assert not np.array_equal(_checked_det_jacobian(straight), _checked_det_jacobian(mesh))
    # given its cells' edges and faces, which are those it would find itself
    assert straight.t2e is mesh.t2e
    found = replace(mesh, doflocs=straight.doflocs)
    for name in ("edges", "t2e", "facets", "t2f", "f2t", "f2e"):
        assert np.array_equal(getattr(straight, name), getattr(found, name)), name
    assert straighten_distorted(straight, min_ratio=0.99) is straight  # straight cells: nothing to do
