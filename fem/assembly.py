"""Isotropic linear-elasticity stiffness matrices, assembled in one vectorised pass.

The vector unknown is stored interleaved, `u[3 * i + c]` = component c at scalar DOF i, which is
scikit-fem's own `ElementVector` numbering. With G_ab[i, j] = integral(d_a phi_i d_b phi_j), block
(a, b) of the stiffness is

    K_ab = lam G_ab + mu G_ab^T + mu delta_ab sum_c G_cc

(tested equal to scikit-fem's `ElementVector` + `linear_elasticity` to round-off). All nine G_ab
share the scalar matrix's sparsity, and G_ab^T at (i, j) is G_ba at (i, j), so one pass gives the
3 x 3 block of every scalar entry: the element integrals are one batched product of the basis
gradients, summed into the scalar pattern once, and both material-free parts (`ElasticityParts`)
are laid out on one interleaved pattern, so K = lam A + mu B for any isotropic material is a sum of
two data arrays. Against six scikit-fem scalar assemblies joined with `scipy.sparse.bmat` and a
permutation, then restricted by fancy indexing: 2.1 s to 1.7 s for the default link's two levels
(the assembly line of `benchmarks/bench_fea_time_to_k.py`, run here and on a checkout of the commit
before, a4bc287), and a material's matrix is no longer a sparse sum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import Basis

DIM = 3


@dataclass(frozen=True, eq=False)
class ElasticityParts:
    """K = lam_Pa * volumetric + mu_Pa * shear for any isotropic material (interleaved, N/m per Pa).

    Both parts live on one sparsity pattern (`indptr`, `indices`, sorted), so a material's matrix
    and the restriction to free DOFs are array operations on the data."""

    indptr: np.ndarray
    indices: np.ndarray
    volumetric_data: np.ndarray  # blocks G_ab
    shear_data: np.ndarray  # blocks G_ab^T + delta_ab sum_c G_cc
    size: int

    def _csr(self, data: np.ndarray) -> sp.csr_matrix:
        matrix = sp.csr_matrix((data, self.indices, self.indptr), shape=(self.size, self.size), copy=False)
        matrix.has_sorted_indices = True
        return matrix

    def matrix(self, lam_Pa: float, mu_Pa: float) -> sp.csr_matrix:
        return self._csr(lam_Pa * self.volumetric_data + mu_Pa * self.shear_data)

    def restricted(self, keep: np.ndarray) -> ElasticityParts:
        """The parts on the rows and columns `keep` (sorted DOF indices, e.g. the unconstrained ones)."""
        kept_dof = np.zeros(self.size, dtype=bool)
        kept_dof[keep] = True
        new_index = np.cumsum(kept_dof) - 1
        rows = _entry_rows(self.indptr)
        kept = kept_dof[rows] & kept_dof[self.indices]
        size = int(kept_dof.sum())
        indptr = np.zeros(size + 1, dtype=self.indptr.dtype)
        np.cumsum(np.bincount(new_index[rows[kept]], minlength=size), out=indptr[1:])
        return ElasticityParts(
            indptr,
            new_index[self.indices[kept]].astype(self.indices.dtype),
            self.volumetric_data[kept],
            self.shear_data[kept],
            size,
        )


def _entry_rows(indptr: np.ndarray) -> np.ndarray:
    """The row of every stored entry of a CSR pattern."""
    return np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))


def elasticity_parts(basis: Basis) -> ElasticityParts:
    """The material-free parts of the elasticity matrix of a scalar H1 basis used per component."""
    blocks, indptr, indices = _gradient_blocks(basis)
    # shear block (a, b) at (i, j): G_ab^T[i, j] = G_ba[i, j], plus delta_ab sum_c G_cc[i, j]
    shear = blocks.transpose(0, 2, 1) + np.einsum("scc->s", blocks)[:, None, None] * np.eye(DIM)
    return _interleaved_parts(indptr, indices, blocks, shear, basis.N)


def pair_key_dtype(n: int) -> type:
    """The integer type of the keys i n + j of the pairs of n DOFs: int32 where they fit, which numpy
    sorts 20-25 % faster than int64 (measured on the default link's 2.4M keys)."""
    return np.int32 if int(n) ** 2 <= np.iinfo(np.int32).max else np.int64


def _gradient_blocks(basis: Basis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """G_ab[i, j] for all a, b on the scalar pattern: (nnz, 3, 3) values, CSR indptr and indices."""
    n_local = basis.Nbfun
    grads = np.array([np.asarray(basis.basis[i][0].grad) for i in range(n_local)])  # (n_local, 3, E, Q)
    n_elements = grads.shape[2]
    by_element = grads.transpose(2, 0, 1, 3).reshape(n_elements, n_local * DIM, -1)  # rows (i, a)
    weighted = by_element * np.asarray(basis.dx)[:, None, :]
    local = np.matmul(by_element, weighted.transpose(0, 2, 1))  # (E, (i, a), (j, b))
    # each element pair's 3 x 3 block contiguous: rows (E, i, j), columns (a, b)
    pair_blocks = local.reshape(n_elements, n_local, DIM, n_local, DIM).transpose(0, 1, 3, 2, 4)
    pair_blocks = pair_blocks.reshape(-1, DIM * DIM)
    dofs = np.asarray(basis.element_dofs, dtype=pair_key_dtype(basis.N))  # (n_local, E)
    rows = np.broadcast_to(dofs.T[:, :, None], (n_elements, n_local, n_local)).ravel()
    cols = np.broadcast_to(dofs.T[:, None, :], (n_elements, n_local, n_local)).ravel()
    keys = rows * int(basis.N) + cols  # in the dofs' type
    order = np.argsort(keys, kind="stable")  # each entry's pairs together, in increasing order
    sorted_keys = keys[order]
    starts = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
    return _summed(order, starts, pair_blocks).reshape(-1, DIM, DIM), *_scalar_pattern(sorted_keys[starts], basis.N)


def _summed(order: np.ndarray, starts: np.ndarray, pair_blocks: np.ndarray) -> np.ndarray:
    """Each entry's sum of the element pairs' blocks (rows of `pair_blocks`) that lie on it, the
    pairs `order[starts[e]:starts[e + 1]]` of entry e in increasing order: one product with the 0/1
    matrix of entries by pairs, whose rows those are, so every entry adds its terms in the order nine
    `np.bincount(entry, weights=...)` calls did, the same to the bit, in one pass over the blocks
    instead of nine strided copies and scatters (0.03-0.05 CPU s a default level). The stable sort
    of the pairs' keys is that matrix's CSR form (0.02-0.03 CPU s a level less than scattering each
    pair's entry and transposing the pairs-by-entries matrix, which a sort of the keys needed too)."""
    n_pairs = order.size
    by_entry = sp.csr_matrix((np.ones(n_pairs), order, np.append(starts, n_pairs)), shape=(starts.size, n_pairs))
    return by_entry @ pair_blocks


def _scalar_pattern(entry_keys: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR indptr and indices of the sorted keys i n + j of a scalar pattern's entries."""
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(entry_keys // n, minlength=n), out=indptr[1:])
    return indptr, entry_keys % n


def _interleaved_parts(
    indptr: np.ndarray, indices: np.ndarray, volumetric: np.ndarray, shear: np.ndarray, n: int
) -> ElasticityParts:
    """Interleave scalar-pattern 3 x 3 blocks: scalar entry (i, j) becomes rows 3i + a, columns 3j + b,
    each row's columns sorted (row i's columns j in order, then b). That is the CSR form of the
    block matrix (BSR) of those blocks, which SciPy converts in one compiled pass: 4-5x less CPU
    than numpy's scatter through an index array of all the entries (measured on the default levels)."""
    shape = (DIM * n, DIM * n)
    volumetric_csr = sp.bsr_matrix((volumetric, indices, indptr), shape=shape).tocsr()
    shear_csr = sp.bsr_matrix((shear, indices, indptr), shape=shape).tocsr()
    return ElasticityParts(volumetric_csr.indptr, volumetric_csr.indices, volumetric_csr.data, shear_csr.data, DIM * n)


def elasticity_matrix(basis: Basis, lam_Pa: float, mu_Pa: float) -> sp.csr_matrix:
    """Stiffness matrix (N/m) of linear elasticity for a scalar H1 basis used per component."""
    return elasticity_parts(basis).matrix(lam_Pa, mu_Pa)


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
