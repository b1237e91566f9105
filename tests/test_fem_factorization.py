"""fem.solvers' kept PARDISO factorisation, its CG and its dot product: the direct solve phase gives
pypardiso's solve to the bit, the CG converges to the exact solution of a nearby system, the dot
is the exact sum to rounding."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg
from threadpoolctl import threadpool_limits

from fem import solvers
from fem.errors import FemError

pypardiso = pytest.importorskip("pypardiso")


def _laplacian_3d(n: int, shift: float = 0.0) -> sp.csr_matrix:
    """SPD: the 7-point Laplacian on an n^3 grid, all faces held, plus shift * I."""
    line = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    eye = sp.identity(n)
    grid = sp.kron(sp.kron(line, eye), eye) + sp.kron(sp.kron(eye, line), eye) + sp.kron(sp.kron(eye, eye), line)
    return sp.csr_matrix(grid + shift * sp.identity(n**3))


def _pypardiso_solve(A: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
    """pypardiso's own factorise-then-solve with the settings Factorization uses."""
    solver = pypardiso.PyPardisoSolver(mtype=2)
    for one_based, value in solvers.PARDISO_IPARM.items():
        solver.set_iparm(one_based, value)
    upper = sp.triu(A, format="csr")
    solver.factorize(upper)
    try:
        return np.asarray(solver.solve(upper, b))
    finally:
        solver.free_memory(everything=True)


def test_the_direct_solve_phase_gives_pypardisos_solve_to_the_bit():
    A = _laplacian_3d(12)
    rng = np.random.default_rng(7)
    # one MKL thread: with more, PARDISO's sums depend on how many threads it gets, so two
    # factorisations of one matrix can differ in their last bits under load
    with threadpool_limits(limits=1):
        _compare_with_pypardiso(A, rng)


def _compare_with_pypardiso(A: sp.csr_matrix, rng: np.random.Generator) -> None:
    factor = solvers.Factorization(A)
    try:
        for b in (rng.standard_normal(A.shape[0]), np.linspace(-1.0, 2.0, A.shape[0])):
            x = factor.solve(b)
            assert np.array_equal(x, _pypardiso_solve(A, b))
            assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b)
    finally:
        factor.free()


def test_the_direct_solve_takes_a_strided_or_integer_right_hand_side_as_a_float_copy():
    A = _laplacian_3d(6)
    b = np.arange(2 * A.shape[0])[::2]  # int, not contiguous
    factor = solvers.Factorization(A)
    try:
        assert np.array_equal(factor.solve(b), factor.solve(b.astype(float).copy()))
    finally:
        factor.free()


def test_a_right_hand_side_of_the_wrong_size_is_a_one_line_error():
    factor = solvers.Factorization(_laplacian_3d(4))
    try:
        with pytest.raises(FemError, match=r"expected a right-hand side of shape \(64,\), got \(63,\)"):
            factor.solve(np.ones(63))
    finally:
        factor.free()


def test_cg_preconditioned_with_a_nearby_factor_converges_to_the_exact_solution():
    # as for another material: the preconditioner factorises a different (here shifted) matrix
    A, nearby = _laplacian_3d(10, shift=0.5), _laplacian_3d(10)
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    exact = scipy.sparse.linalg.spsolve(A.tocsc(), b)
    factor = solvers.Factorization(nearby)
    try:
        # A = nearby + 0.5 I >= nearby: the preconditioned spectrum is above 1
        x, iterations = solvers.preconditioned_cg(A, b, factor.solve, np.zeros_like(b), energy_rtol=1e-10)
    finally:
        factor.free()
    assert 1 < iterations < 30
    # the error's energy norm below 1e-10 of the solution's, and A's eigenvalues within [0.5, 12.5]
    # (Gershgorin): the error's 2-norm is below sqrt(cond(A)) = 5 times 1e-10 of the solution's
    assert np.linalg.norm(x - exact) <= 5e-10 * np.linalg.norm(exact)


def test_a_further_materials_cg_on_the_first_ones_factor_stops_within_its_energy_tolerance():
    # titanium's elasticity on aluminium's factor (their Poisson ratios differ, so no exact scaling):
    # the error's energy norm against the direct solve is below the tolerance times the solution's
    from skfem import Basis, ElementTetP1, MeshTet

    from fem.assembly import elasticity_parts, vector_dofs
    from fem.materials import get_material

    aluminium, titanium = get_material("al6061-t6"), get_material("ti-grade2")
    assert aluminium.poisson_ratio != titanium.poisson_ratio
    grid = np.linspace(0.0, 0.01, 5)
    basis = Basis(MeshTet.init_tensor(grid, grid, grid), ElementTetP1())
    held = vector_dofs(np.flatnonzero(basis.mesh.p[0] == 0.0))  # a cube clamped on one face
    parts = elasticity_parts(basis).restricted(np.setdiff1d(np.arange(3 * basis.N), held))
    K_first, K = parts.matrix(*aluminium.lame_Pa), parts.matrix(*titanium.lame_Pa)
    b = np.random.default_rng(5).standard_normal(K.shape[0])
    exact = scipy.sparse.linalg.spsolve(K.tocsc(), b)
    factor = solvers.Factorization(K_first)
    try:
        first_u = factor.solve(b)
        for tolerance in (solvers.REUSE_ENERGY_TOLERANCE, 1e-9):
            u = solvers.further_material_cg(K, b, factor, aluminium, first_u, titanium, tolerance)
            error = u - exact
            assert math.sqrt(error @ (K @ error)) <= tolerance * math.sqrt(b @ exact)
    finally:
        factor.free()


def test_dot_is_the_exact_sum_to_rounding():
    rng = np.random.default_rng(11)
    for n in (1, 17, 10_001, 100_000):
        a, b = rng.standard_normal(n), rng.standard_normal(n)
        exact = math.fsum(a * b)  # the products themselves rounded once: within n eps of the bound
        bound = n * np.finfo(float).eps * float(np.abs(a * b).sum())
        assert abs(solvers.dot(a, b) - exact) <= bound


def test_pair_keys_are_int32_only_where_every_key_fits():
    from fem.assembly import pair_key_dtype

    largest_int32 = np.iinfo(np.int32).max
    assert pair_key_dtype(1000) is np.int32
    assert pair_key_dtype(46340) is np.int32  # 46340^2 - 1 is the largest key
    assert 46340**2 <= largest_int32 < 46341**2
    assert pair_key_dtype(46341) is np.int64
    assert pair_key_dtype(np.int32(50_000)) is np.int64  # not squared in int32, where it wraps


@pytest.mark.parametrize("canonical", [True, False])
def test_the_upper_triangle_is_scipys_triu_to_the_bit(canonical):
    """`solvers.upper_triangle` (what PARDISO is given) against `sp.triu`: the same arrays, from a
    matrix with sorted entries (as fem.assembly makes them) and from one with unsorted and duplicate
    entries, which it leaves as it was given."""
    rng = np.random.default_rng(3)
    n = 40
    A = sp.random(n, n, density=0.2, random_state=rng, format="csr") + sp.eye(n, format="csr")
    if not canonical:  # each row reversed, its first entry repeated at its end
        data, indices, indptr = [], [], [0]
        for row in range(n):
            entries = slice(A.indptr[row], A.indptr[row + 1])
            data += [*A.data[entries][::-1], A.data[entries][-1]]
            indices += [*A.indices[entries][::-1], A.indices[entries][-1]]
            indptr.append(len(data))
        A = sp.csr_matrix((np.array(data), np.array(indices, np.int32), np.array(indptr, np.int32)), shape=(n, n))
        assert not A.has_canonical_format
    given = (A.data.copy(), A.indices.copy(), A.indptr.copy())
    upper, expected = solvers.upper_triangle(A), sp.triu(A, format="csr")
    for name in ("data", "indices", "indptr"):
        assert np.array_equal(getattr(upper, name), getattr(expected, name)), name
    assert all(np.array_equal(a, b) for a, b in zip(given, (A.data, A.indices, A.indptr), strict=True))
