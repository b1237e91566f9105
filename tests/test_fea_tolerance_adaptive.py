"""stiffness_to_tolerance: refines until the Richardson estimate meets the tolerance, honestly."""

from __future__ import annotations

import pytest

import fem
import geometry
from fem.adaptive import bounding_diagonal_m, stiffness_to_tolerance, stiffnesses_to_tolerance
from fem.richardson import extrapolate

ALUMINIUM = fem.get_material("al6061-t6")
TITANIUM = fem.get_material("ti-grade2")
START_M = 0.012  # the default start on the default link; fixed here so the level sizes are known


SOLVES: list[int] = []  # DOFs of every analyse_link call made by the fixture's runs, in order
LOOSE_LEVELS: dict = {}  # the levels the loose run and the run sharing them solved (fem.adaptive's `solved`)


@pytest.fixture(scope="module")
def coarse_and_tighter():
    """Runs on the default link: loose (5 %, aluminium and titanium on shared meshes), then tighter
    (2 %, aluminium) sharing the loose run's solved levels."""
    import fem.adaptive

    def counted(link, material, **kwargs):
        solution = fem.analyse_link(link, material, **kwargs)
        SOLVES.append(solution.dofs)
        return solution

    lines_loose: list[str] = []
    solved = LOOSE_LEVELS
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(fem.adaptive, "analyse_link", counted)
        both = stiffnesses_to_tolerance(
            None, [ALUMINIUM, TITANIUM], 0.05, start_mesh_size_m=START_M, progress=lines_loose.append, solved=solved
        )
        tighter = stiffness_to_tolerance(None, ALUMINIUM, 0.02, start_mesh_size_m=START_M)
        SOLVES.append(-1)  # marks where the run sharing the loose run's levels starts
        reused = stiffnesses_to_tolerance(None, [ALUMINIUM], 0.02, start_mesh_size_m=START_M, solved=solved)
    return both[ALUMINIUM.name], tighter, lines_loose, both[TITANIUM.name], reused[ALUMINIUM.name]


def test_estimate_meets_the_tolerance(coarse_and_tighter):
    loose, tighter, _, titanium, _ = coarse_and_tighter
    assert loose.stiffness_rel_error_estimate <= 0.05
    assert titanium.stiffness_rel_error_estimate <= 0.05
    assert tighter.stiffness_rel_error_estimate <= 0.02


def test_tighter_tolerance_needs_more_levels_each_one_solve(coarse_and_tighter):
    loose, tighter, lines, _, _ = coarse_and_tighter
    assert len(tighter.levels) > len(loose.levels) >= 2  # the bound needs two levels
    # The tighter run walks the same sequence (same sizes, same meshes, so the same k to solver
    # round-off), which is what lets a later pass reuse an earlier one's levels.
    for a, b in zip(loose.levels, tighter.levels):
        assert a[0] == pytest.approx(b[0], rel=1e-12)
        assert a[1] == b[1]
        assert a[2] == pytest.approx(b[2], rel=1e-9)  # direct solver round-off on ~1e4-1e5 DOFs
    sizes = [level[0] for level in tighter.levels]
    for coarse, fine in zip(sizes, sizes[1:]):
        assert coarse / fine == pytest.approx(4 / 3, rel=1e-12)
    assert len(lines) == len(loose.levels)
    assert all("DOFs" in line and f"{ALUMINIUM.name} " in line and f"{TITANIUM.name} " in line for line in lines)


def test_a_later_pass_solves_only_the_new_levels(coarse_and_tighter):
    loose, tighter, _, _, reused = coarse_and_tighter
    shared_run = SOLVES[SOLVES.index(-1) + 1 :]
    # only the levels finer than the loose run's, each once, and the same answer as a fresh run
    assert shared_run == [dofs for _, dofs, _ in tighter.levels[len(loose.levels) :]]
    assert [level[:2] for level in reused.levels] == [level[:2] for level in tighter.levels]
    # same meshes, so the same k up to direct-solver round-off (as between the loose and tight runs)
    assert reused.stiffness_N_per_m == pytest.approx(tighter.stiffness_N_per_m, rel=1e-9)
    assert reused.stiffness_rel_error_estimate == pytest.approx(tighter.stiffness_rel_error_estimate, rel=1e-6)


def test_levels_kept_for_a_later_run_are_not_solved_again(coarse_and_tighter):
    """The levels as the FEA cache keeps them (JSON records, stages.fea.store_levels): a later run's
    pass to the same tolerance solves nothing and gives the same estimate; the one level whose fields
    the stress study needs, its finest, is solved again only at `with_finest_fields` and equals the
    one solved before."""
    import json

    import fem.adaptive
    from fem.adaptive import SolvedLevel, level_records, solved_levels_from, with_finest_fields
    from fem.settings import FeaSettings

    *_, before = coarse_and_tighter  # aluminium at 2 %, on the levels in LOOSE_LEVELS
    kept = solved_levels_from(json.loads(json.dumps(level_records(LOOSE_LEVELS))))
    solves: list[int] = []

    def counted(link, material, **kwargs):
        solution = fem.analyse_link(link, material, **kwargs)
        solves.append(solution.dofs)
        return solution

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(fem.adaptive, "analyse_link", counted)
        lines: list[str] = []
        again = stiffnesses_to_tolerance(
            None, [ALUMINIUM], 0.02, start_mesh_size_m=START_M, solved=kept, progress=lines.append
        )[ALUMINIUM.name]
        assert solves == [] and all(line.endswith("solved in an earlier run") for line in lines)
        assert again.stiffness_N_per_m == before.stiffness_N_per_m
        assert again.stiffness_rel_error_estimate == before.stiffness_rel_error_estimate
        assert again.levels == before.levels
        assert isinstance(again.finest, SolvedLevel) and again.finest == SolvedLevel.of(before.finest)
        fields = with_finest_fields(None, FeaSettings(), [ALUMINIUM], {ALUMINIUM.name: again})[ALUMINIUM.name]
    assert solves == [before.finest.dofs]  # the finest level, once, for its fields
    assert fields.stiffness_N_per_m == before.stiffness_N_per_m  # the estimate's own numbers
    solution = fields.finest
    assert solution.stiffness_N_per_m == pytest.approx(before.finest.stiffness_N_per_m, rel=1e-9)
    assert solution.peak_von_mises_Pa_per_N == pytest.approx(before.finest.peak_von_mises_Pa_per_N, rel=1e-9)


def test_extrapolation_uses_the_last_two_levels(coarse_and_tighter):
    _, tighter, _, _, _ = coarse_and_tighter
    last = tighter.levels[-2:]
    fit = extrapolate([k for _, _, k in last], [dofs for _, dofs, _ in last])
    assert tighter.stiffness_N_per_m == fit.extrapolated
    assert tighter.stiffness_rel_error_estimate == fit.rel_error_estimate
    assert tighter.stiffness_finest_N_per_m == last[-1][2]
    assert tighter.finest.dofs == last[-1][1]


def test_materials_share_the_meshes(coarse_and_tighter):
    aluminium, _, _, titanium, _ = coarse_and_tighter
    assert [level[:2] for level in aluminium.levels] == [level[:2] for level in titanium.levels]
    # Titanium is stiffer (E 105 vs 69 GPa); k is not exactly proportional to E (nu differs).
    assert titanium.stiffness_N_per_m > aluminium.stiffness_N_per_m


def test_cap_on_dofs_is_a_clear_error():
    # 12 mm and 9 mm give about 11k and 18k DOFs, so the third level (~29k) is above 20k.
    with pytest.raises(fem.FemError, match=r"rel_tolerance=0\.001 not reached.*max_dofs = 20000"):
        stiffness_to_tolerance(None, ALUMINIUM, 0.001, start_mesh_size_m=START_M, max_dofs=20_000)


@pytest.mark.parametrize("tolerance", [0.0, -0.01, 1.5, float("nan")])
def test_bad_tolerance_is_rejected(tolerance):
    with pytest.raises(fem.FemError, match="rel_tolerance"):
        stiffness_to_tolerance(None, ALUMINIUM, tolerance)


def test_default_start_size_comes_from_the_cad_bounding_box():
    # Measured 167.87 mm for the default link (geometry's default element size, 4.2 mm, is this
    # diagonal / 40); the example STEP file is the same link, so the same diagonal to CAD tolerance.
    assert bounding_diagonal_m(None) == pytest.approx(0.1679, abs=1e-4)
    assert bounding_diagonal_m(geometry.EXAMPLE_STEP) == pytest.approx(bounding_diagonal_m(None), rel=1e-5)


def test_bad_start_size_is_rejected():
    with pytest.raises(fem.FemError, match="start_mesh_size_m"):
        stiffness_to_tolerance(None, ALUMINIUM, 0.05, start_mesh_size_m=-1.0)


@pytest.mark.slow
def test_estimate_is_honest_against_a_finer_reference(coarse_and_tighter):
    """The actual error of the returned k is at most 2x its estimate (the estimate is not overconfident).

    Reference: Richardson from three curved-P2 levels each finer than any level of the runs above
    (3.8, 2.85, 2.5 mm; ~116k-330k DOFs) on the whole link, as the adaptive runs mesh it; its own
    estimated error must be well below the errors being checked, else the comparison would mean
    nothing.
    """
    reference = fem.stiffness_study(None, ALUMINIUM, mesh_sizes_m=(0.0038, 0.00285, 0.0025), mirror_symmetry=False)
    for estimate in coarse_and_tighter[:2]:
        assert reference.stiffness_rel_error_estimate < 0.5 * estimate.stiffness_rel_error_estimate
        actual = abs(estimate.stiffness_N_per_m - reference.stiffness_N_per_m) / reference.stiffness_N_per_m
        assert actual <= 2 * estimate.stiffness_rel_error_estimate


def test_an_unreached_tolerance_carries_the_best_estimate_the_solved_levels_meet():
    """--tolerance goes on at the best k its levels reached (stages.tolerance): the estimate the
    error carries is a tolerance that the same solved levels meet with no new solve."""
    import fem.adaptive

    solved: dict = {}
    # 12, 9 and 6.75 mm give about 11k, 18k and 29k DOFs; the fourth level (~47k) is above 40k
    with pytest.raises(fem.adaptive.ToleranceNotReached) as unreached:
        stiffnesses_to_tolerance(None, [ALUMINIUM], 1e-4, start_mesh_size_m=START_M, max_dofs=40_000, solved=solved)
    assert unreached.value.over_dofs
    best = unreached.value.best_rel_error
    assert 1e-4 < best < 0.05
    solves: list[int] = []
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(fem.adaptive, "analyse_link", lambda *a, **k: solves.append(1))
        again = stiffnesses_to_tolerance(
            None, [ALUMINIUM], best * (1 + 1e-9), start_mesh_size_m=START_M, max_dofs=40_000, solved=solved
        )
    assert solves == []
    assert again[ALUMINIUM.name].stiffness_rel_error_estimate == pytest.approx(best, rel=1e-9)
