"""fem.settings.FeaSettings: the FEA's defaults and checks in one object, and the studies' keyword
form is the same settings (the same discrete problems, k equal to the last digit)."""

from __future__ import annotations

import pytest

from fem import FeaSettings, FemError, get_material, stiffness_study
from fem.settings import DEFAULT_BORE_REFINEMENT, LEVEL_RATIO, levels_for_finest

ALUMINIUM = get_material("al6061-t6")
COARSE_LEVELS_M = (0.012, 0.009)


def test_the_defaults_are_the_studies_defaults():
    s = FeaSettings()
    assert (
        s.mesh_sizes_m,
        s.order,
        s.curved,
        s.mirror_symmetry,
        s.load_N,
        s.solver,
        s.bore_refinement,
        s.concurrent_levels,
        s.stress_tolerance,
    ) == (None, 2, True, True, 1000.0, "auto", DEFAULT_BORE_REFINEMENT, True, 0.05)
    assert s.mesh_order == 2 and FeaSettings(curved=False).mesh_order == 1 and FeaSettings(order=1).mesh_order == 1


def test_with_finest_adds_the_coarser_level():
    assert FeaSettings.with_finest(0.0045).mesh_sizes_m == pytest.approx((0.0045 * LEVEL_RATIO, 0.0045), rel=1e-15)
    assert FeaSettings.with_finest(None).mesh_sizes_m is None
    assert FeaSettings(mesh_sizes_m=[0.006, 0.0045]).mesh_sizes_m == (0.006, 0.0045)  # a tuple of floats
    assert FeaSettings.with_finest(0.0045).mesh_sizes_m == levels_for_finest(0.0045)


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"order": 3}, "element order 3: expected one of 1, 2 .*; set it with --order"),
        (
            {"solver": "cholesky"},
            "linear solver 'cholesky': expected one of auto, pardiso, amg, spsolve; set it with python -m fem --solver",
        ),
        ({"mesh_sizes_m": (0.004, 0.006)}, "sizes must decrease"),
        ({"mesh_sizes_m": (0.006,)}, "expected 2 or 3 sizes"),
        ({"load_N": 0.0}, "load_N must be a positive number"),
        ({"stress_tolerance": 1.5}, r"tolerance=1.5: expected a relative change in \(0, 1\)"),
    ],
)
def test_bad_settings_are_refused_on_construction(fields, message):
    with pytest.raises(FemError, match=message):
        FeaSettings(**fields)


def test_keyword_changes_are_the_settings_fields():
    with pytest.raises(TypeError):
        stiffness_study(None, ALUMINIUM, mesh_size_mm=4.5)
    with pytest.raises(FemError, match="element order"):
        stiffness_study(None, ALUMINIUM, FeaSettings(), order=3)


@pytest.mark.filterwarnings("ignore:mesh. a wall")  # coarse on purpose: the 2.5 mm walls are thinner than 9 mm
def test_the_keyword_form_solves_the_same_problem():
    settings = FeaSettings(mesh_sizes_m=COARSE_LEVELS_M, order=1, mirror_symmetry=False)
    by_object = stiffness_study(None, ALUMINIUM, settings)
    by_keywords = stiffness_study(None, ALUMINIUM, mesh_sizes_m=COARSE_LEVELS_M, order=1, mirror_symmetry=False)
    assert by_object.stiffness_N_per_m == by_keywords.stiffness_N_per_m
    assert by_object.levels == by_keywords.levels


def test_the_element_order_message_follows_the_declared_orders(monkeypatch):
    from fem import options

    monkeypatch.setattr(options, "ELEMENT_ORDERS", (1, 2, 3))
    options.check_element_order(3)
    with pytest.raises(FemError, match=r"element order 4: expected one of 1, 2, 3 "):
        options.check_element_order(4)
