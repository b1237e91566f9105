"""dynamics.models.topology: the chain's matrices derived from one topology equal the ones each module built
on its own before (the oracles below are those builders, kept verbatim)."""

import numpy as np
import pytest
import scipy.sparse as sp

from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain, Tensioner
from dynamics.models.topology import ChainTopology, Span, ring_topology
from dynamics.response.sweep import stiffness_matrix_sparse


def _old_dense_stiffness(model: ChainModel) -> np.ndarray:
    """ChainModel.stiffness_matrix before the topology (commit cab7c6f)."""
    n, k = model.n_links, model.stiffness_N_per_m
    kk = np.zeros((n, n))
    for j in range(n):
        i, l = j, (j + 1) % n
        kk[i, i] += k
        kk[l, l] += k
        kk[i, l] -= k
        kk[l, i] -= k
    kk[0, 0] += model.drive_stiffness
    return kk


def _old_sparse_stiffness(model: ChainModel) -> sp.csr_matrix:
    """dynamics.response.sweep.stiffness_matrix_sparse before the topology (commit cab7c6f)."""
    n, k = model.n_links, model.stiffness_N_per_m
    i = np.arange(n)
    j = (i + 1) % n
    rows = np.concatenate([i, j, i, j, [0]])
    cols = np.concatenate([i, j, j, i, [0]])
    vals = np.concatenate([np.full(n, k), np.full(n, k), np.full(n, -k), np.full(n, -k), [model.drive_stiffness]])
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


CASES = [
    ChainModel(2, 1.0, 5e6),
    ChainModel(3, 2.03, 9.27e7, preload_N=0.0),
    ChainModel(16, 2.03, 9.33e7, drive_stiffness_N_per_m=3e7, preload_N=500.0),
    ChainModel(85, 2.03, 9.33e7),
    ChainModel(85, 1.5, 1.2e8, drive_stiffness_N_per_m=1e12, rayleigh_coefficients=(2.0, 1e-5)),
    ChainModel(401, 2.0, 1e8, damping_ratio=0.02),
]


@pytest.mark.parametrize("model", CASES, ids=lambda m: f"N{m.n_links}")
def test_chain_matrices_equal_the_old_builders(model):
    # bit-identical (each entry is a small integer times k, summed exactly), so no result of the
    # existing models can move
    np.testing.assert_array_equal(model.stiffness_matrix(), _old_dense_stiffness(model))
    np.testing.assert_array_equal(stiffness_matrix_sparse(model).toarray(), _old_sparse_stiffness(model).toarray())
    np.testing.assert_array_equal(model.mass_matrix(), model.link_mass_kg * np.eye(model.n_links))


def _old_full_contact_stiffness(model, tensioner, s):
    """ClearanceChain.full_contact_stiffness as it was built before the topology: the chain's K with
    the carriage's row and column added by hand (the idler span s: stretch e_s + 2u)."""
    n, k = model.n_links, model.stiffness_N_per_m
    kk = np.zeros((n + 1, n + 1))
    kk[:n, :n] = _old_dense_stiffness(model)
    b = np.zeros(n + 1)
    b[(s + 1) % n] += 1.0
    b[s] -= 1.0
    b[n] = 2.0
    kk += k * np.outer(b, b)
    kk[:n, :n] -= k * np.outer(b[:n], b[:n])
    kk[n, n] += tensioner.rate_N_per_m
    return kk, np.diag(np.r_[np.full(n, model.link_mass_kg), tensioner.mass_kg])


@pytest.mark.parametrize("model", CASES[:5], ids=lambda m: f"N{m.n_links}")
@pytest.mark.parametrize("tensioner", [Tensioner(0.0, 5.0), Tensioner(2.5e5, 12.0, 300.0), Tensioner(1e9, 0.5)])
def test_the_carriage_topology_equals_the_clearance_chains_full_contact_matrices(model, tensioner):
    chain = ClearanceChain(model, 0.0, tensioner=tensioner)
    k_old, m_old = _old_full_contact_stiffness(model, tensioner, chain.idler_span)
    k_new, m_new = chain.full_contact_stiffness()  # derived from the topology since
    np.testing.assert_array_equal(k_new, k_old)
    np.testing.assert_array_equal(m_new, m_old)
    topo = ring_topology(
        model.n_links,
        model.link_mass_kg,
        model.stiffness_N_per_m,
        model.preload_N,
        model.drive_stiffness,
        carriage=(chain.idler_span, tensioner.rate_N_per_m, tensioner.mass_kg),
    )
    np.testing.assert_array_equal(topo.stiffness_matrix(), k_old)
    np.testing.assert_array_equal(topo.mass_matrix(), m_old)


def test_stretches_and_link_places():
    topo = ring_topology(5, 1.0, 1e6, 100.0, 1e6, carriage=(2, 1e5, 3.0))
    y = np.array([0.0, 1.0, 3.0, 6.0, 10.0, 0.5])
    # span j: y[j+1] - y[j]; span 2 (the carriage's) gains 2u; span 4 closes the loop
    np.testing.assert_allclose(topo.stretches_m(y), [1.0, 2.0, 3.0 + 1.0, 4.0, -10.0])
    np.testing.assert_array_equal(topo.link_dof(), np.arange(5))
    assert topo.n_links == 5 and topo.n_dof == 6


def test_a_span_naming_a_missing_dof_is_refused():
    with pytest.raises(ValueError, match="spans"):
        ChainTopology((1.0, 1.0), ((0,), (1,)), (Span(0, 2),), 1e6, 0.0)
