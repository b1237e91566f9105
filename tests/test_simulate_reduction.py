"""simulate(..., n_modes=r): the chain in its r lowest modes (dynamics/models/reduction.py)."""

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.solvers.simulate import SlackChainWarning, simulate

pytestmark = pytest.mark.filterwarnings("ignore", category=SlackChainWarning)

CAM = CamProgram.indexing("modified-sine")
T = np.arange(361) / (4 * 6.0 * 180.0)  # 90 deg (one index cycle) at 4 samples per degree


@pytest.mark.parametrize("friction, steady", [(0.0, True), (0.35, True), (0.35, False)])
def test_all_modes_reproduce_the_link_coordinates(friction, steady):
    # Same model, same solver, same grid: a change of coordinates only, so the answers agree to the
    # steady-state iteration's tolerance (friction) or to rounding (linear).
    model = ChainModel(24, 2.03, 9e7, friction_coefficient=friction)
    full = simulate(model, CAM, T, steady_state=steady)
    modal = simulate(model, CAM, T, steady_state=steady, n_modes=24)
    scale = np.abs(full.x_m - full.z_m[:, None]).max()
    assert np.abs(modal.x_m - full.x_m).max() <= 1e-6 * scale
    assert np.abs(modal.a_m_s2 - full.a_m_s2).max() <= 1e-5 * np.abs(full.a_m_s2).max()
    assert modal.min_tension_N == pytest.approx(full.min_tension_N, rel=1e-5)


def test_truncation_converges_in_relative_coordinates():
    model = ChainModel(60, 2.03, 9e7, friction_coefficient=0.35)
    full = simulate(model, CAM, T)
    deflection = np.abs(full.x_m - full.z_m[:, None]).max()
    errors = [np.abs(simulate(model, CAM, T, n_modes=r).x_m - full.x_m).max() / deflection for r in (2, 6, 20)]
    # The first mode carries most of the effective mass; each step here adds the next excited ones.
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1e-3


def test_a_long_chain_runs_without_dense_matrices():
    # 3000 links: the dense path would build 3000 x 3000 M, C, K and a 6000-state propagator; the
    # modal path needs only 60 sparse modes. Physics check: the first link stays near the cam.
    model = ChainModel(3000, 2.03, 9e7, friction_coefficient=0.35)
    r = simulate(model, CAM, T[::4], n_modes=60, links=[0, 1499])
    assert r.x_m.shape == (T[::4].size, 2)
    assert np.all(np.isfinite(r.x_m)) and np.abs(r.x_m[:, 0] - r.z_m).max() < 0.05
