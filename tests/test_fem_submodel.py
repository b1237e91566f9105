"""The stress sub-model (fem.submodel, geometry.ball_mesh): on the global's own mesh it is the global
solution; its interpolation of the global is exact where it must be; a sub-model of a plate with a
hole reaches Peterson's stress concentration factor."""

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
    direct solver's round-off (aluminium) and, for titanium (both solved by CG on aluminium's factor),
    to the CGs' tolerances: the global's error below fem.solvers.REUSE_ENERGY_TOLERANCE of its
    energy norm (alone: 6e-6 of the largest displacement at the clamped bore, where they are
    smallest), the sub-model's below fem.submodel.SUBMODEL_ENERGY_TOLERANCE (5.5e-7 at the loaded bore)."""
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


def test_a_piece_the_ball_holds_by_nothing_follows_the_global(global_half):
    """A cell far from the ball added with no cut face (as a thin feature clipped off inside a ball
    would be): no free body; it takes the global's displacements, the rest is still the global's,
    and its stress is not taken."""
    solution = global_half[ALUMINIUM.name]
    link = solution.link
    ball = ball_of_the_global_mesh(solution, link.loaded_bore.center_m, 2.5 * link.loaded_bore.radius_m)
    far = int(
        np.argmax(
            np.linalg.norm(solution.basis.mesh.p[:, solution.basis.mesh.t[0]].T - link.loaded_bore.center_m, axis=1)
        )
    )
    ball.tets10 = np.hstack([ball.tets10, solution.basis.element_dofs[:, far : far + 1]])
    ball.tets = ball.tets10[:4]
    mine = solve_submodel(ball, [GlobalField(solution)], trusted_margin_m=0.0)[ALUMINIUM.name]
    distance, at = cKDTree(solution.basis.doflocs.T).query(mine.basis.doflocs.T)
    assert distance.max() == 0.0
    expected = solution.displacement_m[:, at]
    assert np.abs(mine.displacement_m - expected).max() <= 1e-9 * np.abs(expected).max()
    far_dofs = np.isin(at, solution.basis.element_dofs[:, far])
    assert far_dofs.sum() == 10 and not mine.trusted_at_dofs[far_dofs].any()


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


def test_a_further_materials_field_reuses_the_points_location_on_the_same_mesh_to_the_bit(global_half, monkeypatch):
    first, second = GlobalField(global_half[ALUMINIUM.name]), GlobalField(global_half[TITANIUM.name])
    assert first.solution.basis is second.solution.basis  # one stiffness level's materials share it
    points = np.asarray(first.solution.basis.doflocs)[:, 3::11] + 1e-4  # inside cells, a few outside
    at = first.interpolation(points)
    located_anew = second.displacement_m(points)
    located = []
    interpolation = GlobalField.interpolation
    monkeypatch.setattr(GlobalField, "interpolation", lambda self, p: located.append(self) or interpolation(self, p))
    assert np.array_equal(second.displacement_m(points, at), located_anew)
    assert located == []  # the same basis: not located again
    other_mesh = GlobalField(
        SimpleNamespace(
            basis=Basis(first.solution.basis.mesh, first.solution.basis.elem),
            displacement_m=second.solution.displacement_m,
        )
    )
    other_mesh.displacement_m(points, at)
    assert located == [other_mesh]  # another basis: located again


class PlateField:
    """The eighth plate's global solution (tests/test_fem_stress_kt.py) as a sub-model's driving
    field on the whole plate: u_i(x) = sign(x_i) u_i(|x|) by its three symmetry planes."""

    mirror_axis = None
    clamp_exclusion_m = 0.0
    load_N = 1.0  # the sub-model's peak "per newton" is then the stress in Pa

    def __init__(self, basis, u: np.ndarray, material):
        self.material = material
        self._eighth = GlobalField(SimpleNamespace(basis=basis, displacement_m=u.reshape(-1, 3).T))

    def interpolation(self, points_m: np.ndarray) -> None:
        return None  # nothing to share: one material

    def displacement_m(self, points_m: np.ndarray, at=None) -> np.ndarray:
        sign = np.where(points_m < 0, -1.0, 1.0)
        return sign * self._eighth.displacement_m(np.abs(points_m))

    def clamp_rim_points_m(self) -> np.ndarray:
        return np.zeros((0, 3))


def plate_submodel_peaks(global_hole_size_m: float, radius_m: float, sizes_m: tuple[float, ...]) -> list[float]:
    """Peak von Mises / net-section nominal stress of a sub-model of the whole plate: a ball about
    the hole's peak point (0, d/2, 0), driven by the eighth plate's global solution on its cut,
    meshed at 4 x size and refined to each size within a third of the ball about that point."""
    import gmsh
    from test_fem_stress_kt import D_M, HOLE_D_M, LENGTH_M, STRESS_PA, T_M, eighth_plate

    from fem import problem
    from fem.assembly import elasticity_matrix
    from geometry.ball_mesh import BallMesher, _on_sphere, _sphere
    from geometry.bores import boundary_faces
    from geometry.meshing import Refinement
    from geometry.session import gmsh_model

    lam, mu = ALUMINIUM.lame_Pa
    mesh = eighth_plate(global_hole_size_m, 4 * global_hole_size_m)
    basis = problem.scalar_basis(mesh, 2)
    x = mesh.p[:, mesh.facets].mean(axis=1)
    boundary = mesh.boundary_facets()
    on = {
        name: boundary[np.abs(x[axis, boundary] - value) < 1e-9]
        for name, axis, value in (("x0", 0, 0.0), ("y0", 1, 0.0), ("z0", 2, 0.0), ("end", 0, LENGTH_M))
    }
    fixed = np.concatenate(
        [problem.fixed_vector_dofs(basis, on[name], components=(c,)) for name, c in (("x0", 0), ("y0", 1), ("z0", 2))]
    )
    f = problem.traction_load(
        basis, on["end"], lambda p: np.stack([np.full(p.shape[1:], STRESS_PA), 0 * p[0], 0 * p[0]])
    )
    u = problem.solve_displacement(elasticity_matrix(basis, lam, mu), f, fixed, problem.dof_locations(basis))
    field = PlateField(basis, u, ALUMINIUM)
    center = np.array([0.0, HOLE_D_M / 2, 0.0])
    nominal = STRESS_PA * D_M / (D_M - HOLE_D_M)
    peaks = []
    with gmsh_model("plate"):
        occ = gmsh.model.occ
        plate = occ.addBox(-LENGTH_M, -D_M / 2, -T_M / 2, 2 * LENGTH_M, D_M, T_M)
        hole = occ.addCylinder(0, 0, -T_M, 0, 0, 2 * T_M, HOLE_D_M / 2)
        body, _ = occ.cut([(3, plate)], [(3, hole)])
        pieces, _ = occ.intersect(body, [_sphere(center, radius_m)])
        occ.synchronize()
        volumes = [tag for dim, tag in pieces if dim == 3]
        cut = [f for f in boundary_faces(volumes) if _on_sphere(f, center, radius_m)]
        faces = {"fixed": [], "loaded": [], "mirror": [], "cut": cut}
        mesher = BallMesher(faces, center.reshape(1, 3), radius_m, 0.0)
        for size in sizes_m:
            ball = mesher.mesh([Refinement(tuple(center), radius_m / 3, size)], 4 * size)
            sub = solve_submodel(ball, [field], trusted_margin_m=radius_m / 4)[ALUMINIUM.name]
            peaks.append(sub.peak_Pa_per_N / nominal)
    return peaks


def test_the_submodel_of_a_plate_with_a_hole_converges_to_petersons_kt():
    """Driven by the coarsest global of tests/test_fem_stress_kt.py (3.2 mm at the hole), a ball of
    6 mm about the hole's edge refined to 0.8 and 0.4 mm: within 5 % of Peterson's K_t (the
    whole-plate test's tolerance) and converged to 5 % (3D effects put the thin plate's mid-plane
    peak about 1 % above the plane-stress K_t, see that test). Measured: 2.266 and 2.258 against
    K_t = 2.236 (+1.0 %) and the whole eighth plate's 2.256 at 0.8 mm."""
    from test_fem_stress_kt import D_M, HOLE_D_M, peterson_kt_net

    peaks = plate_submodel_peaks(0.0032, 0.006, (0.0008, 0.0004))
    kt = peterson_kt_net(HOLE_D_M / D_M)
    assert abs(peaks[-1] - peaks[-2]) <= 0.05 * peaks[-1]
    assert peaks[-1] == pytest.approx(kt, rel=0.05)
