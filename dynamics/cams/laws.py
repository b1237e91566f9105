"""Rise laws on the normalised rise x in [0, 1]: displacement, velocity, acceleration and jerk, analytic.

A law maps x = theta/beta to S(x) with S(0) = 0, S(1) = 1; V = dS/dx, A = d2S/dx2, J = d3S/dx3.
A rise of lift h over duration T then has s = h S, v = h V / T, a = h A / T^2, j = h J / T^3.

Piecewise laws (modified sine, modified trapezoid) are built from acceleration pieces
a(u) = P sin(w u + phi) + Q on u = x - x0, integrated in closed form; each piece starts from the
previous piece's end velocity and displacement, so s, v and a are continuous by construction and the
only inexactness is floating-point rounding. The peak acceleration constants are the exact ones
(modified trapezoid Ca = 8 pi/(pi + 2), modified sine Ca = 4 pi^2/(4 + pi)); the handbook's 8-digit
constants leave displacement jumps of ~5e-7 h at the joints.

Laws are looked up by id in a registry (`get_law`, `law_ids`); `register_law` adds one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dynamics.errors import DynamicsError

SVAJ = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class MotionLaw:
    """A rise law: `svaj(x)` returns (S, V, A, J) on the normalised rise x in [0, 1]."""

    law_id: str
    name: str
    svaj: Callable[[np.ndarray], SVAJ]
    zero_end_acceleration: bool  # True if A(0) = A(1) = 0 (no acceleration jump into a dwell)


@dataclass(frozen=True)
class _HarmonicPiece:
    """Acceleration P sin(w u + phi) + Q on u = x - x0 in [0, x1 - x0], with start values s0, v0."""

    x0: float
    x1: float
    amplitude: float  # P
    omega: float  # w
    phase: float  # phi
    offset: float  # Q
    s0: float
    v0: float

    def end_values(self) -> tuple[float, float]:
        s, v, _, _ = self.evaluate(np.array([self.x1]))
        return float(s[0]), float(v[0])

    def evaluate(self, x: np.ndarray) -> SVAJ:
        u = x - self.x0
        p, w, phi, q = self.amplitude, self.omega, self.phase, self.offset
        if w == 0.0:
            a = np.full_like(u, q)
            v = self.v0 + q * u
            s = self.s0 + self.v0 * u + 0.5 * q * u**2
            return s, v, a, np.zeros_like(u)
        arg = w * u + phi
        a = p * np.sin(arg) + q
        j = p * w * np.cos(arg)
        v = self.v0 - (p / w) * (np.cos(arg) - math.cos(phi)) + q * u
        s = (
            self.s0
            + self.v0 * u
            - (p / w**2) * (np.sin(arg) - math.sin(phi))
            + (p / w) * math.cos(phi) * u
            + 0.5 * q * u**2
        )
        return s, v, a, j


def _chain_pieces(specs: list[tuple[float, float, float, float, float, float]]) -> tuple[_HarmonicPiece, ...]:
    """Pieces (x0, x1, P, w, phi, Q) joined end to start, starting from rest at s = 0."""
    pieces = []
    s0 = v0 = 0.0
    for x0, x1, p, w, phi, q in specs:
        piece = _HarmonicPiece(x0, x1, p, w, phi, q, s0, v0)
        pieces.append(piece)
        s0, v0 = piece.end_values()
    return tuple(pieces)


def _piecewise_svaj(pieces: tuple[_HarmonicPiece, ...]) -> Callable[[np.ndarray], SVAJ]:
    edges = np.array([p.x0 for p in pieces[1:]])

    def svaj(x: np.ndarray) -> SVAJ:
        x = np.asarray(x, dtype=float)
        which = np.searchsorted(edges, x, side="right")
        out = [np.empty_like(x) for _ in range(4)]
        for i, piece in enumerate(pieces):
            m = which == i
            if np.any(m):
                for o, val in zip(out, piece.evaluate(x[m])):
                    o[m] = val
        return tuple(out)

    return svaj


def _polynomial_svaj(coefficients: tuple[float, ...]) -> Callable[[np.ndarray], SVAJ]:
    """S(x) = sum c_k x^k with c given from k = 0 upward."""
    p = np.polynomial.Polynomial(coefficients)
    dp = [p, p.deriv(1), p.deriv(2), p.deriv(3)]

    def svaj(x: np.ndarray) -> SVAJ:
        x = np.asarray(x, dtype=float)
        return tuple(d(x) for d in dp)

    return svaj


PI = math.pi
MODIFIED_SINE_CA = 4.0 * PI**2 / (4.0 + PI)
MODIFIED_TRAPEZOID_CA = 8.0 * PI / (PI + 2.0)

_MODIFIED_SINE = _chain_pieces(
    [
        (0.0, 1 / 8, MODIFIED_SINE_CA, 4 * PI, 0.0, 0.0),
        (1 / 8, 7 / 8, MODIFIED_SINE_CA, 4 * PI / 3, PI / 2, 0.0),
        (7 / 8, 1.0, MODIFIED_SINE_CA, 4 * PI, 3 * PI / 2, 0.0),
    ]
)
_MODIFIED_TRAPEZOID = _chain_pieces(
    [
        (0.0, 1 / 8, MODIFIED_TRAPEZOID_CA, 4 * PI, 0.0, 0.0),
        (1 / 8, 3 / 8, 0.0, 0.0, 0.0, MODIFIED_TRAPEZOID_CA),
        (3 / 8, 5 / 8, MODIFIED_TRAPEZOID_CA, 4 * PI, PI / 2, 0.0),
        (5 / 8, 7 / 8, 0.0, 0.0, 0.0, -MODIFIED_TRAPEZOID_CA),
        (7 / 8, 1.0, MODIFIED_TRAPEZOID_CA, 4 * PI, 3 * PI / 2, 0.0),
    ]
)
_CYCLOIDAL = _chain_pieces([(0.0, 1.0, 2 * PI, 2 * PI, 0.0, 0.0)])
_SIMPLE_HARMONIC = _chain_pieces([(0.0, 1.0, PI**2 / 2, PI, PI / 2, 0.0)])

_REGISTRY: dict[str, MotionLaw] = {}


def register_law(law: MotionLaw) -> None:
    """Add a law to the registry (ids are unique)."""
    if law.law_id in _REGISTRY:
        raise DynamicsError(f"law_id: {law.law_id!r} is already registered; expected a new id")
    _REGISTRY[law.law_id] = law


def get_law(law_id: str) -> MotionLaw:
    try:
        return _REGISTRY[law_id]
    except KeyError:
        raise DynamicsError(f"law_id: unknown cam law {law_id!r}; expected one of {', '.join(law_ids())}") from None


def law_ids() -> tuple[str, ...]:
    return tuple(_REGISTRY)


for _law in (
    MotionLaw("modified-sine", "modified sine", _piecewise_svaj(_MODIFIED_SINE), True),
    MotionLaw("modified-trapezoid", "modified trapezoid", _piecewise_svaj(_MODIFIED_TRAPEZOID), True),
    MotionLaw("cycloidal", "cycloidal (full cycloid)", _piecewise_svaj(_CYCLOIDAL), True),
    MotionLaw("poly-345", "3-4-5 polynomial", _polynomial_svaj((0, 0, 0, 10, -15, 6)), True),
    MotionLaw("poly-4567", "4-5-6-7 polynomial", _polynomial_svaj((0, 0, 0, 0, 35, -84, 70, -20)), True),
    MotionLaw("simple-harmonic", "simple harmonic", _piecewise_svaj(_SIMPLE_HARMONIC), False),
):
    register_law(_law)
