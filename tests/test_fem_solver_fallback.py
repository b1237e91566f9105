"""AMG-CG falls back to a direct solver when it does not converge (forced here with one CG
iteration): the solution is the direct solver's, and the result and the progress line say so."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from fem_plate import plate_link

from fem import FeaSettings, analyse_link, get_material, solvers, stiffness_study
from fem.errors import FemWarning

ALUMINIUM = get_material("al6061-t6")


@pytest.fixture
def one_amg_iteration(monkeypatch):
    monkeypatch.setattr(solvers, "AMG_MAX_ITERATIONS", 1)


def _laplacian(n: int) -> sp.csr_matrix:
    """SPD: the 1-D Laplacian with both ends held, condition ~n^2 (one CG iteration is far off)."""
    return sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")


def test_amg_that_does_not_converge_is_solved_directly_and_says_so(one_amg_iteration):
    A, b = _laplacian(400), np.linspace(0.0, 1.0, 400)
    solved = solvers.solve_reported(A, b, "amg")
    assert solved.solver == solvers.direct_solver()
    assert solved.fallback.startswith("AMG-CG did not converge in 1 iterations")
    assert solved.fallback.endswith(f"solved by {solved.solver} instead")
    assert np.allclose(A @ solved.x, b, rtol=0, atol=1e-10 * np.linalg.norm(b))
    with pytest.warns(FemWarning, match="AMG-CG did not converge"):
        assert np.array_equal(solvers.solve(A, b, "amg"), solved.x)


def test_amg_that_converges_is_kept():
    solved = solvers.solve_reported(_laplacian(400), np.linspace(0.0, 1.0, 400), "amg")
    assert (solved.solver, solved.fallback) == ("amg", None)


def test_a_link_solved_after_the_fallback_has_the_direct_solvers_k(one_amg_iteration):
    plate = plate_link()
    direct = analyse_link(plate, ALUMINIUM, order=1, solver=solvers.direct_solver())
    fell_back = analyse_link(plate, ALUMINIUM, order=1, solver="amg")
    assert fell_back.solver == direct.solver and direct.solver_fallback is None
    assert "AMG-CG did not converge" in fell_back.solver_fallback
    assert fell_back.stiffness_N_per_m == pytest.approx(direct.stiffness_N_per_m, rel=1e-12)


@pytest.mark.filterwarnings("ignore:mesh. a wall")  # coarse on purpose: the 2.5 mm walls are thinner than 9 mm
def test_the_stiffness_study_says_so_in_its_result_and_progress_line(one_amg_iteration):
    lines: list[str] = []
    settings = FeaSettings(mesh_sizes_m=(0.012, 0.009), order=1, solver="amg", mirror_symmetry=False)
    estimate = stiffness_study(None, ALUMINIUM, settings, progress=lines.append)
    assert len(estimate.solver_fallbacks) == len(estimate.levels)  # a third level checks the thin walls
    assert all("AMG-CG did not converge" in f for f in estimate.solver_fallbacks)
    level_lines = [line for line in lines if line.startswith("FEA level")]
    assert len(level_lines) == len(estimate.levels)
    assert all(f"solved by {solvers.direct_solver()} instead" in line for line in level_lines)
