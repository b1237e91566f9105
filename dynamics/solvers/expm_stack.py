"""Matrix exponential by scaling and squaring with the [13/13] Pade approximant (Higham 2005),
vectorised over a stack of matrices.

Why not scipy.linalg.expm: it loops over a stack in Python, one call per matrix (85 calls for the
mode exponentials of an 85-link chain, once per material and step). The 1-norm choice of the
squaring count (Higham 2005) can over-scale an unbalanced matrix; the mode matrices are balanced
first (dynamics.solvers.mode_scan.mode_steps). For one large matrix scipy's is used. Tested
against scipy.linalg.expm.
"""

from __future__ import annotations

import numpy as np

# Higham (2005), "The scaling and squaring method for the matrix exponential revisited": the
# [13/13] Pade approximant's coefficients and the 1-norm up to which it is exact in double precision.
_PADE13 = np.array(
    [
        64764752532480000.0,
        32382376266240000.0,
        7771770303897600.0,
        1187353796428800.0,
        129060195264000.0,
        10559470521600.0,
        670442572800.0,
        33522128640.0,
        1323241920.0,
        40840800.0,
        960960.0,
        16380.0,
        182.0,
        1.0,
    ]
)
_THETA13 = 5.371920351148152


def expm_stack(a: np.ndarray) -> np.ndarray:
    """exp of each matrix in a stack (..., n, n) by scaling and squaring with the [13/13] Pade
    approximant. One squaring count serves the whole stack, set by its largest 1-norm; smaller
    matrices are scaled further than they need, which costs a few ulps per extra squaring."""
    norm = float(np.abs(a).sum(axis=-2).max(initial=0.0))  # 1-norm: the largest column sum
    squarings = max(0, int(np.ceil(np.log2(norm / _THETA13)))) if norm > 0.0 else 0
    x = a / 2.0**squarings
    eye = np.eye(a.shape[-1])
    x2 = x @ x
    x4 = x2 @ x2
    x6 = x4 @ x2
    b = _PADE13
    u = x @ (x6 @ (b[13] * x6 + b[11] * x4 + b[9] * x2) + b[7] * x6 + b[5] * x4 + b[3] * x2 + b[1] * eye)
    v = x6 @ (b[12] * x6 + b[10] * x4 + b[8] * x2) + b[6] * x6 + b[4] * x4 + b[2] * x2 + b[0] * eye
    out = np.linalg.solve(v - u, v + u)
    for _ in range(squarings):
        out = out @ out
    return out
