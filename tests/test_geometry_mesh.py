"""The link mesh: bore facet sets on and covering the bores, quadratic nodes on the CAD, VTU export."""

import meshio
import numpy as np
import pytest

from geometry import EXAMPLE_STEP, GeometryError, load_link, write_vtu

SIZE = 0.008  # m, coarse: the properties tested hold at any size


@pytest.fixture(scope="module", params=[None, EXAMPLE_STEP], ids=["default", "example-step"])
def link2(request):
    return load_link(request.param, mesh_size_m=SIZE, order=2)


def _distance_to_axis(points, bore):
    rel = points.T - bore.center_m
    return np.linalg.norm(rel - np.outer(rel @ bore.axis, bore.axis), axis=1)


def _bores(link):
    return (("fixed", link.fixed_bore, link.fixed_bore_facets), ("loaded", link.loaded_bore, link.loaded_bore_facets))


def test_connectivity_is_consistent(link2):
    m = link2
    n = m.points_m.shape[1]
    assert m.tets.shape[0] == 4 and m.tets10.shape == (10, m.tets.shape[1])
    np.testing.assert_array_equal(m.tets10[:4], m.tets)
    assert np.array_equal(np.unique(m.tets10), np.arange(n))  # every point is a node of a tet
    p = m.points_m[:, m.tets]
    signed = np.einsum("ij,ij->j", np.cross((p[:, 1] - p[:, 0]).T, (p[:, 2] - p[:, 0]).T).T, p[:, 3] - p[:, 0])
    assert (signed > 0).all()  # positively oriented


def test_quadratic_node_order_is_meshio_tetra10(link2):
    # meshio/VTK tetra10: nodes 4..9 on edges 01, 12, 02, 03, 13, 23. Interior edges stay straight,
    # so most mid-nodes are exact midpoints; a wrong order would put them an edge length away.
    m = link2
    edges = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
    for k, (a, b) in enumerate(edges):
        offset = np.linalg.norm(
            m.points_m[:, m.tets10[4 + k]] - (m.points_m[:, m.tets10[a]] + m.points_m[:, m.tets10[b]]) / 2, axis=0
        )
        assert np.median(offset) < 1e-12
        assert offset.max() < 0.1 * SIZE  # curved edges move by a sagitta, never by an edge length


def test_facets_lie_on_the_bores(link2):
    for _, bore, facets in _bores(link2):
        # Mesh vertices on a CAD face are on it to gmsh's geometric tolerance (~1e-9 relative).
        assert (
            np.abs(_distance_to_axis(link2.points_m[:, np.unique(facets)], bore) - bore.radius_m).max()
            < 1e-7 * bore.radius_m
        )
        along = (link2.points_m[:, np.unique(facets)].T - bore.center_m) @ bore.axis
        assert np.abs(along).max() <= bore.length_m / 2 + 1e-9


def test_facets_cover_the_whole_bore(link2):
    for _, bore, facets in _bores(link2):
        p = link2.points_m[:, facets]
        area = 0.5 * np.linalg.norm(np.cross((p[:, 1] - p[:, 0]).T, (p[:, 2] - p[:, 0]).T), axis=1).sum()
        exact = 2 * np.pi * bore.radius_m * bore.length_m
        # Flat triangles inscribed in the cylinder: a chord c spans an arc longer by the factor
        # (a/2)/sin(a/2), a = 2 asin(c / 2r); so the area is below 2 pi r L by at most that ratio
        # for the longest chord; a doubled triangle set or a missing half would break the bounds.
        chords = np.linalg.norm(np.hstack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 1], p[:, 0] - p[:, 2]]), axis=0)
        half_angle = np.arcsin(chords.max() / (2 * bore.radius_m))
        assert exact * np.sin(half_angle) / half_angle <= area <= exact
        # No hole in the set either (one missing triangle is only ~0.2 % of the area): the edges
        # used by a single triangle all lie on the two end circles of the bore.
        edges = np.sort(np.hstack([facets[[0, 1]], facets[[1, 2]], facets[[0, 2]]]), axis=0)
        unique, count = np.unique(edges, axis=1, return_counts=True)
        assert set(count) == {1, 2}
        ends = (link2.points_m[:, unique[:, count == 1].ravel()].T - bore.center_m) @ bore.axis
        np.testing.assert_allclose(np.abs(ends), bore.length_m / 2, rtol=1e-9)


def test_loaded_facets_do_not_straddle_the_loaded_half(link2):
    bore, facets = link2.loaded_bore, link2.loaded_bore_facets
    rel = link2.points_m.T - bore.center_m
    cos = (rel - np.outer(rel @ bore.axis, bore.axis)) @ link2.load_direction / bore.radius_m
    c = cos[facets]
    loaded, unloaded = (c >= -1e-9).all(axis=0), (c <= 1e-9).all(axis=0)
    assert (loaded | unloaded).all()
    assert loaded.sum() > 0 and unloaded.sum() > 0


def test_quadratic_nodes_on_the_bores_lie_on_the_cylinder(link2):
    m = link2
    edges = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
    for _, bore, facets in _bores(m):
        facet_edges = {
            tuple(sorted(e)) for tri in facets.T for e in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[0], tri[2]))
        }
        mids = {
            int(m.tets10[4 + k, t])
            for t in range(m.tets.shape[1])
            for k, (a, b) in enumerate(edges)
            if tuple(sorted((m.tets10[a, t], m.tets10[b, t]))) in facet_edges
        }
        mids = np.array(sorted(mids))
        assert len(mids) >= len(facet_edges)  # one mid-node per facet edge (shared between tets)
        r = _distance_to_axis(m.points_m[:, mids], bore)
        # On the CAD cylinder to gmsh's tolerance. A straight midpoint of a chord across the bore
        # would sit inside by the sagitta r (1 - cos(a/2)), about 1e-2 r at these sizes.
        assert np.abs(r - bore.radius_m).max() < 1e-7 * bore.radius_m


def test_bores_are_refined():
    coarse = load_link(mesh_size_m=SIZE, bore_refinement=1.0)
    fine = load_link(mesh_size_m=SIZE, bore_refinement=0.4)
    for a, b in (
        (coarse.fixed_bore_facets, fine.fixed_bore_facets),
        (coarse.loaded_bore_facets, fine.loaded_bore_facets),
    ):
        # Triangle count scales as 1/size^2: 0.4 -> 6x more; allow the mesher a factor 2 slack.
        assert b.shape[1] > 3 * a.shape[1]


def test_meshing_is_deterministic():
    a, b = load_link(mesh_size_m=SIZE), load_link(mesh_size_m=SIZE)
    np.testing.assert_array_equal(a.tets, b.tets)
    np.testing.assert_array_equal(a.points_m, b.points_m)


def _straight_tet_volume(m):
    p = m.points_m[:, m.tets]
    return np.einsum("ij,ij->j", np.cross((p[:, 1] - p[:, 0]).T, (p[:, 2] - p[:, 0]).T).T, p[:, 3] - p[:, 0]).sum() / 6


def test_straight_tet_volume_approaches_the_cad_volume():
    # Flat facets on concave faces (bores, the lug-neck and pocket fillets) add volume, on the lug
    # ends remove it. With the default link's fillets (the pocket floor's is 1 mm, far below the
    # element size) the excess was 0.6 % at 8 mm, 0.29 % at 6 mm and 0.12 % at 3 mm (measured): it
    # is positive and shrinks under refinement (chord error ~ h^2 once the fillets are resolved).
    coarse, fine = load_link(mesh_size_m=SIZE), load_link(mesh_size_m=SIZE / 2)
    excess = [_straight_tet_volume(m) / m.cad_volume_m3 - 1 for m in (coarse, fine)]
    assert 0 < excess[1] < excess[0] / 2
    assert excess[0] < 1e-2


@pytest.mark.parametrize("order", [1, 2])
def test_vtu_round_trip(tmp_path, order):
    m = load_link(mesh_size_m=SIZE, order=order)
    n, t = m.points_m.shape[1], m.tets.shape[1]
    u = np.random.default_rng(0).normal(size=(n, 3))
    stress = np.arange(t, dtype=float)
    path = write_vtu(m, tmp_path / "link.vtu", point_data={"displacement_m": u}, cell_data={"von_mises_Pa": stress})
    back = meshio.read(path)
    np.testing.assert_array_equal(back.points, m.points_m.T)
    kind, cells = ("tetra", m.tets) if order == 1 else ("tetra10", m.tets10)
    assert back.cells[0].type == kind
    np.testing.assert_array_equal(back.cells[0].data, cells.T)
    np.testing.assert_array_equal(back.point_data["displacement_m"], u)
    np.testing.assert_array_equal(back.cell_data["von_mises_Pa"][0], stress)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.vtu"]  # no temporary file left


def test_vtu_rejects_data_of_the_wrong_length(tmp_path):
    m = load_link(mesh_size_m=SIZE)
    with pytest.raises(GeometryError, match="point_data\\['u'\\] has shape"):
        write_vtu(m, tmp_path / "x.vtu", point_data={"u": np.zeros(3)})
    assert not (tmp_path / "x.vtu").exists()


def test_concurrent_calls_are_serialised_and_give_the_serial_result():
    # gmsh is not thread-safe; load_link holds a process-wide lock, so two threads get exactly
    # what one thread gets.
    from concurrent.futures import ThreadPoolExecutor

    serial = load_link(mesh_size_m=SIZE)
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(lambda _: load_link(mesh_size_m=SIZE), range(2)))
    for r in results:
        np.testing.assert_array_equal(r.tets, serial.tets)
        np.testing.assert_array_equal(r.points_m, serial.points_m)


def test_gmsh_is_quiet_and_leaves_ctrl_c_alone(tmp_path, capfd):
    import signal

    from geometry import DEFAULT_LINK, write_step

    handler = signal.getsignal(signal.SIGINT)
    link = load_link(write_step(DEFAULT_LINK, tmp_path / "link.step"), mesh_size_m=SIZE)
    assert link.tets.shape[1] > 0
    assert signal.getsignal(signal.SIGINT) is handler
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # OpenCASCADE's STEP banners go to /dev/null
