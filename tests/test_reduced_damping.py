"""The global damping law's O(N) form (dynamics.models.reduced_damping) against the dense modal C.

- Tight quadrature (tolerance 1e-13): the form is the dense C to round-off, and the integrator with it
  equals the dense run to round-off (both paths): the new form reduces to the old one.
- Default tolerance 1e-4: every mode's damping ratio within 1e-4 of zeta (the trapezoidal rule's
  error is the same for every eigenvalue, see the module), the matrix within 1e-4 of the dense one,
  and the integrator's station links' displacements within 1e-4 of the dense run's peak (the damping
  force changes by at most that fraction, so the response by at most that fraction of itself:
  measured 2.4e-5), accelerations within 1e-3 (see the test; measured 7.4e-4 at N = 85).
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain
from dynamics.models.reduced_damping import DEFAULT_DAMPING_TOLERANCE, reduced_damping
from dynamics.options import DEFAULT_PIN_CLEARANCE_M
from dynamics.response.metrics import station_links
from dynamics.solvers import clearance_verlet as verlet


def _chain(n, **kw):
    return ChainModel(n_links=n, link_mass_kg=2.03, stiffness_N_per_m=9.0092e7, friction_coefficient=0.35, **kw)


@pytest.mark.parametrize("n", [7, 85, 400])
def test_tight_quadrature_is_the_dense_matrix_to_round_off(n):
    chain = _chain(n)
    dense = chain.damping_matrix()
    np.testing.assert_allclose(reduced_damping(chain, 1e-13).dense(), dense, rtol=0, atol=1e-12 * np.abs(dense).max())


def test_rayleigh_damping_is_exact_without_nodes():
    chain = _chain(85, rayleigh_coefficients=(3.0, 2e-5))
    r = reduced_damping(chain)
    assert r.taus.size == 0
    dense = chain.damping_matrix()
    np.testing.assert_allclose(r.dense(), dense, rtol=0, atol=1e-13 * np.abs(dense).max())


@pytest.mark.parametrize("n", [85, 400])
def test_every_mode_keeps_its_damping_ratio_to_the_tolerance(n):
    chain = _chain(n)
    omega, phi = chain.modes()
    r = reduced_damping(chain)
    modal = phi.T @ r.dense() @ phi  # mass-normalised modes: diag(2 zeta omega) for the dense C
    zeta = np.diag(modal) / (2 * omega)
    assert np.max(np.abs(zeta / chain.damping_ratio - 1)) <= DEFAULT_DAMPING_TOLERANCE
    off = modal - np.diag(np.diag(modal))
    assert np.max(np.abs(off)) <= 1e-10 * np.max(np.abs(modal))  # still modal: no coupling
    dense = chain.damping_matrix()
    assert np.max(np.abs(r.dense() - dense)) <= DEFAULT_DAMPING_TOLERANCE * np.abs(dense).max()


def _window(model, sub=8, compiled=None):
    t = np.arange(241) / 4 / (6 * 180.0)  # 60 degrees at 4 per degree: the index's impacts
    cam = CamProgram.indexing("modified-sine", pitch_m=0.1125, rpm=180.0)
    tf = np.linspace(t[0], t[-1], sub * (t.size - 1) + 1)
    _, v, a, _ = cam.svaj(tf)
    n = model.n_links
    return verlet.integrate(
        model, v, a, tf[1] - tf[0], np.zeros(n), -v[0] * np.ones(n), out_every=sub, compiled=compiled
    )


@pytest.mark.parametrize("compiled", [None, False])
def test_integrator_with_the_tight_form_equals_the_dense_run(compiled):
    chain = _chain(40)
    dense = _window(ClearanceChain(chain, DEFAULT_PIN_CLEARANCE_M), compiled=compiled)
    reduced = _window(ClearanceChain(chain, DEFAULT_PIN_CLEARANCE_M, damping_tolerance=1e-13), compiled=compiled)
    assert dense.impacts > 0 and reduced.impacts == dense.impacts
    np.testing.assert_allclose(reduced.y, dense.y, rtol=0, atol=1e-10 * np.abs(dense.y).max())


@pytest.mark.parametrize("n", [85, 400])
def test_default_form_within_its_tolerance_of_the_dense_run(n):
    chain = _chain(n)
    dense = _window(ClearanceChain(chain, DEFAULT_PIN_CLEARANCE_M))
    reduced = _window(ClearanceChain(chain, DEFAULT_PIN_CLEARANCE_M, damping_tolerance=DEFAULT_DAMPING_TOLERANCE))
    cols = [link - 1 for link in station_links(n).values()]
    # accelerations through impacts: a small change moves an impact's instant, and the sampled
    # acceleration near it by up to ten times as much (measured 7.4e-4 of the peak at N = 85)
    for q, factor in (("y", 1.0), ("a", 10.0)):
        d, r = getattr(dense, q)[:, cols], getattr(reduced, q)[:, cols]
        assert np.max(np.abs(r - d)) <= factor * DEFAULT_DAMPING_TOLERANCE * np.max(np.abs(d))


def test_long_chain_memory_is_linear_no_dense_damping():
    model = ClearanceChain(_chain(2000), DEFAULT_PIN_CLEARANCE_M)
    assert model.damping_is_reduced
    op = model.damping_operator
    _, weights, factors, _ = op.packed()
    assert factors.shape == (weights.size, 3, 2000) and weights.size < 40
