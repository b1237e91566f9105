"""The replica's matrices and forces are the script's (Appendix C), quirks included."""

import numpy as np
import pytest

from dynamics.errors import DynamicsError
from dynamics.models.mqp2012 import (
    MATERIALS,
    preload_links,
    preload_vector,
    replica_system,
    run_mqp2012,
    script_matrices,
)


def test_stiffness_matrix_layout():
    _, K, _, _, _ = script_matrices(8, 1.0, 1.0)
    expected = 2 * np.eye(8) - np.eye(8, k=1) - np.eye(8, k=-1)
    expected[0, 0] = 3
    expected[0, 7] = expected[7, 0] = -1
    assert np.array_equal(K, expected)


def test_damping_vector_and_asymmetric_corners():
    k, m, zeta = 2.0, 0.5, 0.13
    M, K, C, c, w = script_matrices(9, k, m, zeta)
    # c is 2 zeta m times the sorted natural frequencies of (K, M): check them independently.
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    assert np.allclose(w, np.sqrt(lam), rtol=1e-12)
    assert np.all(np.diff(c) >= 0)
    assert np.allclose(c, 2 * zeta * m * np.sqrt(lam), rtol=1e-12)
    assert C[0, 0] == 3 * c[0] and C[8, 8] == c[0] + c[8]
    assert C[8, 0] == -c[0] and C[0, 8] == -c[8]
    assert C[3, 3] == c[3] + c[4] and C[3, 4] == C[4, 3] == -c[4]
    assert not np.allclose(C, C.T)  # the script's C is not symmetric


@pytest.mark.parametrize("n", [8, 9, 10, 85, 86])
def test_preload_positions_follow_the_scripts_branches(n):
    # even N: [f; zeros((N-8)/2); 2224; zeros(5); -2224; zeros((N-8)/2)] -> links N/2-2 and N/2+4
    # odd N:  [f; zeros((N-7)/2); 2224; zeros(4); -2224; zeros((N-7)/2)] -> links (N-3)/2 and (N+7)/2
    plus, minus = preload_links(n)
    assert (plus, minus) == ((n // 2 - 2, n // 2 + 4) if n % 2 == 0 else ((n - 3) // 2, (n + 7) // 2))
    p = preload_vector(n)
    assert p.size == n and p[plus - 1] == 2224.0 and p[minus - 1] == -2224.0 and np.count_nonzero(p) == 2


def test_preload_positions_for_the_reports_chain():
    assert preload_links(85) == (41, 46)
    assert preload_links(8) == (2, 8)


def test_friction_is_the_scripts_tiny_term():
    system, _ = replica_system("al6061-t6", 10, 0.35)
    m = MATERIALS["al6061-t6"][1]
    v = np.array([1.0, -2.0, 0.0] + [1.0] * 7)
    g = system.nonlinear_force(np.zeros(10), v)
    # The script subtracts m * b * sign(v) from the acceleration (b = 0.35 * 9.8): as a force, m^2 b sign(v).
    assert np.allclose(np.linalg.solve(system.mass, g)[:3], [-m * 0.35 * 9.8, m * 0.35 * 9.8, 0.0])
    assert replica_system("al6061-t6", 10, 0.0)[0].nonlinear_force is None


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(material="steel"), "material"),
        (dict(n_links=7), "n_links"),
        (dict(rpm=0.0), "rpm"),
        (dict(friction=-0.1), "friction"),
        (dict(cams=("no-such-law",)), "no-such-law"),
        (dict(cams=()), "cams"),
    ],
)
def test_bad_inputs(kwargs, match):
    with pytest.raises(DynamicsError, match=match):
        run_mqp2012(**kwargs)
