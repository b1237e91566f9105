"""The reference integrator for the machine on its wheels (dynamics.models.machine): scipy's solve_ivp with
error control over one index cycle, where the polygonal feed makes the model nonlinear and
time-varying. Speed is not its purpose: it is the yardstick a faster method will be checked against.

Equations (relative to the cam, M diagonal):

    M q'' = -C q' - K q - r z''(t) + g(t, q),

r the inertial load (dynamics.models.machine.MachineOnWheels.inertial_load) and g the polygonal feed's
departure from the linear model, evaluated at the wheels' angles since the dwell at `t_dwell_s`
(the cycle's start, where the pin that pulls each strand during the index seated).

Tolerance: DOP853 at rtol 1e-11 with an absolute tolerance of 1e-11 of the state's scale (1 mm, 1 m/s
by default). Its global error, checked against the exact first-order-hold solver on the linear
model, is 3e-9 of the displacement's peak and 7e-9 of the velocity's over one index cycle of a
12-link machine (test_machine_on_wheels asserts 1e-8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from dynamics.errors import SolverFailedError
from dynamics.models.machine import MachineOnWheels


@dataclass(frozen=True)
class MachineResponse:
    t_s: np.ndarray  # (m,)
    q_m: np.ndarray  # (m, n_dof) relative displacements of the DOFs
    v_m_s: np.ndarray  # (m, n_dof)
    n_rhs: int


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
) -> MachineResponse:
    """Integrate from t_eval_s[0] with state (q0, v0) to t_eval_s[-1]; `zddot(t)`, `z(t)`: the cam's
    acceleration and lift (callables of a float time)."""
    t = np.asarray(t_eval_s, dtype=float)
    t_dwell = float(t[0] if t_dwell_s is None else t_dwell_s)
    m = np.diag(machine.mass_matrix())
    k = machine.stiffness_matrix()
    c = machine.damping_matrix()
    r = machine.inertial_load()
    n = m.size
    radii = np.array([ends.wheel.feed_radius_m for ends in machine.wheel_ends])
    z_dwell = float(z(t_dwell))
    polygonal = machine.polygonal and radii.size > 0

    def rhs(time, y):
        q, v = y[:n], y[n:]
        force = -(c @ v) - (k @ q) - r * float(zddot(time))
        if polygonal:
            force = force + machine.polygon_force((float(z(time)) - z_dwell) / radii, q)
        return np.concatenate([v, force / m])

    atol = np.concatenate([np.full(n, rtol * scale_m), np.full(n, rtol * scale_m_s)])
    sol = solve_ivp(rhs, (t[0], t[-1]), np.concatenate([q0, v0]), method="DOP853", t_eval=t, rtol=rtol, atol=atol)
    if sol.status != 0:
        raise SolverFailedError(f"machine on wheels (DOP853): {sol.message}")
    return MachineResponse(t, sol.y[:n].T, sol.y[n:].T, int(sol.nfev))
