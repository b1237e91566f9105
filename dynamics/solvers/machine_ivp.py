"""The reference integrator for the machine on its wheels (dynamics.models.machine): scipy's solve_ivp with
error control over one index cycle, where the polygonal feed makes the model nonlinear and
time-varying. Speed is not its purpose: it is the yardstick a faster method will be checked against.

Equations (relative to the cam, M diagonal):

    M q'' = -C q' - K q - r z''(t) + g(t, q),

r the inertial load (dynamics.models.machine.MachineOnWheels.inertial_load) and g the polygonal feed's
departure from the linear model, evaluated at the wheels' angles since the dwell at `t_dwell_s`
(the cycle's start, where the pin that pulls each strand during the index seated).

With a tooth phase other than 0 (MachineOnWheels.seat_change_lift_m) the seats change inside the
cycle, when the cam's lift since the dwell reaches that lift: the instant is located on the cam's lift
(brentq to 1e-15 s), the integration stops there, applies the transfer
(dynamics.solvers.machine_steady.transfer, with the cam's speed) and goes on with the dwell's lift
counted one pitch on (the angles one tooth back: the next pin pulls the strand, the next index's
frame). Outputs at or after that instant are in the new labels.

Tolerance: DOP853 at rtol 1e-11 with an absolute tolerance of 1e-11 of the state's scale (1 mm, 1 m/s
by default). Its global error, checked against the exact first-order-hold solver on the linear
model, is 3e-9 of the displacement's peak and 7e-9 of the velocity's over one index cycle of a
12-link machine (test_machine_on_wheels asserts 1e-8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynamics.errors import SolverFailedError
from dynamics.models.machine import MachineOnWheels


@dataclass(frozen=True)
class MachineResponse:
    t_s: np.ndarray  # (m,)
    q_m: np.ndarray  # (m, n_dof) relative displacements of the DOFs
    v_m_s: np.ndarray  # (m, n_dof)
    n_rhs: int
    seat_change_s: float | None = None  # the instant of a seat change inside the cycle (None: none)
    seating: tuple | None = None  # its (per-wheel speeds, per-wheel impact energies, stored-energy change)


def seat_change_time_s(z, t0_s: float, t1_s: float, z_dwell_m: float, lift_m: float | None) -> float | None:
    """The instant in (t0_s, t1_s] at which the cam's lift since the dwell, z(t) - z_dwell_m, reaches
    `lift_m` (a non-decreasing lift, an indexing cam's); None when it is not reached in there."""
    from scipy.optimize import brentq

    if lift_m is None:
        return None
    f = lambda time: float(z(time)) - z_dwell_m - lift_m  # noqa: E731
    if not (f(t0_s) < 0.0 <= f(t1_s)):
        return None
    return float(brentq(f, t0_s, t1_s, xtol=1e-15, rtol=4 * np.finfo(float).eps))


def cam_lift_m(cam, time_s: float) -> float:
    """The cam program's lift at one instant (its law, not samples)."""
    return float(cam.svaj(np.array([time_s]))[0][0])


def cam_seat_change_s(cam, t1_s: float, lift_m: float) -> float:
    """`seat_change_time_s` of an index that starts at t = 0 on `cam`'s own law (the lift since its
    lift at 0), in (0, t1_s]; a DynamicsError where the lift does not reach `lift_m` in there."""
    from dynamics.errors import DynamicsError

    t_seat = seat_change_time_s(lambda time: cam_lift_m(cam, time), 0.0, t1_s, cam_lift_m(cam, 0.0), lift_m)
    if t_seat is None:
        raise DynamicsError("seat change: the cam's lift does not reach it within the index cycle")
    return t_seat


def sampled_seat_change_s(t_s, lift_samples_m, lift_m: float | None) -> float | None:
    """`seat_change_time_s` on a lift sampled at `t_s` (linear between the samples), since its first
    sample, over the samples' span."""
    t, s = np.asarray(t_s, dtype=float), np.asarray(lift_samples_m, dtype=float)
    return seat_change_time_s(lambda x: np.interp(x, t, s), t[0], t[-1], s[0], lift_m)


def integrate_cycle(
    machine: MachineOnWheels,
    zddot,
    z,
    t_eval_s,
    q0,
    v0,
    *,
    t_dwell_s: float | None = None,
    rtol: float = 1e-11,
    scale_m: float = 1e-3,
    scale_m_s: float = 1.0,
    zdot=None,
) -> MachineResponse:
    """Integrate from t_eval_s[0] with state (q0, v0) to t_eval_s[-1]; `zddot(t)`, `z(t)`: the cam's
    acceleration and lift (callables of a float time); `zdot(t)` its speed, needed where the seats
    change inside the cycle (tooth phase != 0)."""
    t = np.asarray(t_eval_s, dtype=float)
    t_dwell = float(t[0] if t_dwell_s is None else t_dwell_s)
    z_dwell = float(z(t_dwell))
    t_seat = seat_change_time_s(z, float(t[0]), float(t[-1]), z_dwell, machine.seat_change_lift_m)
    if t_seat is None:
        return _integrate(machine, zddot, z, t, q0, v0, z_dwell, rtol, scale_m, scale_m_s)
    if zdot is None:
        raise SolverFailedError("integrate_cycle: the seats change inside the cycle; expected the cam's speed zdot")
    first = _integrate(machine, zddot, z, np.append(t[t < t_seat], t_seat), q0, v0, z_dwell, rtol, scale_m, scale_m_s)
    q1, v1, seating = seat_change_inside(
        machine, first.q_m[-1], first.v_m_s[-1], float(z(t_seat)) - z_dwell, float(zdot(t_seat))
    )
    # after the seat change the dwell's lift counts one pitch on: the next pin's angle is one tooth
    # back, the next index's frame
    z_next = z_dwell + machine.sprocket.pitch_m
    second = _integrate(
        machine, zddot, z, np.insert(t[t > t_seat], 0, t_seat), q1, v1, z_next, rtol, scale_m, scale_m_s
    )
    after = 0 if np.any(t == t_seat) else 1  # a sample at the instant itself is the state after it
    return MachineResponse(
        t,
        np.concatenate([first.q_m[:-1], second.q_m[after:]]),
        np.concatenate([first.v_m_s[:-1], second.v_m_s[after:]]),
        first.n_rhs + second.n_rhs,
        t_seat,
        seating,
    )


def seat_change_inside(machine: MachineOnWheels, q, v, z_rel_m: float, zdot_m_s: float):
    """(q, v) after the transfer inside the index at the cam's lift since the dwell `z_rel_m` and speed
    `zdot_m_s`, and its (per-wheel seating speeds, per-wheel impact energies, change of stored energy:
    after, with the angles one tooth back, minus before)."""
    from dynamics.solvers.machine_steady import transfer

    radii = np.array([ends.wheel.feed_radius_m for ends in machine.wheel_ends])
    tooth = np.array([ends.wheel.tooth_angle_rad for ends in machine.wheel_ends])
    angles = z_rel_m / radii
    q1, v1, speeds, impacts = transfer(machine, q, v, angles_rad=angles, zdot_m_s=zdot_m_s)
    change = machine.stored_energy_J(q1, v1, zdot_m_s, angles - tooth) - machine.stored_energy_J(q, v, zdot_m_s, angles)
    return q1, v1, (speeds, impacts, float(change))


def _integrate(machine, zddot, z, t, q0, v0, z_dwell, rtol, scale_m, scale_m_s) -> MachineResponse:
    """From t[0] to t[-1], the wheels' angles counted from the lift `z_dwell`."""
    m = np.diag(machine.mass_matrix())
    k = machine.stiffness_matrix()
    c = machine.damping_matrix()
    r = machine.inertial_load()
    n = m.size
    radii = np.array([ends.wheel.feed_radius_m for ends in machine.wheel_ends])
    polygonal = machine.polygonal and radii.size > 0

    def rhs(time, y):
        q, v = y[:n], y[n:]
        force = -(c @ v) - (k @ q) - r * float(zddot(time))
        if polygonal:
            force = force + machine.polygon_force((float(z(time)) - z_dwell) / radii, q)
        return np.concatenate([v, force / m])

    from scipy.integrate import solve_ivp  # the reference only: see dynamics.solvers.ivp

    atol = np.concatenate([np.full(n, rtol * scale_m), np.full(n, rtol * scale_m_s)])
    sol = solve_ivp(rhs, (t[0], t[-1]), np.concatenate([q0, v0]), method="DOP853", t_eval=t, rtol=rtol, atol=atol)
    if sol.status != 0:
        raise SolverFailedError(f"machine on wheels (DOP853): {sol.message}")
    return MachineResponse(t, sol.y[:n].T, sol.y[n:].T, int(sol.nfev))
