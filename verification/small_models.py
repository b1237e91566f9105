"""1- and 2-DOF follower models for quick looks (the 2012 report's Appendices A and B, and Dynacam's
one-mass follower), solved by the same solvers as the chain. SI units.

One DOF (form-closed single-mass follower): the mass is tied to the cam by k1 and c1, and may also
have a dashpot c2 to ground:

    m x'' + (c1 + c2) x' + k1 x = k1 s + c1 s'.

Two DOF (Appendix B): mass 1 tied to the cam by (k1, c1), mass 2 to mass 1 by (k2, c2):

    M = diag(m1, m2),  C = [[c1 + c2, -c2], [-c2, c2]],  K = [[k1 + k2, -k2], [-k2, k2]],
    f = [k1 s + c1 s', 0].

The report's scripts set c = 2 zeta sqrt(k1 m1) for every dashpot (zeta = 0.05); the constructors
take a damping ratio and apply it the same way unless dashpots are given explicitly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.models.system import Response, SampledForce, SecondOrderSystem
from dynamics.solvers import solve


@dataclass(frozen=True)
class FollowerModel:
    """A small follower model: the system and the cam coupling of mass 1 (k1 s + c1 s')."""

    system: SecondOrderSystem
    drive_stiffness_N_per_m: float
    drive_damping_N_s_per_m: float

    def force(self, cam, t_s: np.ndarray) -> SampledForce:
        s, v, _, _ = cam.svaj(np.asarray(t_s, dtype=float))
        f = np.zeros((len(t_s), self.system.n_dof))
        f[:, 0] = self.drive_stiffness_N_per_m * np.asarray(s) + self.drive_damping_N_s_per_m * np.asarray(v)
        return SampledForce(np.asarray(t_s, dtype=float), f)

    def simulate(self, cam, t_s: np.ndarray, *, method: str = "exact", x0=None, v0=None, **options) -> Response:
        """Absolute motion of the masses at t_s; from rest at zero unless x0, v0 are given."""
        return solve(self.system, self.force(cam, t_s), t_s, method=method, x0=x0, v0=v0, **options)


def one_dof_follower(
    mass_kg: float,
    stiffness_N_per_m: float,
    *,
    damping_ratio: float = 0.05,
    drive_damping_N_s_per_m: float | None = None,
    ground_damping_N_s_per_m: float = 0.0,
) -> FollowerModel:
    """m x'' + (c1 + c2) x' + k1 x = k1 s + c1 s', c1 = 2 zeta sqrt(k1 m) unless given."""
    _positive("mass_kg", mass_kg)
    _positive("stiffness_N_per_m", stiffness_N_per_m)
    c1 = _dashpot(drive_damping_N_s_per_m, damping_ratio, stiffness_N_per_m, mass_kg)
    if not (np.isfinite(ground_damping_N_s_per_m) and ground_damping_N_s_per_m >= 0):
        raise DynamicsError(f"ground_damping_N_s_per_m: expected >= 0, got {ground_damping_N_s_per_m!r}")
    system = SecondOrderSystem(
        np.array([[mass_kg]]), np.array([[c1 + ground_damping_N_s_per_m]]), np.array([[stiffness_N_per_m]])
    )
    return FollowerModel(system, float(stiffness_N_per_m), c1)


def two_dof_follower(
    masses_kg: tuple[float, float],
    stiffnesses_N_per_m: tuple[float, float],
    *,
    damping_ratio: float = 0.05,
    dampings_N_s_per_m: tuple[float, float] | None = None,
) -> FollowerModel:
    """Appendix B: mass 1 to the cam by (k1, c1), mass 2 to mass 1 by (k2, c2); by default
    c1 = c2 = 2 zeta sqrt(k1 m1), as the script does."""
    m1, m2 = masses_kg
    k1, k2 = stiffnesses_N_per_m
    for name, val in (("masses_kg", m1), ("masses_kg", m2), ("stiffnesses_N_per_m", k1), ("stiffnesses_N_per_m", k2)):
        _positive(name, val)
    if dampings_N_s_per_m is None:
        c1 = c2 = _dashpot(None, damping_ratio, k1, m1)
    else:
        c1, c2 = (float(c) for c in dampings_N_s_per_m)
        if not all(np.isfinite(c) and c >= 0 for c in (c1, c2)):
            raise DynamicsError(f"dampings_N_s_per_m: expected two values >= 0, got {dampings_N_s_per_m!r}")
    system = SecondOrderSystem(
        np.diag([m1, m2]).astype(float),
        np.array([[c1 + c2, -c2], [-c2, c2]]),
        np.array([[k1 + k2, -k2], [-k2, k2]], dtype=float),
    )
    return FollowerModel(system, float(k1), c1)


def _dashpot(given, zeta, k, m) -> float:
    if given is not None:
        if not (np.isfinite(given) and given >= 0):
            raise DynamicsError(f"drive_damping_N_s_per_m: expected >= 0, got {given!r}")
        return float(given)
    if not (np.isfinite(zeta) and 0 <= zeta < 1):
        raise DynamicsError(f"damping_ratio: expected 0 <= zeta < 1, got {zeta!r}")
    return float(2 * zeta * np.sqrt(k * m))


def _positive(name: str, value) -> None:
    if not (np.isfinite(value) and value > 0):
        raise DynamicsError(f"{name}: expected a positive finite number, got {value!r}")
