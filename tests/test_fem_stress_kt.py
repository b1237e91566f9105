"""Peak stress against a published stress concentration factor: a thin plate with a central hole.

Reference: Peterson's fit for a central circular hole in a finite-width plate in tension, as given
in Roark's Formulas for Stress and Strain (Young & Budynas, 7th ed., Table 17.1, case 1a):
K_t = 3.00 - 3.13 (d/D) + 3.66 (d/D)^2 - 1.53 (d/D)^3 on the net section, sigma_nom = P / (t (D - d)).
The fit is for a thin plate (plane stress); with t = d / 5 the peak at the mid-plane is within
about 1 % of it (3D effects grow with t/d; measured here: 2.256 against 2.236, +0.9 %). The test asks for 5 %, the issue's tolerance, and for
the peak to converge: the change between the two finest meshes below 5 %.
"""

from __future__ import annotations

import gmsh
import numpy as np
import pytest
from skfem import MeshTet2

from fem import problem
from fem.assembly import elasticity_matrix
from fem.materials import get_material
from geometry.session import initialize_gmsh

D_M = 0.040  # plate width
HOLE_D_M = 0.016  # d/D = 0.4
T_M = HOLE_D_M / 5  # thin: plane stress
LENGTH_M = 0.080  # half-length: 2 widths from the hole to the loaded end
STRESS_PA = 1e6  # far-field tension


def peterson_kt_net(d_over_D: float) -> float:
    x = d_over_D
    return 3.00 - 3.13 * x + 3.66 * x**2 - 1.53 * x**3


def eighth_plate(hole_size_m: float, far_size_m: float) -> MeshTet2:
    """One eighth of the plate (symmetry planes x = 0, y = 0, z = 0), curved tets10, hole at the origin."""
    initialize_gmsh()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        box = occ.addBox(0, 0, 0, LENGTH_M, D_M / 2, T_M / 2)
        hole = occ.addCylinder(0, 0, -T_M, 0, 0, 2 * T_M, HOLE_D_M / 2)
        occ.cut([(3, box)], [(3, hole)])
        occ.synchronize()
        hole_faces = [s for _, s in gmsh.model.getEntities(2) if gmsh.model.getType(2, s) == "Cylinder"]
        field = gmsh.model.mesh.field
        distance = field.add("Distance")
        field.setNumbers(distance, "SurfacesList", hole_faces)
        threshold = field.add("Threshold")
        field.setNumber(threshold, "InField", distance)
        field.setNumber(threshold, "SizeMin", hole_size_m)
        field.setNumber(threshold, "SizeMax", far_size_m)
        field.setNumber(threshold, "DistMin", HOLE_D_M / 4)
        field.setNumber(threshold, "DistMax", HOLE_D_M)
        field.setAsBackgroundMesh(threshold)
        for option in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{option}", 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", far_size_m)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        points = np.zeros((3, int(tags.max()) + 1))
        points[:, tags.astype(int)] = coords.reshape(-1, 3).T
        _, nodes = gmsh.model.mesh.getElementsByType(11)
        cells = nodes.reshape(-1, 10).T.astype(np.int64)[[0, 1, 2, 3, 4, 5, 6, 7, 9, 8]]
    finally:
        gmsh.finalize()
    used, compact = np.unique(cells, return_inverse=True)
    return MeshTet2(np.ascontiguousarray(points[:, used]), compact.reshape(cells.shape))


def peak_stress_ratio(hole_size_m: float, far_size_m: float) -> float:
    """Peak von Mises (DOF-averaged, P2) over the net-section nominal stress."""
    material = get_material("al6061-t6")
    lam, mu = material.lame_Pa
    mesh = eighth_plate(hole_size_m, far_size_m)
    basis = problem.scalar_basis(mesh, 2)
    x = mesh.p[:, mesh.facets].mean(axis=1)
    boundary = mesh.boundary_facets()
    tol = 1e-9
    on = {
        name: boundary[np.abs(x[axis, boundary] - value) < tol]
        for name, axis, value in (("x0", 0, 0.0), ("y0", 1, 0.0), ("z0", 2, 0.0), ("end", 0, LENGTH_M))
    }
    fixed = np.concatenate(
        [problem.fixed_vector_dofs(basis, on[name], components=(c,)) for name, c in (("x0", 0), ("y0", 1), ("z0", 2))]
    )
    f = problem.traction_load(
        basis, on["end"], lambda p: np.stack([np.full(p.shape[1:], STRESS_PA), 0 * p[0], 0 * p[0]])
    )
    u = problem.solve_displacement(elasticity_matrix(basis, lam, mu), f, fixed, problem.dof_locations(basis))
    local = basis.elem.doflocs.T
    vm = problem.von_mises_Pa(problem.displacement_gradients(basis, u, local), lam, mu)
    dofs = basis.element_dofs.T
    at_dofs = np.bincount(dofs.ravel(), vm.ravel(), basis.N) / np.bincount(dofs.ravel(), minlength=basis.N)
    nominal = STRESS_PA * D_M / (D_M - HOLE_D_M)
    return float(at_dofs.max()) / nominal


@pytest.fixture(scope="module")
def ratios():
    return [peak_stress_ratio(h, 4 * h) for h in (0.0032, 0.0016, 0.0008)]


def test_peak_stress_converges_under_refinement(ratios):
    assert abs(ratios[-1] - ratios[-2]) <= 0.05 * ratios[-1]


def test_peak_stress_matches_petersons_kt(ratios):
    kt = peterson_kt_net(HOLE_D_M / D_M)
    assert kt == pytest.approx(2.236, abs=1e-3)
    assert ratios[-1] == pytest.approx(kt, rel=0.05)


@pytest.mark.slow
@pytest.mark.parametrize("part", ["default link", "filleted two-bore part"])
def test_stress_study_converges_to_five_percent(part, tmp_path):
    # Measured on the default link (a sub-model of its mirror half): 13.6 / 14.1 / 13.8 MPa per kN
    # at 4.5 (global) / 2.25 / 1.1 mm local elements (estimate 3.8 %), at the top of a side rail
    # where the pocket's corner fillet begins; uniform 2.6 mm elements (292k DOFs) give 13.8.
    from test_fea_estimate_verification import filleted_two_bore_part

    from fem import stress_study
    from fem.study import default_mesh_sizes

    source = None if part == "default link" else filleted_two_bore_part(tmp_path / "dog_bone.step")
    material = get_material("al6061-t6")
    estimate = stress_study(source, [material], base_mesh_size_m=default_mesh_sizes(source)[-1])[material.name]
    assert estimate.converged and estimate.rel_change <= 0.05
    assert len(estimate.levels) >= 2
    # Away from the clamp: the reported point is farther than the documented distance from both
    # rims (circles) of the clamped bore.
    bore = estimate.global_solution.link.fixed_bore
    rel = np.asarray(estimate.location_m) - bore.center_m
    axial = rel @ bore.axis
    radial = np.linalg.norm(rel - axial * bore.axis)
    to_rims = [np.hypot(radial - bore.radius_m, axial - end) for end in (-bore.length_m / 2, bore.length_m / 2)]
    assert min(to_rims) > estimate.clamp_distance_m > 0
