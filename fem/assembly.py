"""Isotropic linear-elasticity stiffness matrices, assembled fast from scalar blocks.

The vector unknown is stored interleaved, `u[3 * i + c]` = component c at scalar DOF i, which is
scikit-fem's own `ElementVector` numbering. Block (a, b) of the stiffness is

    K_ab[i, j] = integral(lam d_a phi_i d_b phi_j + mu d_b phi_i d_a phi_j + mu delta_ab grad phi_i . grad phi_j)

Six scalar assemblies (K_ba = K_ab^T) give the same matrix as scikit-fem's
`ElementVector` + `linear_elasticity` (tested to round-off) several times faster.

The six blocks are assembled without the material: with G_ab[i, j] = integral(d_a phi_i d_b phi_j)
(G_ba = G_ab^T), K_ab = lam G_ab + mu G_ab^T + mu delta_ab sum_c G_cc, so one assembly per mesh
(`ElasticityParts`) gives K for every isotropic material as K = lam A + mu B, a sparse sum.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import Basis, BilinearForm

DIM = 3


#: Threads for the stiffness assembly (two: the measured best on this 2-core machine).
ASSEMBLY_THREADS = 2


def assembly_threads() -> int:
    """ASSEMBLY_THREADS, or fewer where OMP_NUM_THREADS asks for fewer: Dask's worker processes
    set it to 1 because the workers, one per core, are the parallelism (two threads each would
    oversubscribe the cores and cost a design study its scaling)."""
    try:
        requested = int(os.environ.get("OMP_NUM_THREADS", ASSEMBLY_THREADS))
    except ValueError:
        requested = ASSEMBLY_THREADS
    return max(1, min(ASSEMBLY_THREADS, requested))


def _gradient_form(a: int, b: int, nthreads: int) -> BilinearForm:
    def form(u, v, w):
        return v.grad[a] * u.grad[b]

    return BilinearForm(form, nthreads=nthreads)


@dataclass(frozen=True, eq=False)
class ElasticityParts:
    """K = lam_Pa * volumetric + mu_Pa * shear for any isotropic material (interleaved, N/m per Pa)."""

    volumetric: sp.csr_matrix  # blocks G_ab
    shear: sp.csr_matrix  # blocks G_ab^T + delta_ab sum_c G_cc

    def matrix(self, lam_Pa: float, mu_Pa: float) -> sp.csr_matrix:
        return lam_Pa * self.volumetric + mu_Pa * self.shear

    def restricted(self, keep: np.ndarray) -> "ElasticityParts":
        """The parts on the rows and columns `keep` (e.g. the unconstrained DOFs)."""
        return ElasticityParts(self.volumetric[keep][:, keep], self.shear[keep][:, keep])


def elasticity_parts(basis: Basis, nthreads: int | None = None) -> ElasticityParts:
    """The material-free parts of the elasticity matrix of a scalar H1 basis used per component
    (nthreads None: `assembly_threads()`)."""
    nthreads = assembly_threads() if nthreads is None else nthreads
    g = {(a, b): _gradient_form(a, b, nthreads).assemble(basis) for a in range(DIM) for b in range(a, DIM)}
    laplacian = g[0, 0] + g[1, 1] + g[2, 2]
    shear = {(a, b): (g[a, b].T + laplacian if a == b else g[a, b].T) for a, b in g}
    return ElasticityParts(interleave(g, basis.N), interleave(shear, basis.N))


def interleave(blocks: dict[tuple[int, int], sp.spmatrix], n: int) -> sp.csr_matrix:
    """Join upper blocks K_ab (a <= b, each n x n) of a symmetric 3n x 3n matrix, interleaved."""
    grid = [[blocks[a, b] if a <= b else blocks[b, a].T for b in range(DIM)] for a in range(DIM)]
    # Blocked order (component-major) is cheap to build; one symmetric permutation interleaves it.
    # Measured 2-3x faster than joining COO triplets at 116k DOFs, identical matrix.
    perm = (np.arange(DIM)[None, :] * n + np.arange(n)[:, None]).ravel()
    return sp.bmat(grid, format="csr")[perm][:, perm]


def elasticity_matrix(basis: Basis, lam_Pa: float, mu_Pa: float, nthreads: int | None = None) -> sp.csr_matrix:
    """Stiffness matrix (N/m) of linear elasticity for a scalar H1 basis used per component."""
    return elasticity_parts(basis, nthreads).matrix(lam_Pa, mu_Pa)


def vector_dofs(scalar_dofs: np.ndarray) -> np.ndarray:
    """All three interleaved vector DOFs of the given scalar DOFs."""
    scalar_dofs = np.asarray(scalar_dofs).ravel()
    return (DIM * scalar_dofs[:, None] + np.arange(DIM)).ravel()


def rigid_body_modes(points_m: np.ndarray) -> np.ndarray:
    """The six rigid-body modes (3 translations, 3 rotations) at DOF locations (3, n) -> (3n, 6)."""
    n = points_m.shape[1]
    x = points_m - points_m.mean(axis=1, keepdims=True)
    modes = np.zeros((n, DIM, 6))
    for c in range(DIM):
        modes[:, c, c] = 1.0
    # rotation about axis r: e_r x x
    for r in range(DIM):
        omega = np.zeros(DIM)
        omega[r] = 1.0
        modes[:, :, DIM + r] = np.cross(omega, x.T)
    return modes.reshape(DIM * n, 6)
