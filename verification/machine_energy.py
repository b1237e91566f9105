"""Energy balance of the machine on its wheels across seat changes (issue #22): an oracle for the tests.

Over a window of index cycles, each integrated by the reference integrator's method (DOP853, tight
tolerance) and each followed by the transfer at the dwell (dynamics.solvers.machine_steady.transfer),

    work of the drive = damping's dissipation + seating losses + change of stored energy,

the stored energy being dynamics.models.machine.MachineOnWheels.stored_energy_J (absolute frame:
kinetic 1/2 sum M (q' + z')^2, the spans' P e + k e^2 / 2 with the feed's departure at the wheels'
angles, ground springs, the carriage's -2 P u).

Within a cycle the drive's work and the dissipation are two extra states of the same ODE:

    W' = -z' 1_m^T (dV/dq + C q') + dV/dt,     D' = q'^T C q',

1_m marking the DOFs that move with the cam (every chain DOF; not the carriage). This is the
prescribed motion's power: d/dt of the stored energy along the equations of motion
M q'' = -C q' - dV/dq - M 1_m z''. With a compliant drive every span stretch is unchanged when the
cam and all chain DOFs move together except the drive spring's and, through the wheel's angle, the
feed's departure, so 1_m^T dV/dq = k_g u_d + (dV/dt) / z' and W' = -z' (k_g u_d + 1_m^T C q'): the
torsional spring's force on the cam's side times the cam's motion, plus the dampers' reaction on
the cam (modal damping ties the chain to the cam's frame); `drive_spring_power_W` is that form.

At each transfer the losses are computed here from the state before it, independently of the
transfer's own bookkeeping:
- kinetic: the arriving link's plastic impact with its wheel, (1/2) s^2 / (1/m + c^2/M_g),
  s = y'_in - c u', c = dX/du at the seat (1/M_g = 0 on a sprocket held to the cam; the model's
  seated links move with u alone, the carriage's motion is not in their kinetic energy);
- elastic, the seat snap: the arriving link moves to its seat, so the span behind it (stretch e1)
  and its own span (e2) become one span of stretch e1 + e2 + delta, delta = d(u/R_m) - d(T + u/R_m)
  the chordal projection of one seated span (0 without the polygonal action, T the tooth angle);
  the leaving link stays where it is (at its seat, carriage included), so the span ahead of the
  wheel becomes the projection of a seated span (stretch -delta) and the strand's first span keeps
  its stretch.
Anything else the transfer changes (the places' relabelling) must conserve energy, and the
balance over the window fails if it does not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from dynamics.errors import SolverFailedError
from dynamics.models.machine import MachineOnWheels
from dynamics.solvers.machine_steady import transfer


@dataclass(frozen=True)
class CycleEnergy:
    """One index cycle: the drive's work and the dissipation over it (J), the stored energy at its
    start and end (J), and the state at its end (before the transfer)."""

    work_J: float
    dissipated_J: float
    stored_start_J: float
    stored_end_J: float
    q_end: np.ndarray
    v_end: np.ndarray
    n_rhs: int


@dataclass(frozen=True)
class SeatingEnergy:
    """One transfer: per wheel the impact's kinetic loss and the snap's elastic change (J), and the
    stored energy just before and after it (J)."""

    impact_J: tuple[float, ...]
    snap_J: tuple[float, ...]
    stored_before_J: float
    stored_after_J: float


@dataclass(frozen=True)
class WindowEnergy:
    cycles: tuple[CycleEnergy, ...]
    transfers: tuple[SeatingEnergy, ...]

    @property
    def work_J(self) -> float:
        return float(sum(c.work_J for c in self.cycles))

    @property
    def dissipated_J(self) -> float:
        return float(sum(c.dissipated_J for c in self.cycles))

    @property
    def seating_loss_J(self) -> float:
        """Impacts' losses minus the snaps' elastic gains, all transfers."""
        return float(sum(sum(s.impact_J) - sum(s.snap_J) for s in self.transfers))

    @property
    def stored_change_J(self) -> float:
        end = self.transfers[-1].stored_after_J if len(self.transfers) == len(self.cycles) else None
        return float((self.cycles[-1].stored_end_J if end is None else end) - self.cycles[0].stored_start_J)

    @property
    def imbalance_J(self) -> float:
        return self.work_J - self.dissipated_J - self.seating_loss_J - self.stored_change_J


def _cam_at(cam, t: float) -> tuple[float, float, float]:
    s, v, a, _ = cam.svaj(np.array([t]))
    return float(s[0]), float(v[0]), float(a[0])


def _moves(machine: MachineOnWheels) -> np.ndarray:
    return machine.topology.moves_with_cam()


def polygonal_stretches_m(machine: MachineOnWheels, q: np.ndarray, angles_rad) -> np.ndarray:
    """Every span's stretch, the wheel-end spans carrying the feed's departure at the wheels'
    nominal angles since the dwell."""
    e = machine.topology.incidence().toarray() @ q
    if machine.polygonal:
        for ends, angle in zip(machine.wheel_ends, angles_rad):
            u = 0.0 if ends.dof is None else q[ends.dof]
            d = float(ends.wheel.feed_departure_m(angle + u / ends.wheel.feed_radius_m))
            e[ends.behind_span] += d
            e[ends.ahead_span] -= d
    return e


def explicit_time_power_W(machine: MachineOnWheels, q: np.ndarray, angles_rad, zdot_m_s: float) -> float:
    """dV/dt at fixed q: the feed's departure moving with the cam, (T_behind - T_ahead) d'(a) z' / R_m."""
    if not machine.polygonal:
        return 0.0
    topo = machine.topology
    e = polygonal_stretches_m(machine, q, angles_rad)
    tension = topo.preload_N + topo.span_stiffness_N_per_m * e
    out = 0.0
    for ends, angle in zip(machine.wheel_ends, angles_rad):
        w = ends.wheel
        u = 0.0 if ends.dof is None else q[ends.dof]
        slope = float(w.feed_departure_slope(angle + u / w.feed_radius_m))
        out += (tension[ends.behind_span] - tension[ends.ahead_span]) * slope * zdot_m_s / w.feed_radius_m
    return float(out)


def drive_power_W(machine: MachineOnWheels, q, v, angles_rad, zdot_m_s: float) -> float:
    """The prescribed motion's power, -z' 1_m^T (dV/dq + C q') + dV/dt."""
    dv_dq = machine.stiffness_matrix() @ q - machine.polygon_force(angles_rad, q)
    force = dv_dq + machine.damping_matrix() @ v
    return float(-zdot_m_s * (_moves(machine) @ force) + explicit_time_power_W(machine, q, angles_rad, zdot_m_s))


def drive_spring_power_W(machine: MachineOnWheels, q, v, zdot_m_s: float) -> float:
    """With a compliant drive: -z' (k_g u_d + 1_m^T C q'), the torsional spring's force on the cam's
    side (k_theta / R_m^2 on the path) and the dampers' reaction on the cam, times its motion."""
    dof, k_g = machine.topology.ground[0]
    return float(-zdot_m_s * (k_g * q[dof] + _moves(machine) @ (machine.damping_matrix() @ v)))


def integrate_cycle_energy(
    machine: MachineOnWheels,
    cam,
    q0,
    v0,
    t0_s: float = 0.0,
    *,
    rtol: float = 1e-12,
    energy_scale_J: float = 1.0,
    t1_s: float | None = None,
    z_dwell_m: float | None = None,
) -> CycleEnergy:
    """One index cycle from t0_s (a dwell's end, where the pins that pull the strands seated) with the
    drive's work and the dissipation as extra states; the cam exact (its law, not samples). A piece
    of a cycle with `t1_s` (default: the cycle's end) and `z_dwell_m`, the lift the wheels' angles
    count from (default: the lift at t0_s)."""
    m = np.diag(machine.mass_matrix())
    k = machine.stiffness_matrix()
    c = machine.damping_matrix()
    r = machine.inertial_load()
    moves = _moves(machine)
    n = m.size
    radii = np.array([ends.wheel.feed_radius_m for ends in machine.wheel_ends])
    z_dwell = _cam_at(cam, t0_s)[0] if z_dwell_m is None else float(z_dwell_m)
    polygonal = machine.polygonal and radii.size > 0

    def rhs(time, y):
        q, v = y[:n], y[n : 2 * n]
        z, zd, zdd = _cam_at(cam, time)
        angles = (z - z_dwell) / radii
        g = machine.polygon_force(angles, q) if polygonal else 0.0
        cv = c @ v
        force = -cv - (k @ q) - r * zdd + g
        dv_dq = k @ q - g
        power = -zd * (moves @ (dv_dq + cv))
        if polygonal:
            power += explicit_time_power_W(machine, q, angles, zd)
        return np.concatenate([v, force / m, [power, v @ cv]])

    atol = np.concatenate([np.full(n, rtol * 1e-3), np.full(n, rtol * 1.0), np.full(2, rtol * energy_scale_J)])
    y0 = np.concatenate([q0, v0, [0.0, 0.0]])
    t1 = t0_s + cam.cycle_s if t1_s is None else float(t1_s)
    sol = solve_ivp(rhs, (t0_s, t1), y0, method="DOP853", rtol=rtol, atol=atol)
    if sol.status != 0:
        raise SolverFailedError(f"machine energy (DOP853): {sol.message}")
    q1, v1 = sol.y[:n, -1], sol.y[n : 2 * n, -1]
    zd0, zd1 = _cam_at(cam, t0_s)[1], _cam_at(cam, t1)[1]
    start = (_cam_at(cam, t0_s)[0] - z_dwell) / radii
    return CycleEnergy(
        float(sol.y[2 * n, -1]),
        float(sol.y[2 * n + 1, -1]),
        machine.stored_energy_J(np.asarray(q0, float), np.asarray(v0, float), zd0, start),
        machine.stored_energy_J(q1, v1, zd1, (_cam_at(cam, t1)[0] - z_dwell) / radii),
        q1,
        v1,
        int(sol.nfev),
    )


def seating_energy(
    machine: MachineOnWheels, q: np.ndarray, v: np.ndarray, angles_rad=None, zdot_m_s: float = 0.0
) -> tuple[list[float], list[float]]:
    """Per wheel, from the state at the seat change (before the transfer): the arriving link's
    impact loss and the seat snap's elastic change (module docstring). By default at the end of an
    index (the wheels' nominal angles one tooth, the cam at rest); inside it (tooth phase != 0) at
    the wheels' nominal angles since the dwell and the cam's speed there: the slip is then taken in
    the absolute frame, s = (y'_in + z') - c (u' + z'), and delta = d(a - T + u/R_m) - d(a + u/R_m)."""
    topo = machine.topology
    k, preload = topo.span_stiffness_N_per_m, topo.preload_N
    b = topo.incidence().toarray()
    link_mass = machine.chain.link_mass_kg
    masses = np.asarray(topo.masses_kg)
    tooth = np.array([ends.wheel.tooth_angle_rad for ends in machine.wheel_ends])
    angles = tooth if angles_rad is None else np.asarray(angles_rad, dtype=float)
    e = polygonal_stretches_m(machine, q, angles)
    impacts, snaps = [], []
    for ends, angle in zip(machine.wheel_ends, angles):
        w = ends.wheel
        u = 0.0 if ends.dof is None else q[ends.dof]
        ud = 0.0 if ends.dof is None else v[ends.dof]
        eps = u / w.feed_radius_m
        if machine.polygonal:
            c = 1.0 + float(w.feed_departure_slope(angle + eps)) / w.feed_radius_m
            delta = float(w.feed_departure_m(angle - w.tooth_angle_rad + eps) - w.feed_departure_m(angle + eps))
        else:
            c, delta = 1.0, 0.0
        behind = ends.behind_span
        arriving = int(np.flatnonzero(b[behind] == -1.0)[0])  # the behind end of the wheel's behind span
        before = int(np.flatnonzero(b[:, arriving] == 1.0)[0])  # the span whose ahead end it is
        e1, e2 = e[before], e[behind]
        # the model's seated links move with u alone (not the carriage)
        slip = (v[arriving] + zdot_m_s) - c * (ud + zdot_m_s)
        flexibility = 1.0 / link_mass + (0.0 if ends.dof is None else c**2 / masses[ends.dof])
        impacts.append(0.5 * slip**2 / flexibility)
        e_new = e1 + e2 + delta
        arriving_change = preload * delta + 0.5 * k * (e_new**2 - e1**2 - e2**2)
        leaving_change = preload * (-delta) + 0.5 * k * delta**2
        snaps.append(float(arriving_change + leaving_change))
    return impacts, snaps


def energy_window(machine: MachineOnWheels, cam, n_cycles: int, *, rtol: float = 1e-12) -> WindowEnergy:
    """n_cycles index cycles from rest, each followed by the transfer (the machine as it runs); at a
    tooth phase other than 0 the transfer is inside each cycle (`_energy_window_inside`)."""
    n = machine.topology.n_dof
    q, v = np.zeros(n), np.zeros(n)
    if machine.seat_change_lift_m is not None:
        return _energy_window_inside(machine, cam, n_cycles, q, v, rtol)
    tooth = np.array([ends.wheel.tooth_angle_rad for ends in machine.wheel_ends])
    cycles, transfers = [], []
    for i in range(n_cycles):
        cycle = integrate_cycle_energy(machine, cam, q, v, i * cam.cycle_s, rtol=rtol)
        cycles.append(cycle)
        impacts, snaps = seating_energy(machine, cycle.q_end, cycle.v_end)
        q, v, _, _ = transfer(machine, cycle.q_end, cycle.v_end)
        before = machine.stored_energy_J(cycle.q_end, cycle.v_end, 0.0, tooth)
        after = machine.stored_energy_J(q, v, 0.0, np.zeros(tooth.size))
        transfers.append(SeatingEnergy(tuple(impacts), tuple(snaps), before, after))
    return WindowEnergy(tuple(cycles), tuple(transfers))


def _energy_window_inside(machine: MachineOnWheels, cam, n_cycles: int, q, v, rtol: float) -> WindowEnergy:
    """Each cycle in two pieces around its seat change (the lift since the dwell at
    MachineOnWheels.seat_change_lift_m, located here on the cam's law by brentq): the first piece's
    angles from the dwell, the transfer with the cam's speed, the second piece's angles one tooth
    back (the dwell's lift one pitch on). The window's pieces are its `cycles`."""
    from scipy.optimize import brentq

    tooth = np.array([ends.wheel.tooth_angle_rad for ends in machine.wheel_ends])
    radii = np.array([ends.wheel.feed_radius_m for ends in machine.wheel_ends])
    pitch = machine.sprocket.pitch_m
    pieces, transfers = [], []
    for i in range(n_cycles):
        t0, t1 = i * cam.cycle_s, (i + 1) * cam.cycle_s
        z0 = _cam_at(cam, t0)[0]
        t_seat = brentq(lambda t, z0=z0: _cam_at(cam, t)[0] - z0 - machine.seat_change_lift_m, t0, t1, xtol=1e-15)
        first = integrate_cycle_energy(machine, cam, q, v, t0, rtol=rtol, t1_s=t_seat, z_dwell_m=z0)
        z_seat, zd_seat, _ = _cam_at(cam, t_seat)
        angles = (z_seat - z0) / radii
        impacts, snaps = seating_energy(machine, first.q_end, first.v_end, angles, zd_seat)
        q, v, _, _ = transfer(machine, first.q_end, first.v_end, angles_rad=angles, zdot_m_s=zd_seat)
        before = machine.stored_energy_J(first.q_end, first.v_end, zd_seat, angles)
        after = machine.stored_energy_J(q, v, zd_seat, angles - tooth)
        transfers.append(SeatingEnergy(tuple(impacts), tuple(snaps), before, after))
        second = integrate_cycle_energy(machine, cam, q, v, t_seat, rtol=rtol, t1_s=t1, z_dwell_m=z0 + pitch)
        pieces += [first, second]
        q, v = second.q_end, second.v_end
    return WindowEnergy(tuple(pieces), tuple(transfers))
