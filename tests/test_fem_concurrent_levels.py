"""A stiffness study solves its mesh levels side by side (issue #13): same answer as one after the
other, the levels really overlap, and an error in a level's thread reaches the caller."""

from __future__ import annotations

import threading

import pytest

import fem.study
from fem import FemError, get_material, stiffness_studies

pytestmark = pytest.mark.filterwarnings("ignore:mesh. a wall:fem.errors.FemWarning")  # coarse on purpose
ALUMINIUM, TITANIUM = get_material("al6061-t6"), get_material("ti-grade2")
COARSE_SIZES_M = (0.012, 0.009)  # the default link, coarse: a few seconds per study
# its 2.535 mm rails are refined at 9 mm, so the study adds a third level (fem.study.with_wall_check_level)
N_LEVELS = 3


def _study(concurrent: bool, progress=None):
    return stiffness_studies(
        None, [ALUMINIUM, TITANIUM], mesh_sizes_m=COARSE_SIZES_M, concurrent_levels=concurrent, progress=progress
    )


def test_concurrent_levels_give_the_sequential_answer_in_level_order():
    lines: list[str] = []
    together, apart = _study(True, lines.append), _study(False)
    for name in (ALUMINIUM.name, TITANIUM.name):
        a, b = together[name], apart[name]
        # the same meshes and solves; PARDISO's threads may sum in another order: round-off only
        assert [lv[:2] for lv in a.levels] == [lv[:2] for lv in b.levels]
        assert [lv[2] for lv in a.levels] == pytest.approx([lv[2] for lv in b.levels], rel=1e-10)
        assert a.stiffness_N_per_m == pytest.approx(b.stiffness_N_per_m, rel=1e-10)
        assert a.stiffness_rel_error_estimate == pytest.approx(b.stiffness_rel_error_estimate, rel=1e-6)
        assert a.finest.mesh_size_m == COARSE_SIZES_M[-1]
    assert [line.split(",")[0] for line in lines] == [
        f"FEA level {level}/{N_LEVELS}" for level in range(1, N_LEVELS + 1) for _ in (ALUMINIUM, TITANIUM)
    ]
    first = together[ALUMINIUM.name].timing_s
    assert 0 < first["wall"] and "wall" not in together[TITANIUM.name].timing_s


def _meeting_levels(monkeypatch, parties: int) -> list[str]:
    """Make every level's solve wait at a barrier until `parties` levels are solving at once."""
    barrier = threading.Barrier(parties, timeout=60)
    threads: list[str] = []
    solve = fem.study.analyse_link_materials

    def meeting(*args, **kwargs):
        threads.append(threading.current_thread().name)
        barrier.wait()
        return solve(*args, **kwargs)

    monkeypatch.setattr(fem.study, "analyse_link_materials", meeting)
    return threads


def test_levels_are_solved_at_the_same_time_in_threads_of_their_own(monkeypatch):
    threads = _meeting_levels(monkeypatch, parties=N_LEVELS)  # a sequential study would time out here
    stiffness_studies(None, [ALUMINIUM], mesh_sizes_m=COARSE_SIZES_M, concurrent_levels=True)
    assert len(set(threads)) == N_LEVELS and all(name.startswith("fem-level") for name in threads)


def test_without_concurrency_one_level_at_a_time(monkeypatch):
    threads = _meeting_levels(monkeypatch, parties=1)
    solving = []
    solve = fem.study.analyse_link_materials

    def one_at_a_time(*args, **kwargs):
        solving.append(1)
        assert len(solving) == 1, "two levels were being solved at once"
        try:
            return solve(*args, **kwargs)
        finally:
            solving.pop()

    monkeypatch.setattr(fem.study, "analyse_link_materials", one_at_a_time)
    stiffness_studies(None, [ALUMINIUM], mesh_sizes_m=COARSE_SIZES_M, concurrent_levels=False)
    assert len(threads) == N_LEVELS


@pytest.mark.parametrize("concurrent", [True, False])
def test_an_error_in_a_level_reaches_the_caller(monkeypatch, concurrent):
    solve = fem.study.analyse_link_materials

    def failing(link, *args, **kwargs):
        if kwargs.get("stress"):  # the finest level
            raise FemError("PARDISO: the finest level failed")
        return solve(link, *args, **kwargs)

    monkeypatch.setattr(fem.study, "analyse_link_materials", failing)
    with pytest.raises(FemError, match="finest level failed"):
        stiffness_studies(None, [ALUMINIUM], mesh_sizes_m=COARSE_SIZES_M, concurrent_levels=concurrent)
