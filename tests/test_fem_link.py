"""analyse_link on a gmsh plate with two bores (no geometry stage needed)."""

from dataclasses import replace

import numpy as np
import pytest
from fem_plate import plate_link

from fem import FemError, analyse_link, get_material, problem
from fem.link import bearing_traction, skfem_mesh

ALUMINIUM = get_material("al6061-t6")


@pytest.fixture(scope="module")
def plate():
    return plate_link(0.008)


@pytest.fixture(scope="module")
def plate_quadratic():
    return plate_link(0.008, order=2)


@pytest.fixture(scope="module")
def solution(plate_quadratic):
    return analyse_link(plate_quadratic, ALUMINIUM)


def test_work_and_energy_forms_of_k_agree(solution):
    # F / delta (delta from integral t.u) and F^2 / 2U are equal for the exact discrete
    # solution; PARDISO's residual (~1e-15 relative, condition ~1e7) bounds the difference.
    assert solution.stiffness_N_per_m == pytest.approx(solution.stiffness_from_energy_N_per_m, rel=1e-9)


def test_mass_is_density_times_cad_volume(solution, plate_quadratic):
    assert solution.mass_kg == pytest.approx(2700.0 * plate_quadratic.cad_volume_m3, rel=1e-12)
    # Curved P2 cells follow the bores: the meshed volume matches the CAD to ~1e-6 (straight
    # cells cut the circles' chords, ~1e-3 at this size).
    assert solution.mesh_volume_m3 == pytest.approx(plate_quadratic.cad_volume_m3, rel=1e-5)


def test_stiffness_scales_exactly_with_E_at_fixed_poisson_ratio(plate):
    base = analyse_link(plate, ALUMINIUM, order=1)
    stiffer = analyse_link(plate, replace(ALUMINIUM, youngs_modulus_Pa=3 * ALUMINIUM.youngs_modulus_Pa), order=1)
    # K is linear in E; only round-off of the direct solve remains.
    assert stiffer.stiffness_N_per_m == pytest.approx(3 * base.stiffness_N_per_m, rel=1e-10)
    # stress per newton does not depend on E
    assert stiffer.peak_von_mises_Pa_per_N == pytest.approx(base.peak_von_mises_Pa_per_N, rel=1e-8)


def test_stiffness_and_stress_per_newton_do_not_depend_on_load(plate):
    a = analyse_link(plate, ALUMINIUM, order=1, load_N=1.0)
    b = analyse_link(plate, ALUMINIUM, order=1, load_N=5000.0)
    assert a.stiffness_N_per_m == pytest.approx(b.stiffness_N_per_m, rel=1e-10)
    assert a.peak_von_mises_Pa_per_N == pytest.approx(b.peak_von_mises_Pa_per_N, rel=1e-10)
    assert np.allclose(5000 * a.displacement_m, b.displacement_m, rtol=0, atol=1e-10 * np.abs(b.displacement_m).max())


def test_bearing_pressure_has_the_resultant_F_along_the_load_direction(plate_quadratic, solution):
    # On the exact half cylinder p0 = 2F / (pi R L) gives resultant F along d and none across.
    # Curved P2 facets represent the bore to ~1e-6, so the normalised p0 matches to ~1e-4.
    mesh, index = skfem_mesh(plate_quadratic, 2)
    loaded = problem.facet_indices(mesh, index[plate_quadratic.loaded_bore_facets])
    bore = plate_quadratic.loaded_bore
    p0 = 2 * 1000.0 / (np.pi * bore.radius_m * bore.length_m)
    f = problem.traction_load(solution.basis, loaded, bearing_traction(bore, plate_quadratic.load_direction, p0))
    resultant = problem.as_components(f).sum(axis=1)
    assert resultant @ plate_quadratic.load_direction == pytest.approx(1000.0, rel=1e-4)
    assert np.linalg.norm(resultant - 1000.0 * plate_quadratic.load_direction) < 1e-3 * 1000.0


@pytest.mark.parametrize("order", [1, 2])
def test_the_bearing_load_is_scikit_fems_facet_basis_load_to_rounding(plate_quadratic, plate, order):
    # fem.problem.traction_load takes the facet points' reference coordinates from the faces they
    # lie on; scikit-fem's FacetBasis inverts the cells' maps at them (Newton's method on the curved
    # cells): the same load vector to rounding, on curved and on straight cells
    from skfem import FacetBasis, LinearForm

    link = plate_quadratic if order == 2 else plate
    mesh, index = skfem_mesh(link, order)
    assert mesh.affine == (order == 1)
    loaded = problem.facet_indices(mesh, index[link.loaded_bore_facets])
    basis = problem.scalar_basis(mesh, order)
    traction = bearing_traction(link.loaded_bore, link.load_direction, 1.0)
    ours = problem.traction_load(basis, loaded, traction)
    facet_basis = FacetBasis(mesh, basis.elem, facets=loaded, intorder=problem.TRACTION_INTORDER)
    forms = [LinearForm(lambda v, w, c=c: traction(np.asarray(w.x))[c] * v) for c in range(3)]
    theirs = np.column_stack([form.assemble(facet_basis) for form in forms]).ravel()
    assert np.count_nonzero(theirs) > 100
    assert np.max(np.abs(ours - theirs)) <= 1e-13 * np.max(np.abs(theirs))


def test_loaded_bore_moves_along_the_load_and_fixed_bore_stays(solution, plate_quadratic):
    x = solution.basis.doflocs
    near_loaded = np.linalg.norm(x - plate_quadratic.loaded_bore.center_m[:, None], axis=0) < 1.01 * 0.008
    assert np.all(solution.displacement_m[0, near_loaded] > 0)
    on_fixed = np.abs(np.hypot(x[0], x[1]) - 0.008) < 1e-9
    assert np.all(solution.displacement_m[:, on_fixed] == 0)


def test_p2_converges_faster_than_p1_to_the_same_stiffness():
    # FE stiffness is an upper bound decreasing to the exact value (measured on this plate:
    # P1 4.17e8 / 4.09e8 / 4.01e8 and curved P2 3.9407e8 / 3.9353e8 / 3.9323e8 at 8 / 6 / 4 mm).
    coarse, fine = plate_link(0.008, order=2), plate_link(0.005, order=2)
    p1 = [analyse_link(m, ALUMINIUM, order=1).stiffness_N_per_m for m in (coarse, fine)]
    p2 = [analyse_link(m, ALUMINIUM, order=2).stiffness_N_per_m for m in (coarse, fine)]
    assert p1[0] > p1[1] > p2[0] > p2[1]
    assert (p2[0] - p2[1]) < 0.1 * (p1[0] - p1[1])
    assert p1[1] == pytest.approx(p2[1], rel=0.05)


def test_peak_stress_away_from_clamp_excludes_the_clamp_rim(solution):
    assert 0 < solution.peak_von_mises_away_from_clamp_Pa_per_N <= solution.peak_von_mises_Pa_per_N
    assert solution.clamp_exclusion_radius_m == pytest.approx(0.25 * 0.008)


def test_p1_on_the_quadratic_mesh_ignores_mid_edge_nodes(plate_quadratic, plate):
    # The order-2 LinkMesh carries extra points; P1 must drop them (no singular matrix).
    s = analyse_link(plate_quadratic, ALUMINIUM, order=1)
    assert s.dofs == 3 * len(np.unique(plate_quadratic.tets))


@pytest.mark.parametrize("solver", ["amg", "spsolve"])
def test_solvers_agree_with_pardiso(plate, solver):
    # AMG-CG stops at a 1e-10 relative residual: k (a quadratic functional) to ~1e-9.
    reference = analyse_link(plate, ALUMINIUM, order=1, solver="pardiso").stiffness_N_per_m
    assert analyse_link(plate, ALUMINIUM, order=1, solver=solver).stiffness_N_per_m == pytest.approx(
        reference, rel=1e-8
    )


def test_bad_inputs_are_fem_errors(plate):
    with pytest.raises(FemError, match="order"):
        analyse_link(plate, ALUMINIUM, order=3)
    with pytest.raises(FemError, match="load_N"):
        analyse_link(plate, ALUMINIUM, load_N=0.0)
    with pytest.raises(FemError, match="linear solver 'magic'"):
        analyse_link(plate, ALUMINIUM, solver="magic")
    swapped = replace(plate, loaded_bore_facets=plate.loaded_bore_facets[:, :0])
    with pytest.raises(FemError, match="loaded_bore_facets"):
        analyse_link(swapped, ALUMINIUM)
    interior = replace(plate, fixed_bore_facets=plate.tets[:3, :5])
    with pytest.raises(FemError, match="interior faces"):
        analyse_link(interior, ALUMINIUM)
    not_faces = replace(plate, fixed_bore_facets=np.array([[0], [1], [2]]) + plate.tets[0, 0])
    with pytest.raises(FemError, match="not facets|not tetrahedron vertices"):
        analyse_link(not_faces, ALUMINIUM)


@pytest.mark.parametrize(
    "sizes, fragment",
    [
        ((0.004, 0.006), "decrease"),
        ((0.006,), "2 or 3"),
        ((0.008, -0.004), "positive"),
        ((0.01, 0.008, 0.006, 0.004), "2 or 3"),
    ],
)
def test_study_rejects_bad_mesh_sizes_before_meshing(sizes, fragment):
    from fem import stiffness_study

    with pytest.raises(FemError, match=fragment):
        stiffness_study(None, ALUMINIUM, mesh_sizes_m=sizes)
