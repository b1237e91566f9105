import numpy as np

from dynamics.models.system import SampledForce


def test_sampled_force_is_linear_between_samples():
    f = SampledForce(np.array([0.0, 1.0, 3.0]), np.array([[0.0], [2.0], [6.0]]))
    assert f.at(0.5)[0] == 1.0
    assert f.at(2.0)[0] == 4.0
    assert f.at(3.0)[0] == 6.0
