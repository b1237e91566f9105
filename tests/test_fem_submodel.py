"""The stress sub-model (fem.submodel, geometry.ball_mesh): on the global's own mesh it is the global
solution; its interpolation of the global is exact where it must be; cut from the CAD it reaches the
converged peak of the default link."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import cKDTree
from skfem import Basis, MeshTet1

import geometry
from fem import get_material
from fem.errors import FemWarning
from fem.link import analyse_link_materials
from fem.stress import STRESS_AWAY_RATIOS
from fem.submodel import GlobalField, solve_submodel

ALUMINIUM = get_material("al6061-t6")
TITANIUM = get_material("ti-grade2")  # another Poisson's ratio: solved by CG on the first's factor
COARSE_M = 0.012


@pytest.fixture(scope="module")
def global_half():
    part = geometry.as_part(None, symmetry=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FemWarning)
        link = geometry.mesh_part(part, mesh_size_m=COARSE_M, order=2, mirror=True)
        return analyse_link_materials(link, [ALUMINIUM, TITANIUM], away_ratios=STRESS_AWAY_RATIOS)


def _keys(triangles: np.ndarray, n: int) -> np.ndarray:
    a, b, c = np.sort(triangles, axis=0).astype(np.int64)
    return (a * n + b) * n + c


def ball_of_the_global_mesh(solution, center_m: np.ndarray, radius_m: float) -> SimpleNamespace:
    """The global's own cells whose vertices are all within the ball, as a `BallMesh`: points are
    the global's DOF locations (its curved, straightened cells kept), the cut is where the cells
    left out touch, the bore and mirror facets are the global's inside the ball."""
    basis, link = solution.basis, solution.link
    mesh = basis.mesh
    inside = np.all(np.linalg.norm(mesh.p[:, mesh.t] - center_m.reshape(3, 1, 1), axis=0) <= radius_m, axis=0)
    tets10 = basis.element_dofs[:, inside]  # vertices are the first DOFs: indices into mesh.p too
    boundary = MeshTet1(mesh.p, tets10[:4]).boundary_facets()
    faces = MeshTet1(mesh.p, tets10[:4]).facets[:, boundary]
    n = mesh.p.shape[1]
    vertex = np.full(link.points_m.shape[1], -1, dtype=np.int64)
    used = np.unique(link.tets)
    vertex[used] = np.arange(len(used))
    tagged = {
        name: _keys(vertex[getattr(link, f"{name}_facets")], n) for name in ("fixed_bore", "loaded_bore", "mirror")
    }
    global_boundary = _keys(mesh.facets[:, mesh.boundary_facets()], n)
    keys = _keys(faces, n)
    sets = {name: faces[:, np.isin(keys, k)] for name, k in tagged.items()}
    return SimpleNamespace(
        points_m=np.asarray(basis.doflocs),
        tets=tets10[:4],
        tets10=tets10,
        fixed_bore_facets=sets["fixed_bore"],
        loaded_bore_facets=sets["loaded_bore"],
        mirror_facets=sets["mirror"],
        cut_facets=faces[:, ~np.isin(keys, global_boundary)],
        centers_m=center_m.reshape(1, 3),
        radius_m=radius_m,
    )


@pytest.mark.parametrize("bore", ["loaded", "fixed"])
def test_the_submodel_on_the_global_mesh_is_the_global_solution(global_half, bore):
    """A ball of the global's own cells about a pin bore (its bearing pressure or its clamp inside,
    and the mirror plane), driven by the global on the cut: the global's displacements, to the
    direct solver's round-off (aluminium) and to the 1e-6 residual of the CG both titanium solves use."""
    solutions = list(global_half.values())
    link = solutions[0].link
    center = getattr(link, f"{bore}_bore").center_m
    ball = ball_of_the_global_mesh(solutions[0], center, 2.5 * link.loaded_bore.radius_m)
    assert ball.cut_facets.shape[1] > 0 and ball.mirror_facets.shape[1] > 0
    assert getattr(ball, f"{bore}_bore_facets").shape[1] > 0
    sub = solve_submodel(ball, [GlobalField(s) for s in solutions], trusted_margin_m=0.0)
    for solution, rel in zip(solutions, (1e-9, 1e-5)):
        mine = sub[solution.material.name]
        distance, at = cKDTree(solution.basis.doflocs.T).query(mine.basis.doflocs.T)
        assert distance.max() == 0.0
        expected = solution.displacement_m[:, at]
        assert np.abs(mine.displacement_m - expected).max() <= rel * np.abs(expected).max()


def test_the_global_field_is_the_global_solution_at_its_nodes_and_inside_its_cells(global_half):
    solution = global_half[ALUMINIUM.name]
    field = GlobalField(solution)
    nodes = np.asarray(solution.basis.doflocs)[:, ::7]
    assert (
        np.abs(field.displacement_m(nodes) - solution.displacement_m[:, ::7]).max()
        <= 1e-12 * np.abs(solution.displacement_m).max()
    )
    # inside a cell: the cell's own P2 interpolant (at its reference centroid)
    centre = np.full((3, 1), 0.25)
    at_centres = Basis(solution.basis.mesh, solution.basis.elem, quadrature=(centre, np.ones(1)))
    cells = np.arange(0, solution.basis.mesh.t.shape[1], 50)
    points = np.asarray(solution.basis.mapping.F(centre))[:, cells, 0]
    expected = np.array([np.asarray(at_centres.interpolate(solution.displacement_m[c]))[cells, 0] for c in range(3)])
    assert np.abs(field.displacement_m(points) - expected).max() <= 1e-10 * np.abs(expected).max()
