"""ARPACK's start vector, fixed. `scipy.sparse.linalg.eigsh` without `v0` draws its start from
ARPACK's own random state, which moves from call to call and differs between processes; Lanczos
stops at its tolerance, not at the exact eigenvalue, so the result moved with it (the O(N) machine
damping's node weights by about 1e-10 between two processes). Every eigsh call in dynamics passes
`lanczos_start`, so the same model gives bit-identical results in every process."""

from __future__ import annotations

import numpy as np

# Any fixed seed: the vector only has to be the same everywhere and, being random, not orthogonal to
# the mode sought (ones would be orthogonal to a uniform ring's alternating top mode)
START_SEED = 0


def lanczos_start(n: int) -> np.ndarray:
    """The start vector of an eigsh call on an n x n operator: uniform in [-1, 1), as ARPACK draws
    its own, from a fixed seed."""
    return np.random.default_rng(START_SEED).uniform(-1.0, 1.0, n)
