"""The friction law's tanh, one function for both explicit kernels (the ring, clearance_verlet, and
the machine, machine_verlet): tanh x = (1 - q) / (1 + q), q = exp(-2|x|), with the sign of x, the
exponential written out in arithmetic, no call and no branch, so that a loop of it vectorises.

Plain Python here: clearance_verlet compiles it among its step's inlined helpers (under its FASTMATH)
and machine_verlet inlines that compiled one, as it does the ring's other helpers.
"""

from __future__ import annotations

import math

import numpy as np

# Above this argument tanh rounds to 1 in double precision (1 - tanh x ~ 2 exp(-2x) falls below half an
# ulp of 1, 2^-54, from x = 55 ln 2 / 2 = 19.06), so the friction law takes +-F_c there without computing
# it: the links sliding faster than 19 velocity scales (95 mm/s by default) through the indexing motion.
TANH_IS_ONE = 19.1
# ln 2 in two parts (the first with its low bits zero, so that k ln2_hi is exact for the k of
# `tanh_branch_free`) and 1 / ln 2
LN2_HI, LN2_LO, INV_LN2 = 6.93147180369123816490e-01, 1.90821492927058770002e-10, 1.44269504088896338700e00
# 1 / n! for n = 13 .. 0: exp r on |r| <= ln 2 / 2 to its rounding (the next term, 0.35^14 / 14!, is 4e-18)
EXP_TAYLOR = tuple(1.0 / math.factorial(m) for m in range(13, -1, -1))
# 1 - 2^-(2^b), b = 0 .. 5: the factors of 2^-k, one per bit of k < 64 (`tanh_branch_free`), all exact
HALVINGS = tuple(1.0 - 2.0 ** -(2**b) for b in range(6))


def tanh_branch_free(x):
    """tanh x as (1 - q) / (1 + q), q = exp(-2|x|), the sign of x, with exp(-y) = 2^-k exp(r),
    k = round(y / ln 2), r = k ln 2 - y, exp r by its Taylor polynomial, 2^-k as the product of one
    exact factor per bit of k. y is capped at 2 TANH_IS_ONE, where q is below half an ulp of 1 and the
    result is exactly +-1 (as there on). Within 2.3e-16 of the library's tanh (tested)."""
    y = min(2.0 * abs(x), 2.0 * TANH_IS_ONE)
    k = np.floor(y * INV_LN2 + 0.5)
    r = (k * LN2_HI - y) + k * LN2_LO
    e = 0.0
    for c in EXP_TAYLOR:
        e = e * r + c
    scale = 1.0
    for c in HALVINGS:
        half = np.floor(0.5 * k)
        scale *= 1.0 - c * (k - 2.0 * half)  # 1 - c times k's lowest bit
        k = half
    q = e * scale
    return math.copysign((1.0 - q) / (1.0 + q), x)
