"""Linear solvers for symmetric positive definite elasticity systems, behind one registry.

`solve(A, b, method="auto", near_nullspace=None)`; methods:

- "pardiso": MKL PARDISO sparse Cholesky (pypardiso, SPD mode mtype 2 on the upper triangle).
- "amg": pyamg smoothed aggregation preconditioned CG, the rigid-body modes as near-nullspace.
- "spsolve": SciPy's SuperLU, the reference (slow and memory hungry beyond ~50k DOFs).

"auto" is PARDISO where it is installed (fastest by measurement, see benchmarks/), else AMG.
"""

from __future__ import annotations

import contextlib
import ctypes
import glob
import os
import sys
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import FemError, FemWarning
from .materials import Material, lame_ratio_low
from .options import check_linear_solver

AMG_RELATIVE_TOLERANCE = 1e-10  # residual; k is then converged far below discretisation error
AMG_MAX_ITERATIONS = 1000  # CG iterations; the link's P2 systems converge in tens (measured)
# The CG that reuses another material's factorisation stops where its error's energy norm is below
# this fraction of the solution's (`preconditioned_cg`). k = F^2 / (f . u) is then within that
# fraction of the direct solve's (|f . e| = |u K e| <= |u|_K |e|_K): 1e-4, 1/85 of the default
# link's estimated 0.85 %. The stresses are linear in the error too: on the default link's levels
# (titanium on aluminium's factor) the peak moved by 1.4e-5 of itself and every node's von Mises by
# at most 5e-5 of the peak, against their estimated 3 %; k by 1.4e-6. Three iterations a level
# there, where a 1e-6 residual took six; each iteration shrinks the error 12-30-fold (measured).
REUSE_ENERGY_TOLERANCE = 1e-4
REUSE_MAX_ITERATIONS = 200


# MKL PARDISO settings (1-based iparm numbers as in Intel's documentation), against MKL's defaults
# on the default link's 72k-DOF P2 system (`python benchmarks/run.py --only pardiso_settings`, one
# thread, medians of 5): analysis 0.88 -> 0.47 s, one solve 0.14 -> 0.07 s, factorisation
# 1.68 / 1.80 s (unchanged within the spread), relative residual 1.1e-11 / 1.3e-11.
# - 1 = 1: use the values below, the rest stay 0;
# - 37 = -90: let PARDISO find the 3 x 3 nodal blocks of the vector field (variable block rows where
#   90 % of the pattern agrees): the ordering and symbolic analysis work on 1/9 of the graph;
# - 2 = 3: METIS nested dissection run in parallel (OpenMP), not 2 = 2's serial METIS (MKL's default);
# - 24 = 1: the two-level parallel factorisation, not the classic one;
#   both together, on the default link's two stiffness levels (39k unknowns each, MKL's two threads,
#   CPU s medians of 4 alternating, load 2.5-3.2): analysis 0.22 / 0.20 against 0.43 / 0.41,
#   factorisation 0.81 / 0.75 against 0.95 / 1.05, a back-substitution the same (0.04-0.05); the
#   stiffness step 9.62 against 10.07 CPU s (docs/performance.md); k moves by 2e-12 of itself (the
#   factor's rounding). 24 = 10 fails on this SPD matrix (error 1); 37 = 0 (no blocks) factorises
#   in about as little but doubles the analysis;
# - 8 = 0: no iterative refinement after a solve: for an SPD matrix without pivot perturbation it
#   does not change the residual's order here and costs extra products and back-substitutions,
#   which are most of a further material's CG.
PARDISO_IPARM = {1: 1, 2: 3, 8: 0, 24: 1, 37: -90}
PARDISO_SOLVE_PHASE = 33  # forward and backward substitution with the kept factor


def _point_pypardiso_at_mkl() -> None:
    """Tell pypardiso where MKL's runtime is, if it sits where the mkl wheel puts it.

    Without PYPARDISO_MKL_RT every PyPardisoSolver() looks the library up with find_library and a
    recursive glob of the environment: 0.3-0.5 s per solver (measured), paid per mesh level.
    """
    if "PYPARDISO_MKL_RT" in os.environ:
        return
    found = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len)
    if found:
        os.environ["PYPARDISO_MKL_RT"] = found[0]


# MKL PARDISO's error codes (Intel's documentation of the `error` argument) that a user can act on.
_PARDISO_ERRORS = {
    -2: "not enough memory",
    -3: "reordering failed",
    -4: "zero pivot (the matrix is singular: a flat element or a part not held)",
    -9: "not enough memory for the out-of-core solve",
    -11: "read/write problem with the out-of-core files",
    -12: "the matrix is not symmetric positive definite",
}
SOLVER_REMEDY = "pass a larger --mesh-size MM (fewer unknowns) or --solver amg (less memory)"


@contextlib.contextmanager
def explained_solver_errors(method: str, n_unknowns: int) -> Iterator[None]:
    """Turn a linear solver's failure (PyPardisoError, MemoryError) into a one-line FemError that
    says what failed and what to change."""
    try:
        yield
    except MemoryError:
        raise FemError(f"solver {method}: out of memory on {n_unknowns} unknowns; {SOLVER_REMEDY}") from None
    except Exception as exc:
        if type(exc).__name__ != "PyPardisoError":
            raise
        code = getattr(exc, "value", None)
        code = code if isinstance(code, int) else _error_code(str(exc))
        what = _PARDISO_ERRORS.get(code, "failed")
        raise FemError(f"solver {method}: error {code} ({what}) on {n_unknowns} unknowns; {SOLVER_REMEDY}") from None


def _error_code(message: str) -> int | None:
    """The number in pypardiso's message "The Pardiso solver failed with error code -2. ..."."""
    import re

    found = re.search(r"error code (-?\d+)", message)
    return int(found.group(1)) if found else None


class Factorization:
    """A kept MKL PARDISO Cholesky factorisation of one SPD matrix, to solve it again or to
    precondition a nearby one (another material on the same mesh). Call `free()` when done.

    The solves call PARDISO's solve phase (33) directly, with the matrix's 1-based indices
    converted once: pypardiso's `solve` makes the same call after comparing the matrix with its copy
    of the factorised one and converting the indices again, 4-5 ms of a 40 ms back-substitution at
    the default link's 37k unknowns (measured), and keeps that copy (16 MB there). The call uses
    pypardiso's handle, settings and library (`pt`, `iparm`, `_mkl_pardiso`): a pypardiso that
    renamed them fails tests/test_fem_factorization.py."""

    def __init__(self, A: sp.spmatrix):
        _point_pypardiso_at_mkl()
        import pypardiso

        self._solver = pypardiso.PyPardisoSolver(mtype=2)  # real symmetric positive definite
        for one_based, value in PARDISO_IPARM.items():
            self._solver.set_iparm(one_based, value)
        self._upper = upper_triangle(A)
        with explained_solver_errors("pardiso", A.shape[0]):
            self._solver.factorize(self._upper)
        self._solver.remove_stored_factorization()
        # as pypardiso passes them (`_call_pardiso`): CSR, 1-based, int32
        self._one_based_indptr = self._upper.indptr.astype(np.int32) + 1
        self._one_based_indices = self._upper.indices.astype(np.int32) + 1

    def solve(self, b: np.ndarray) -> np.ndarray:
        """A^-1 b for one right-hand side (1-D)."""
        b = np.ascontiguousarray(b, dtype=float)
        if b.shape != (self._upper.shape[0],):
            raise FemError(
                f"Factorization.solve: expected a right-hand side of shape ({self._upper.shape[0]},), got {b.shape}"
            )
        x = np.zeros_like(b)
        error = ctypes.c_int32(0)
        solver = self._solver
        int_p, double_p = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        solver._mkl_pardiso(
            solver.pt.ctypes.data_as(ctypes.POINTER(solver._pt_type[0])),
            ctypes.byref(ctypes.c_int32(1)),  # maxfct
            ctypes.byref(ctypes.c_int32(1)),  # mnum
            ctypes.byref(ctypes.c_int32(solver.mtype)),
            ctypes.byref(ctypes.c_int32(PARDISO_SOLVE_PHASE)),
            ctypes.byref(ctypes.c_int32(b.size)),
            self._upper.data.ctypes.data_as(double_p),
            self._one_based_indptr.ctypes.data_as(int_p),
            self._one_based_indices.ctypes.data_as(int_p),
            solver.perm.ctypes.data_as(int_p),
            ctypes.byref(ctypes.c_int32(1)),  # right-hand sides
            solver.iparm.ctypes.data_as(int_p),
            ctypes.byref(ctypes.c_int32(solver.msglvl)),
            b.ctypes.data_as(double_p),
            x.ctypes.data_as(double_p),
            ctypes.byref(error),
        )
        if error.value != 0:
            what = _PARDISO_ERRORS.get(error.value, "failed")
            raise FemError(f"solver pardiso: error {error.value} ({what}) on {b.size} unknowns; {SOLVER_REMEDY}")
        return x

    def free(self) -> None:
        self._solver.free_memory(everything=True)


def upper_triangle(A: sp.spmatrix) -> sp.csr_matrix:
    """`sp.triu(A, format="csr")` (the same arrays) taken from A's CSR arrays directly, without its
    round trip through COO: 17-26 against 41-52 ms CPU on the default link's finest level (37k
    unknowns, 2.6M entries)."""
    A = sp.csr_matrix(A)  # no copy of a CSR matrix
    if not A.has_canonical_format:  # sorted column indices, each entry once, as triu's COO round trip gives
        A = A.copy()  # the caller's matrix left as it is
        A.sum_duplicates()
    n = A.shape[0]
    rows = np.repeat(np.arange(n, dtype=A.indices.dtype), np.diff(A.indptr))
    keep = A.indices >= rows
    indptr = np.zeros(n + 1, dtype=A.indptr.dtype)
    np.cumsum(np.bincount(rows[keep], minlength=n), out=indptr[1:])
    return sp.csr_matrix((A.data[keep], A.indices[keep], indptr), shape=A.shape)


def preconditioned_cg(
    A: sp.spmatrix,
    b: np.ndarray,
    precondition: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    energy_rtol: float = REUSE_ENERGY_TOLERANCE,
    spectrum_low: float = 1.0,
) -> tuple[np.ndarray, int]:
    """Solve SPD A x = b by conjugate gradients preconditioned with `precondition` (P^-1, P SPD),
    from x0, until the error's energy norm |e|_A = sqrt(r A^-1 r) is below `energy_rtol` times the
    solution's, sqrt(b . x). The error's norm is bounded by the preconditioned residual, which CG
    computes anyway: r A^-1 r <= r P^-1 r / spectrum_low, where `spectrum_low` is a lower bound of
    P^-1 A's eigenvalues.

    With another material's factor as P (K = lam A_lam + mu A_mu on one mesh) the spectrum of
    P^-1 K lies between the ratios of the two materials' Lame constants (`materials.lame_ratio_low`),
    so a few iterations suffice (each one back-substitution and one product with A).
    Returns (x, iterations); FemError if the error does not fall below the tolerance.
    """
    x = np.array(x0, dtype=float)
    r = b - A @ x
    z = precondition(r)
    p = z.copy()
    rz = dot(r, z)
    for iteration in range(REUSE_MAX_ITERATIONS + 1):
        if rz <= energy_rtol**2 * spectrum_low * dot(b, x):
            return x, iteration
        Ap = A @ p
        alpha = rz / dot(p, Ap)
        x += alpha * p
        r -= alpha * Ap
        z = precondition(r)
        rz, rz_old = dot(r, z), rz
        p = z + (rz / rz_old) * p
    raise FemError(
        f"preconditioned CG did not converge in {REUSE_MAX_ITERATIONS} iterations "
        f"(estimated relative energy error {np.sqrt(max(rz, 0.0) / (spectrum_low * abs(dot(b, x)) or 1.0)):.1e})"
    )


def further_material_cg(
    K: sp.spmatrix,
    b: np.ndarray,
    first_factor: Factorization,
    first_material: Material,
    first_u: np.ndarray,
    material: Material,
    energy_rtol: float = REUSE_ENERGY_TOLERANCE,
) -> np.ndarray:
    """A further material's CG on the first one's factor: K u = b for `material` on the mesh where
    `first_material`'s system was factorised (`first_factor`) and solved (`first_u`, the same DOFs as
    b). The start is the first solution scaled by the Young's moduli (exact where the Poisson ratios
    agree); the first's factor preconditions, and `materials.lame_ratio_low` bounds the spectrum of
    P^-1 K from below for `preconditioned_cg`'s energy-norm stop at `energy_rtol`."""
    scale = first_material.youngs_modulus_Pa / material.youngs_modulus_Pa
    u, _ = preconditioned_cg(
        K,
        b,
        first_factor.solve,
        first_u * scale,
        energy_rtol,
        spectrum_low=lame_ratio_low(material, first_material),
    )
    return u


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """a . b of two 1-D float arrays in the calling thread, without BLAS.

    numpy's `a @ b` is OpenBLAS's ddot, which above 10,000 entries wakes OpenBLAS's worker thread;
    that thread then spins for tens of ms, taking a core from PARDISO's threads and the other
    stiffness level: in titanium's CG (three dots an iteration) it doubled the CG's CPU (measured,
    docs/performance.md). Rounding: a different summation order than ddot's, to a few ulp."""
    return float(np.einsum("i,i", a, b))


def _norm(a: np.ndarray) -> float:
    return float(np.sqrt(dot(a, a)))


def _pardiso(A: sp.csr_matrix, b: np.ndarray, near_nullspace: np.ndarray | None) -> np.ndarray:
    factor = Factorization(A)
    try:
        return factor.solve(b)
    finally:
        factor.free()


def _amg(A: sp.csr_matrix, b: np.ndarray, near_nullspace: np.ndarray | None) -> np.ndarray:
    import pyamg

    # improve_candidates=None: on the link's P2 systems the default candidate smoothing cost 3.3 s
    # of setup at 34k DOFs (0.2 s without) for the same CG iteration count (measured).
    ml = pyamg.smoothed_aggregation_solver(A.tocsr(), B=near_nullspace, symmetry="symmetric", improve_candidates=None)
    residuals: list[float] = []
    x = ml.solve(b, tol=AMG_RELATIVE_TOLERANCE, accel="cg", maxiter=AMG_MAX_ITERATIONS, residuals=residuals)
    if residuals[-1] > AMG_RELATIVE_TOLERANCE * np.linalg.norm(b) * 10:
        raise AmgNotConverged(
            f"AMG-CG did not converge in {AMG_MAX_ITERATIONS} iterations "
            f"(relative residual {residuals[-1] / np.linalg.norm(b):.1e})"
        )
    return x


class AmgNotConverged(FemError):
    """AMG-CG stopped above its residual tolerance (`solve` then falls back to a direct solver)."""


def _spsolve(A: sp.csr_matrix, b: np.ndarray, near_nullspace: np.ndarray | None) -> np.ndarray:
    from scipy.sparse.linalg import spsolve

    return spsolve(A.tocsc(), b)


def _has_pardiso() -> bool:
    _point_pypardiso_at_mkl()
    try:
        import pypardiso  # noqa: F401
    except (ImportError, OSError):
        return False
    return True


SOLVERS: dict[str, Callable[[sp.csr_matrix, np.ndarray, np.ndarray | None], np.ndarray]] = {
    "pardiso": _pardiso,
    "amg": _amg,
    "spsolve": _spsolve,
}


def resolve(method: str) -> str:
    """The concrete method "auto" stands for here; unknown names are a FemError."""
    if method == "auto":
        return "pardiso" if _has_pardiso() else "amg"
    check_linear_solver(method)
    return method


def direct_solver() -> str:
    """The direct solver to fall back on: PARDISO where it is installed, else SuperLU."""
    return "pardiso" if _has_pardiso() else "spsolve"


@dataclass(frozen=True)
class Solved:
    """A solution, the solver that produced it and, if it is not the one asked for, why."""

    x: np.ndarray
    solver: str
    fallback: str | None = None  # one line: why the asked-for solver's answer was not used


def solve_reported(
    A: sp.spmatrix, b: np.ndarray, method: str = "auto", near_nullspace: np.ndarray | None = None
) -> Solved:
    """Solve A x = b for symmetric positive definite A; where AMG-CG does not converge or pyamg is
    not installed, solve it again with `direct_solver()` and say so (`Solved.fallback`)."""
    method = resolve(method)
    A, b = sp.csr_matrix(A), np.asarray(b, dtype=float)
    try:
        with explained_solver_errors(method, A.shape[0]):
            return Solved(np.asarray(SOLVERS[method](A, b, near_nullspace)), method)
    except (AmgNotConverged, ImportError) as exc:
        if method != "amg":
            raise
        why = str(exc) if isinstance(exc, AmgNotConverged) else f"AMG-CG is not available ({exc})"
    direct = direct_solver()
    with explained_solver_errors(direct, A.shape[0]):
        x = np.asarray(SOLVERS[direct](A, b, None))
    return Solved(x, direct, f"{why}: solved by {direct} instead")


def solve(A: sp.spmatrix, b: np.ndarray, method: str = "auto", near_nullspace: np.ndarray | None = None) -> np.ndarray:
    """Solve A x = b for symmetric positive definite A (with `solve_reported`'s fallback from AMG-CG,
    said as a FemWarning: callers that keep the solver in their result call `solve_reported`)."""
    solved = solve_reported(A, b, method, near_nullspace)
    if solved.fallback is not None:
        warnings.warn(solved.fallback, FemWarning, stacklevel=2)
    return solved.x
