"""The FEA stage on the geometry stage's default link and on STEP exports of it."""

from dataclasses import replace

import pytest

from fem import analyse_link, get_material, stiffness_study
from geometry import DEFAULT_LINK, EXAMPLE_STEP, LinkFeatures, load_link, nominal_volume_m3, write_step

ALUMINIUM = get_material("al6061-t6")
REPORT_K_AL_N_PER_M = 9.27e7
# Coarse meshes keep these tests fast; at 8 mm curved P2 is ~3 % stiff (against an extrapolated
# 9.32e7 N/m), while two different 8 mm meshes of the same part scatter by <= 0.1 % (measured on
# the sharp-cornered link), so "same part, same k" is checked to 0.5 %.
COARSE_M = 0.008
SAME_PART_REL = 5e-3


def solve(source, material=ALUMINIUM, mesh_size_m=COARSE_M, order=2):
    link = load_link(source, mesh_size_m=mesh_size_m, order=order, bore_refinement=0.7)
    return analyse_link(link, material, order=order)


@pytest.fixture(scope="module")
def default():
    return solve(None)


def test_mass_is_density_times_the_closed_form_cad_volume(default):
    # geometry's closed-form volume of the parametric solid; OpenCASCADE's is exact to round-off.
    assert default.mass_kg == pytest.approx(2700.0 * nominal_volume_m3(DEFAULT_LINK), rel=1e-6)


def test_curved_cells_hold_the_cad_volume_once_they_resolve_the_fillets():
    # The 1 mm pocket-floor fillet cannot be represented by 8 mm cells (0.3 % too much volume
    # there, measured); at the default finest size, 4.5 mm, curved P2 cells hold the volume to
    # 4e-4 (measured), straight ones not (concave fillets and bores cut by chords).
    import numpy as np
    from skfem import Basis, ElementTetP2

    from fem.link import skfem_mesh

    link = load_link(None, mesh_size_m=0.0045, order=2, bore_refinement=0.7)
    volumes = [
        float(np.sum(Basis(skfem_mesh(link, 2, curved=c)[0], ElementTetP2(), intorder=2).dx)) for c in (True, False)
    ]
    assert volumes[0] == pytest.approx(link.cad_volume_m3, rel=5e-4)
    assert abs(volumes[0] / link.cad_volume_m3 - 1) < 0.5 * abs(volumes[1] / link.cad_volume_m3 - 1)


def test_calibration_against_the_report(default):
    # Even the coarse, too stiff 8 mm value must be within the 15 % of the report.
    assert default.stiffness_N_per_m == pytest.approx(REPORT_K_AL_N_PER_M, rel=0.15)


def test_k_scales_exactly_with_E_at_fixed_poisson_ratio(default):
    titanium_like = replace(ALUMINIUM, youngs_modulus_Pa=105e9)
    scaled = analyse_link(default.link, titanium_like)
    assert scaled.stiffness_N_per_m == pytest.approx(default.stiffness_N_per_m * 105e9 / 68.9e9, rel=1e-10)


def test_k_decreases_under_refinement_towards_the_extrapolated_value():
    # FE stiffness is an upper bound that decreases as the mesh is refined.
    estimate = stiffness_study(None, ALUMINIUM, mesh_sizes_m=COARSE_LEVELS_M)
    ks = [k for _, _, k in estimate.levels]
    assert ks[0] > ks[1] > ks[2] > estimate.stiffness_N_per_m
    assert estimate.monotone


# Levels coarser than the default: their elements are thicker than the 6.9 mm web, so k is not yet
# in its asymptotic range there and the estimate is wide (7 %, measured); whether its interval
# holds the finer default study's k is the slow test's business.
COARSE_LEVELS_M = (0.011, 0.008, 0.0065)


@pytest.mark.slow
def test_default_study_meets_the_one_percent_target_and_the_reports_figures():
    # The done-when: error estimate below 1 % with the default levels (timing is in the
    # README, not asserted). Measured: k = 9.328e7 N/m +- 0.91 % (aluminium), +0.6 % against the
    # report's 9.27e7 (the sharp-cornered link was -2.8 %); titanium 1.416e8 +- 0.94 %, -1.6 % against 1.439e8.
    estimate = stiffness_study(None, ALUMINIUM)
    assert estimate.stiffness_rel_error_estimate < 0.01
    assert estimate.stiffness_N_per_m == pytest.approx(REPORT_K_AL_N_PER_M, rel=0.03)
    coarse = stiffness_study(None, ALUMINIUM, mesh_sizes_m=COARSE_LEVELS_M)
    gap = abs(coarse.stiffness_N_per_m - estimate.stiffness_N_per_m) / estimate.stiffness_N_per_m
    assert gap <= coarse.stiffness_rel_error_estimate + estimate.stiffness_rel_error_estimate


@pytest.fixture(scope="module")
def split_bores(tmp_path_factory):
    d = tmp_path_factory.mktemp("steps")
    features = LinkFeatures(split_bores=True)
    return {
        unit: solve(write_step(DEFAULT_LINK, d / f"link_{unit}.step", unit=unit, features=features))
        for unit in ("mm", "m")
    }


def test_same_part_in_mm_and_m_with_split_bores_gives_same_k_and_mass(split_bores, default):
    mm, m = split_bores["mm"], split_bores["m"]
    assert mm.mass_kg == pytest.approx(m.mass_kg, rel=1e-9)
    assert mm.mass_kg == pytest.approx(default.mass_kg, rel=1e-6)
    assert mm.pitch_m == pytest.approx(0.1125, rel=1e-9) and m.pitch_m == pytest.approx(0.1125, rel=1e-9)
    assert mm.stiffness_N_per_m == pytest.approx(m.stiffness_N_per_m, rel=SAME_PART_REL)
    assert mm.stiffness_N_per_m == pytest.approx(default.stiffness_N_per_m, rel=SAME_PART_REL)


def test_exported_part_with_fillets_and_chamfers_in_mm_and_m(tmp_path):
    # The shipped example (mm, split bores, 1 mm chamfer on top and fillet under each bore) and
    # the same part written in metres: the same solid, so the same k and mass.
    features = LinkFeatures(split_bores=True, bore_edge_break_m=0.001)
    in_m = solve(write_step(DEFAULT_LINK, tmp_path / "link_m.step", unit="m", features=features))
    in_mm = solve(EXAMPLE_STEP)
    assert in_mm.mass_kg == pytest.approx(in_m.mass_kg, rel=1e-9)
    assert in_mm.stiffness_N_per_m == pytest.approx(in_m.stiffness_N_per_m, rel=SAME_PART_REL)
    assert in_mm.bore_radius_m == pytest.approx(DEFAULT_LINK.bore_radius_m, rel=1e-9)
