"""fem.budget: the memory model's arithmetic and the unknowns it counts (its calibration against
measured peaks is in its docstring; tests/test_wild_corpus.py measures runs against the budget)."""

import numpy as np
import pytest

from fem.budget import BASE_BYTES, MemoryBudget, levels_dofs, mesh_dofs, peak_bytes
from fem.errors import FemError


def test_p2_unknowns_are_three_per_vertex_and_edge_of_two_tets_sharing_a_face():
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]]).T  # 5 vertices, 9 edges
    assert mesh_dofs(tets, None, order=2) == 3 * (5 + 9)
    assert mesh_dofs(tets, None, order=1) == 3 * 5


def test_coarsening_by_the_factor_brings_the_estimate_within_the_budget():
    budget = MemoryBudget.gigabytes(2.0)
    dofs = levels_dofs(2_000_000, 2, 4 / 3)
    assert not budget.fits(dofs)
    factor = budget.coarsening(dofs)
    assert budget.fits(levels_dofs(int(dofs[0] / factor**3), 2, 4 / 3))


def test_the_estimate_grows_with_the_unknowns_from_the_base():
    assert peak_bytes([0]) == BASE_BYTES
    assert peak_bytes([100_000, 40_000]) < peak_bytes([200_000, 80_000])


def test_a_budget_below_the_base_is_refused_naming_the_option():
    with pytest.raises(FemError, match="--max-memory"):
        MemoryBudget.gigabytes(0.1)


def test_the_memory_budget_range_has_one_home_in_settings_limits_that_both_clis_and_the_fea_apply():
    from fem.cli import main as fem_main
    from fem.settings import FeaSettings
    from settings import LIMITS
    from settings.run import MIN_MAX_MEMORY_GB

    assert BASE_BYTES == MIN_MAX_MEMORY_GB * 1e9  # the smallest budget is the model's base
    expected = LIMITS["max_memory_gb"].problem(0.5)
    assert expected.startswith("--max-memory: expected a memory budget > 0.55 GB")
    for make in (lambda: FeaSettings(max_memory_gb=0.5), lambda: MemoryBudget.gigabytes(0.5)):
        with pytest.raises(FemError) as raised:
            make()
        assert str(raised.value) == expected
    assert fem_main(["--max-memory", "0.5"]) == 2
    assert LIMITS["max_memory_gb"].problem(0.56) is None
