"""The stiffness study with its thin-wall size fields on (fem.study, geometry.meshing.THIN_WALL_FRACTION):
at sizes where the built-in link's 2.535 mm side rails are thinner than half the finest elements,
the rails are refined on every level, a third coarser level checks the asymptotic range
(`fem.study.with_wall_check_level`), and k's estimate bounds its error.

Reference: the built-in link's converged k (al6061-t6), 9.352e7 N/m, from three levels of this
code with the default settings at 4 / 3 / 2.25 mm (98,673 / 201,684 whole-link and 223,044
half-link unknowns, k 9.40986e7 / 9.39121e7 / 9.37761e7; no wall is refined there): extrapolated
9.35196e7 +- 0.333 % (the rate bracket's bound), observed rate 1.60 (the clamped bore rim and
re-entrant edges: h^1.42-1.5, fem.richardson), whose own extrapolation gives 9.352e7 too (79 s,
4.1 GB peak, a loaded 2-core machine):

    stiffness_study(None, get_material("al6061-t6"), mesh_sizes_m=(0.004, 0.003, 0.00225))
"""

from __future__ import annotations

import math
import warnings

import pytest

import geometry
from fem import get_material, stiffness_study
from fem.budget import mesh_dofs
from fem.quality import thin_wall_warning
from fem.settings import DEFAULT_BORE_REFINEMENT, levels_for_finest
from fem.study import refined_down_to_m, with_wall_check_level
from geometry.mesh_estimate import WallFeature
from geometry.session import taken_model

REFERENCE_K_N_PER_M = 9.352e7
ALUMINIUM = get_material("al6061-t6")


def _within_estimate(finest_m: float):
    estimate = stiffness_study(None, ALUMINIUM, mesh_sizes_m=levels_for_finest(finest_m))
    error = estimate.stiffness_N_per_m / REFERENCE_K_N_PER_M - 1
    assert abs(error) <= estimate.stiffness_rel_error_estimate, (error, estimate.stiffness_rel_error_estimate)
    return estimate


def test_at_12mm_the_rails_are_refined_and_k_is_within_its_estimate():
    # measured: 9.444e7 +- 9.3 % (+0.99 %: the 21.3 mm check level is far from the asymptotic
    # range); without the fields 9.492e7 +- 2.32 % (+1.50 %)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        estimate = _within_estimate(0.012)
    # the refined rails have an element through their thickness: no thin-wall warning about them
    assert not [w for w in caught if "wall about" in str(w.message)]
    assert len(estimate.levels) == 3
    plain = geometry.mesh_part(
        geometry.as_part(None), mesh_size_m=0.012, order=2, bore_refinement=DEFAULT_BORE_REFINEMENT, mirror=True
    )
    assert estimate.finest.dofs > 1.5 * mesh_dofs(plain.tets, plain.tets10, 2)


@pytest.mark.slow
@pytest.mark.parametrize("finest_m", [0.010, 0.008, 0.006])
def test_at_coarse_sizes_k_with_the_rails_refined_is_within_its_estimate(finest_m):
    # measured: 10 mm 9.461e7 +- 1.28 % (+1.17 %; its two finer levels alone: +- 0.90 %, outside;
    # without the fields 8.687e7 +- 8.0 %, -7.1 %), 8 mm 9.353e7 +- 1.82 % (+0.01 %),
    # 6 mm 9.267e7 +- 3.11 % (-0.91 %)
    _within_estimate(finest_m)


def test_the_thin_wall_warning_spares_the_walls_the_fields_refined():
    coarse = geometry.mesh_part(
        geometry.as_part(None), mesh_size_m=0.012, order=2, bore_refinement=DEFAULT_BORE_REFINEMENT, mirror=True
    )
    assert "2.5" in thin_wall_warning(coarse)  # the rails under 12 mm elements, not refined
    assert (
        thin_wall_warning(coarse, refined_down_to_m(geometry.as_part(None).geometry.mesh_features.walls, 0.012)) is None
    )
    assert refined_down_to_m((), 0.012) == math.inf


def test_a_check_level_only_where_a_wall_is_refined():
    rail = WallFeature(0.002535, 1e-3)
    assert with_wall_check_level((0.008, 0.006), (rail,), 0.006) == pytest.approx((0.008 * 4 / 3, 0.008, 0.006))
    assert with_wall_check_level((0.006, 0.0045), (rail,), 0.0045) == (0.006, 0.0045)  # the default levels
    assert with_wall_check_level((0.008, 0.006), (), 0.006) == (0.008, 0.006)
    assert with_wall_check_level((0.01, 0.008, 0.006), (rail,), 0.006) == (0.01, 0.008, 0.006)  # three given


def test_the_stages_level_count_is_the_studys(monkeypatch):
    """The FEA stage's "N mesh levels" line counts the study's planned levels: 3 where the rails are
    refined (10 mm on the built-in link), 2 at the default sizes."""
    import fem
    from fem.settings import FeaSettings
    from fem.study import planned_mesh_sizes
    from stages.fea import _solve_stiffness

    part = geometry.resolve_part(None)
    monkeypatch.setattr(fem, "stiffness_studies", lambda *args, **kwargs: {})  # the line, not the solves
    try:
        for settings, n_levels in ((FeaSettings.with_finest(0.010), 3), (FeaSettings(), 2)):
            assert len(planned_mesh_sizes(part, settings)[0]) == n_levels
            lines: list[str] = []
            _solve_stiffness(part, settings, [ALUMINIUM], None, lines.append, None, 0)
            assert lines == [f"FEA al6061-t6: built-in default link, P2, {n_levels} mesh levels"]
    finally:
        # the sizes measured the part keeping its mirror half for a finest level that never came:
        # removed, so that no later mesh of the built-in link's half in this process is meshed in it
        with taken_model(part.half_model_name):
            pass
