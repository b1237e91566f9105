"""The step loop's layout of the machine's topology (dynamics.solvers.machine_verlet._layout): its
gathers give the incidence's stretches B q and forces B^T T (the topology's own sparse B, carriage
shares included), for the machines the layouts build and for a topology where a DOF is behind or
ahead of two spans (the layout's extra entries) and spans have held ends."""

from types import SimpleNamespace

import numpy as np
import pytest

from dynamics.models.chain import ChainModel
from dynamics.models.clearance import Tensioner
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import MachineLayout
from dynamics.models.wheels import Wheel
from dynamics.solvers import machine_verlet as mv

WHEEL = Wheel(12, 0.1125, 6, 0.688)


def _stretches_and_forces(lay, q, t):
    """B q and B^T t through the layout's gathers, as the step loop takes them (carriage shares too)."""
    qx, tx = np.append(q, 0.0), np.append(t, 0.0)
    e = qx[lay.ends[1]] - qx[lay.ends[0]]
    e[lay.carriage[0]] += lay.carriage_gain * qx[lay.carriage[1]]
    f = tx[lay.sides[1]] - tx[lay.sides[0]]
    np.add.at(f, lay.extra[0], -lay.extra_sign * tx[lay.extra[1]])
    np.add.at(f, lay.carriage[1], lay.carriage_gain * tx[lay.carriage[0]])
    return e, f


@pytest.mark.parametrize("drive", ["wheels", "link"])
@pytest.mark.parametrize("tensioner", [None, Tensioner(1e5, 5.0, 100.0)])
def test_the_layout_is_the_topologys_incidence(drive, tensioner):
    layout = MachineLayout(drive, WHEEL, WHEEL, None, True) if drive == "wheels" else MachineLayout()
    model = ClearanceMachine.of(ChainModel(41, 2.03, 9.331e7), layout, tensioner, 94e-6)
    b = model.topology.incidence().toarray()
    rng = np.random.default_rng(1)
    q, t = rng.standard_normal(b.shape[1]), rng.standard_normal(b.shape[0])
    e, f = _stretches_and_forces(mv._layout(model.arrays), q, t)
    np.testing.assert_allclose(e, b @ q, rtol=0, atol=1e-14)
    np.testing.assert_allclose(f, b.T @ t, rtol=0, atol=1e-14)


def test_a_dof_on_two_spans_and_held_ends_take_the_extra_entries():
    rng = np.random.default_rng(0)
    n, ns = 9, 14
    span_int = np.full((ns, 4), -1, dtype=np.int64)
    span_int[:, :2] = rng.integers(-1, n, (ns, 2))  # -1: a held end
    arrays = SimpleNamespace(span_int=span_int, span_float=np.zeros((ns, 2)), dof_float=np.zeros((n, 7)))
    lay = mv._layout(arrays)
    b = np.zeros((ns, n))
    for j, (behind, ahead) in enumerate(span_int[:, :2]):
        if ahead >= 0:
            b[j, ahead] += 1.0
        if behind >= 0:
            b[j, behind] -= 1.0
    assert lay.extra_sign.size > 0
    q, t = rng.standard_normal(n), rng.standard_normal(ns)
    e, f = _stretches_and_forces(lay, q, t)
    np.testing.assert_allclose(e, b @ q, rtol=0, atol=1e-14)
    np.testing.assert_allclose(f, b.T @ t, rtol=0, atol=1e-14)
