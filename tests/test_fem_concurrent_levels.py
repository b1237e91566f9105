"""A stiffness study solves its mesh levels side by side (issue #13): same answer as one after the
other, the levels really overlap, one factorisation alive at a time (issue #24: the FEA's peak
memory), and an error in a level's thread reaches the caller."""

from __future__ import annotations

import threading
import time

import pytest

import fem.heap
import fem.solvers
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
    trims = []
    monkeypatch.setattr(fem.study, "release_free_memory", lambda: trims.append(threading.current_thread().name))
    stiffness_studies(None, [ALUMINIUM], mesh_sizes_m=COARSE_SIZES_M, concurrent_levels=False)
    assert len(threads) == N_LEVELS
    assert trims == ["MainThread"]  # after the levels only: each level reuses the freed pages of the one before


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


def test_levels_side_by_side_factorise_one_at_a_time_and_give_their_heap_back(monkeypatch):
    """The levels start together (a barrier), yet no two factorisations are alive at once (the
    study's solve slot); the levels that waited for it, and every level when done, trimmed the heap."""
    threads = _meeting_levels(monkeypatch, parties=N_LEVELS)
    alive, most_alive = [], []
    factorisation = fem.solvers.Factorization

    class Counted(factorisation):
        def __init__(self, A):
            alive.append(self)
            most_alive.append(len(alive))
            super().__init__(A)

        def free(self):
            super().free()
            alive.remove(self)

    monkeypatch.setattr(fem.solvers, "Factorization", Counted)
    slots: list[fem.heap.TrimmingLock] = []

    class Recorded(fem.heap.TrimmingLock):
        def __init__(self):
            super().__init__()
            slots.append(self)

    monkeypatch.setattr(fem.study, "TrimmingLock", Recorded)
    trims = []
    monkeypatch.setattr(fem.study, "release_free_memory", lambda: trims.append(threading.current_thread().name))
    stiffness_studies(None, [ALUMINIUM, TITANIUM], mesh_sizes_m=COARSE_SIZES_M, concurrent_levels=True)
    assert len(set(threads)) == N_LEVELS
    assert len(most_alive) == N_LEVELS and max(most_alive) == 1 and not alive
    assert len(slots) == 1 and slots[0].trimmed_waits >= 1  # the barrier made at least one level wait
    # each level's thread once its level is done, then the study's after the levels
    assert sorted(trims) == sorted([*threads, "MainThread"])


def test_a_trimming_lock_excludes_and_only_a_waiter_trims(monkeypatch):
    trims = []
    monkeypatch.setattr(fem.heap, "release_free_memory", lambda: trims.append(1))
    lock = fem.heap.TrimmingLock()
    with lock:
        pass
    assert lock.trimmed_waits == 0 and not trims  # free: taken at once
    order = []

    def waiter():
        with lock:
            order.append("waiter")

    with lock:
        thread = threading.Thread(target=waiter)
        thread.start()
        while lock.trimmed_waits == 0:  # the waiter has trimmed and now blocks
            time.sleep(0.001)
        order.append("holder")
    thread.join(timeout=10)
    assert order == ["holder", "waiter"] and lock.trimmed_waits == 1 and trims == [1]
