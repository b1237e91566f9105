"""Badly shaped tetrahedra: the radius-ratio check finds them, and what the solve makes of them.

A good structured mesh of a bar is spoiled by moving one interior vertex towards the centroid of
the face opposite it in one of its tets (new position c + eps (v - c)): that tet flattens
(q ~ eps^2) and its neighbours degrade, without any tet turning inside out.
"""

from __future__ import annotations

import numpy as np
import pytest
from fem_bar import E_PA, LOAD_N, bar_on_rollers
from skfem import MeshTet

import geometry
from fem.errors import FemError
from fem.quality import (
    DEGENERATE_QUALITY,
    POOR_QUALITY_THRESHOLD,
    link_quality,
    mesh_quality,
    quality_warning,
    radius_ratios,
    require_valid,
)

LENGTH_M, WIDTH_M, HEIGHT_M = 3.0, 1.0, 1.0


def bar() -> MeshTet:
    return MeshTet.init_tensor(np.linspace(0, LENGTH_M, 7), np.linspace(0, WIDTH_M, 3), np.linspace(0, HEIGHT_M, 3))


def signed_volumes(mesh: MeshTet) -> np.ndarray:
    a, b, c, d = (mesh.p[:, mesh.t[i]].T for i in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a))


def flattened(mesh: MeshTet, eps: float) -> tuple[MeshTet, int]:
    """The mesh with one tet flattened (see the module doc) and that tet's index."""
    vertex = np.setdiff1d(np.arange(mesh.p.shape[1]), mesh.boundary_nodes())[0]
    tet = int(np.flatnonzero((mesh.t == vertex).any(axis=0))[0])
    centroid = mesh.p[:, [i for i in mesh.t[:, tet] if i != vertex]].mean(axis=1)
    points = mesh.p.copy()
    points[:, vertex] = centroid + eps * (mesh.p[:, vertex] - centroid)
    return MeshTet(points, mesh.t), tet


def bar_stiffness_error(mesh: MeshTet, order: int, solver: str) -> float:
    """k / (EA/L) - 1 of the bar on roller supports (exact for any valid mesh: u is linear)."""
    _, f, u = bar_on_rollers(mesh, order, solver, LENGTH_M, WIDTH_M, HEIGHT_M)
    return float(LOAD_N**2 / (f @ u) / (E_PA * WIDTH_M * HEIGHT_M / LENGTH_M) - 1)


def test_radius_ratio_of_known_tets():
    regular = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float).T
    kuhn = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1]], dtype=float).T
    order = np.array([[0], [1], [2], [3]])
    assert radius_ratios(regular, order)[0] == pytest.approx(1.0, rel=1e-14)
    # Either orientation, any scale: q is a shape measure.
    assert radius_ratios(3.7 * regular, order[[1, 0, 2, 3]])[0] == pytest.approx(1.0, rel=1e-14)
    # Cube-corner (Kuhn) tet: r_in = 3V/S = (1/2)/(1 + sqrt 2), r_circ = sqrt(3)/2 (the cube's sphere).
    expected = 3 * (0.5 / (1 + np.sqrt(2))) / (np.sqrt(3) / 2)
    assert radius_ratios(kuhn, order)[0] == pytest.approx(expected, rel=1e-14)
    flat = kuhn.copy()
    flat[2, 3] = 0.0  # fourth vertex in the plane of the other three
    assert radius_ratios(flat, order)[0] == 0.0


def test_good_meshes_pass():
    quality = mesh_quality(bar().p, bar().t)
    assert quality.worst == pytest.approx(0.7174, abs=1e-4)  # all Kuhn tets
    assert quality.below_threshold == 0 and quality_warning(quality) is None
    require_valid(quality)
    # gmsh's mesh of the default link at its default finest size, 4.5 mm (measured worst q 0.18;
    # 0.14 at 6 mm). At 12 mm it was 0.21-0.33 on the sharp-cornered link; the filleted one has
    # slivers there (q 0.08), where 12 mm elements meet its 1 mm pocket-floor fillet.
    link = link_quality(geometry.load_link(None, mesh_size_m=0.0045))
    assert link.worst > POOR_QUALITY_THRESHOLD and quality_warning(link) is None


def test_a_flattened_tet_is_found_and_named_in_the_warning():
    mesh, tet = flattened(bar(), 0.1)
    assert np.all(np.sign(signed_volumes(mesh)) == np.sign(signed_volumes(bar())))  # nothing inverted
    quality = mesh_quality(mesh.p, mesh.t)
    assert quality.worst < 0.07 and 1 <= quality.below_threshold <= 4  # measured: 0.049, 2 tets
    assert radius_ratios(mesh.p, mesh.t)[tet] < POOR_QUALITY_THRESHOLD
    message = quality_warning(quality)
    assert (
        message is not None
        and f"below {POOR_QUALITY_THRESHOLD:g}" in message
        and f"{quality.below_threshold} of 144" in message
    )
    require_valid(quality)  # poor but not degenerate: a warning, not an error


@pytest.mark.parametrize("eps", [1e-1, 1e-3, 1e-5, 1e-7])
@pytest.mark.parametrize("order", [1, 2])
def test_direct_solve_still_passes_the_patch_test_on_slivers(eps, order):
    # The exact solution is linear, so any valid mesh reproduces it; what a sliver costs is
    # conditioning (~1/q^2). PARDISO kept EA/L to 2e-12 down to q = 5e-14 (eps = 1e-7, measured);
    # 1e-9 allows for the round-off that conditioning amplifies on other BLAS builds.
    mesh, _ = flattened(bar(), eps)
    assert bar_stiffness_error(mesh, order, "pardiso") == pytest.approx(0.0, abs=1e-9)


def test_flat_tet_is_an_error_that_names_the_threshold():
    mesh, _ = flattened(bar(), 0.0)
    quality = mesh_quality(mesh.p, mesh.t)
    # The vertex lands on a plane of the structured mesh: its tet and one neighbour go flat.
    assert quality.degenerate >= 1 and quality.worst < DEGENERATE_QUALITY
    with pytest.raises(
        FemError, match=rf"{quality.degenerate} of 144 tetrahedra are flat \(radius ratio below {DEGENERATE_QUALITY:g}"
    ):
        require_valid(quality)


def test_bad_threshold_is_rejected():
    with pytest.raises(FemError, match="threshold"):
        mesh_quality(bar().p, bar().t, threshold=1.5)
