"""Uncoupled modes under a first-order-hold force, stepped in blocks instead of step by step.

Each mode q'' + c q' + w^2 q = p(t), with p linear over a step h, has the exact recurrence

    s_k+1 = E s_k + g0 p_k + g1 p_k+1,    s = [q, q'],

(E, g0, g1 blocks of one 4x4 Van Loan exponential). Over a block of L steps from s_0,

    s_i = E^i s_0 + sum_{j<i} E^(i-1-j) u_j,    u_j = g0 p_j + g1 p_j+1:

the sum is one product with a block-Toeplitz matrix of the powers E^0..E^(L-1), for every block
and mode at once; only the block starts are chained in a Python loop (T / L iterations instead of
T). The terms are those of the step-by-step recurrence, regrouped, so the two agree to rounding
(tested), at any damping: rigid, critically damped and overdamped modes need no special case
because nothing is diagonalised. Used by the exact solver on classically damped systems and by
the modal solver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynamics.solvers.expm_stack import expm_stack

# Block length cap: the Toeplitz kernel holds 4 L^2 numbers per mode (32 -> 4096, 13 MB at 400 modes).
MAX_BLOCK = 32


@dataclass(frozen=True)
class ModeSteps:
    """Exact one-step matrices of r uncoupled modes for one step length: s_k+1 = E s_k + g0 p_k + g1 p_k+1."""

    e: np.ndarray  # (r, 2, 2)
    g0: np.ndarray  # (r, 2)
    g1: np.ndarray  # (r, 2)

    def lowest(self, r: int) -> ModeSteps:
        return ModeSteps(self.e[:r], self.g0[:r], self.g1[:r])


def mode_steps(omega2: np.ndarray, damping: np.ndarray, h: float) -> ModeSteps:
    """Step matrices of the modes q'' + damping q' + omega2 q = p: the 4x4 Van Loan exponential of
    every mode at once. Each mode's q is scaled by max(omega, 1/h) first, so that its matrix has
    entries of order omega h instead of omega^2 h (balanced: a few squarings, not a dozen)."""
    r = omega2.size
    scale = np.maximum(np.sqrt(np.maximum(omega2, 0.0)), 1.0 / h)
    aug = np.zeros((r, 4, 4))
    aug[:, 0, 1] = scale * h
    aug[:, 1, 0] = -omega2 / scale * h
    aug[:, 1, 1] = -damping * h
    aug[:, 1, 2] = h
    aug[:, 2, 3] = 1.0
    ex = expm_stack(aug)
    e = ex[:, :2, :2].copy()
    e[:, 0, 1] /= scale
    e[:, 1, 0] *= scale
    g0 = ex[:, :2, 2] - ex[:, :2, 3]
    g1 = ex[:, :2, 3].copy()
    g0[:, 0] /= scale
    g1[:, 0] /= scale
    return ModeSteps(e, g0, g1)


def block_length(n_steps: int) -> int:
    """About sqrt(T / 2): the kernel product costs T L per mode and its set-up L^2, the chaining loop
    T / L iterations, each dearer than a kernel row (Python), so the balance sits below sqrt(T)."""
    return int(min(MAX_BLOCK, max(1, np.ceil(np.sqrt(n_steps / 2)))))


@dataclass(frozen=True)
class BlockKernel:
    """[T | S] per mode: T (2L x 2L) the lower block-triangular Toeplitz matrix of E^0..E^(L-1),
    which maps a block's inputs to its states from rest, and S (2L x 2) = E^1..E^L stacked, which
    maps the block's start state to them. Its last two rows give the block's end state; their last
    two columns are E^L."""

    matrix: np.ndarray  # (r, 2L, 2L + 2)

    @property
    def length(self) -> int:
        return self.matrix.shape[1] // 2

    def lowest(self, r: int) -> BlockKernel:
        return BlockKernel(self.matrix[:r])


def block_kernel(e: np.ndarray, length: int) -> BlockKernel:
    r = e.shape[0]
    powers = np.empty((length + 1, r, 2, 2))
    powers[0] = np.eye(2)
    for p in range(1, length + 1):
        np.matmul(powers[p - 1], e, out=powers[p])
    mat = np.zeros((r, length, 2, length + 1, 2))  # (mode, row block i, a, column block j, b)
    for lag in range(length):  # Toeplitz: block (i, i - lag) is E^lag
        i = np.arange(lag, length)
        mat[:, i, :, i - lag, :] = powers[lag][None]
    mat[:, :, :, length, :] = powers[1:].transpose(1, 0, 2, 3)
    return BlockKernel(mat.reshape(r, 2 * length, 2 * length + 2))


def propagate_modes(steps: ModeSteps, kernel: BlockKernel, p: np.ndarray, s0: np.ndarray) -> np.ndarray:
    """States s_0..s_T (T + 1, 2, r) of the modes from s0 (2, r) under modal forces p (T + 1, r):
    [q; q'] rows, so that the physical [x | v] is one product with the mode shapes."""
    n_steps, r = p.shape[0] - 1, p.shape[1]
    length = kernel.length
    n_blocks = -(-n_steps // length)
    # columns are blocks; rows 2i + a hold step i's input component a, and the last two the block's
    # start state, so that one batched product per mode gives every state
    cols = np.zeros((r, 2 * length + 2, n_blocks))
    padded = np.zeros((n_blocks * length + 1, r))
    padded[: n_steps + 1] = p
    now = padded[:-1].reshape(n_blocks, length, r).transpose(2, 1, 0)
    nxt = padded[1:].reshape(n_blocks, length, r).transpose(2, 1, 0)
    for a in (0, 1):
        cols[:, a : 2 * length : 2] = steps.g0[:, a, None, None] * now + steps.g1[:, a, None, None] * nxt
    ends = kernel.matrix[:, -2:, : 2 * length] @ cols[:, : 2 * length]  # each block's end state from rest
    starts = cols[:, 2 * length :]
    starts[:, :, 0] = s0.T
    last = kernel.matrix[:, -2:, 2 * length :]  # E^L
    for b in range(1, n_blocks):
        prev = starts[:, :, b - 1]
        starts[:, :, b] = ends[:, :, b - 1] + last[:, :, 0] * prev[:, :1] + last[:, :, 1] * prev[:, 1:]
    states = kernel.matrix @ cols  # (r, 2L, n_blocks)
    out = np.empty((n_blocks * length + 1, 2, r))  # the padded steps too: one strided copy, no temporary
    out[0] = s0
    out[1:].reshape(n_blocks, length, 2, r)[...] = states.reshape(r, length, 2, n_blocks).transpose(3, 1, 2, 0)
    return out[: n_steps + 1]


def propagate_modes_stepwise(steps: list[ModeSteps], which: np.ndarray, p: np.ndarray, s0: np.ndarray) -> np.ndarray:
    """As `propagate_modes` on a grid with several step lengths: steps[which[k]] is step k's."""
    out = np.empty((p.shape[0], 2, p.shape[1]))
    out[0] = s0
    for k in range(p.shape[0] - 1):
        st = steps[which[k]]
        s = out[k]
        for a in (0, 1):
            out[k + 1, a] = st.e[:, a, 0] * s[0] + st.e[:, a, 1] * s[1] + st.g0[:, a] * p[k] + st.g1[:, a] * p[k + 1]
    return out
