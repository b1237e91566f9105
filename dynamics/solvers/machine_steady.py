"""Periodic steady state of the machine on its wheels, with relabelling (issue #22).

Each index moves the chain one pitch: one link seats on each wheel from the strand behind it and one
leaves onto the strand ahead. The DOFs of dynamics.models.machine are places on the machine (a wheel's
seated group, the k-th free link of a strand, the carriage), so with identical links the machine
after an index is the machine before it with every link moved one place ahead. The steady state of
continuous indexing is therefore the state x0 at the start of an index with

    x0 = T(P(x0)),

P the motion over one index cycle (from the start of one index to the start of the next, the cam at
rest at both ends) and T the transfer at the dwell:
- a free link takes the state of the link one place behind it;
- the link that leaves a wheel onto the strand ahead starts at its seat: y = u + d(a_end) - g u_c (d
  the feed's departure, dynamics.models.wheels, 0 without the polygonal action; g u_c the carriage's
  lengthening of the span ahead of an idler wheel on it), y' = u' dX/du (the model's seated links
  move with u alone, so this keeps the kinetic energy the model gives them);
- the link that arrives from the strand behind seats with a plastic impact along the strand
  (the tooth takes it at the wheel's pitch-circle speed): the group's generalised momentum
  M_g u' + m c y'_in is kept, u'+ = (M_g u' + m c y'_in) / (M_g + m c^2), c = dX/du at the seat
  (1 without the polygonal action); on a sprocket held to the cam u' stays 0. Rigid seating also
  puts it at its seat, moving it by its span's dynamic stretch e2 (tens of micrometres); that
  changes the elastic energy of the span behind it by k e1 e2 and releases the arriving span's
  1/2 k e2^2. The impact's kinetic loss is reported per wheel, the transfer's whole change of
  stored energy (both effects, all wheels) per cycle;
- the carriage keeps its state.

For the linear (polygon-free) model P(x) = Phi x + r and T(x) = A x are linear, so x0 solves
(I - A Phi) x0 = A r exactly (Phi the exact first-order-hold one-cycle propagator). With the
polygonal feed P is dynamics.solvers.machine_ivp's integrator and the transfer is nonlinear only through
d(a_end); x0 comes from Newton shooting with the linear model's A Phi as the Jacobian.

Tooth phase phi != 0 (dynamics.models.machine): the transfer happens inside the cycle, when the cam has
lifted (1 - phi) p, with the cam's speed z' there; the steady state is x0 = P_2(T(P_1(x0))) (P_1, P_2
the motion before and after it), the same relabelling by one link per index: for the polygon-free
model one linear solve with Phi_2 A Phi_1 (T is still linear: with c = 1 the cam's speed cancels),
with the polygonal feed the same Newton shooting with that as the Jacobian.

`labelled_periodic_state` is the other steady state: the same links stay seated every cycle
(x0 = P(x0)), the frame the issue's first figures were computed in; it is kept to compare with them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from dynamics.errors import DynamicsError, SolverFailedError
from dynamics.models.machine import MachineOnWheels
from dynamics.models.system import SampledForce
from dynamics.solvers import solve
from dynamics.solvers.exact import propagate
from dynamics.solvers.machine_ivp import MachineResponse, integrate_cycle, sampled_seat_change_s, seat_change_inside
from dynamics.solvers.steady_state import monodromy


@dataclass(frozen=True)
class CycleResponse:
    """One index cycle in steady state: DOF displacement, velocity, acceleration (relative to the cam)
    at the samples, the cam's samples, and the seating diagnostics of the cycle's transfer (at its
    end, or inside it where the tooth phase is not 0; the samples from that instant on are in the new
    labels)."""

    t_s: np.ndarray
    q_m: np.ndarray
    v_m_s: np.ndarray
    a_m_s2: np.ndarray  # relative acceleration y''
    zddot_m_s2: np.ndarray
    # per wheel: |(y'_in + z') - c (u' + z')| of the link that seats (z' = 0 at the dwell)
    seating_speed_m_s: tuple[float, ...]
    seating_impact_J: tuple[float, ...]  # per wheel: kinetic energy lost in the plastic seating impact
    transfer_energy_change_J: float  # stored energy after the transfer minus before (all wheels)


@dataclass(frozen=True)
class _Places:
    """Index maps of the transfer: per DOF, the DOF whose state it takes (-1: none), and per wheel
    (group DOF or None, DOF of the link arriving from behind, DOF of the link leaving ahead)."""

    source: np.ndarray
    wheels: tuple[tuple[int | None, int, int], ...]


def _places(machine: MachineOnWheels) -> _Places:
    if machine.drive != "wheels":
        raise DynamicsError("drive: the relabelled steady state needs drive='wheels' (the link drive has no seats)")
    if not machine.rigid_seating:
        raise DynamicsError(
            "tooth_stiffness_N_per_m: the seat change (transfer) is built for rigid seating only; "
            "with a tooth stiffness use the labelled frame (relabel=False)"
        )
    topo = machine.topology
    n = topo.n_dof
    n_places = len(machine.groups)
    held = machine.drive_held
    dof_of_place = [None if (p == 0 and held) else p - (1 if held else 0) for p in range(n_places)]
    source = np.full(n, -1)
    group_places = {0} | ({machine.idler_place} if machine.idler_place is not None else set())
    for p in range(n_places):
        d = dof_of_place[p]
        if d is None or p in group_places:
            continue
        behind = (p - 1) % n_places
        if behind not in group_places:
            source[d] = dof_of_place[behind]
    if topo.n_dof > len([d for d in dof_of_place if d is not None]):
        source[n - 1] = n - 1  # the carriage keeps its state
    wheels = []
    for place in sorted(group_places):
        wheels.append((dof_of_place[place], dof_of_place[(place - 1) % n_places], dof_of_place[(place + 1) % n_places]))
    return _Places(source, tuple(wheels))


def transfer(
    machine: MachineOnWheels,
    q: np.ndarray,
    v: np.ndarray,
    *,
    linear: bool = False,
    angles_rad=None,
    zdot_m_s: float = 0.0,
):
    """(q, v) after the seat changes, and per wheel the seating speed and the kinetic energy the
    plastic impact takes. `linear`: the polygon-free map even when the machine has the polygonal
    action (the Newton Jacobian). By default the seats change at the dwell (the wheels' nominal
    angle one tooth since the last, the cam at rest); inside the index (tooth phase != 0) pass the
    wheels' nominal angles since the dwell and the cam's speed there: momentum and the seating speed
    are then taken in the absolute frame (a wheel's path speed u' + z', the arriving link's y' + z',
    the leaving link leaves at c (u' + z')), which at z' = 0 is the dwell's map."""
    places = _places(machine)
    topo = machine.topology
    masses = np.asarray(topo.masses_kg)
    link_mass = machine.chain.link_mass_kg
    q_new = np.where(places.source >= 0, q[np.maximum(places.source, 0)], 0.0)
    v_new = np.where(places.source >= 0, v[np.maximum(places.source, 0)], 0.0)
    speeds, impacts = [], []
    zd = float(zdot_m_s)
    for i, (ends, (group, arriving, leaving)) in enumerate(zip(machine.wheel_ends, places.wheels)):
        wheel = ends.wheel
        polygon = machine.polygonal and not linear
        u = 0.0 if group is None else q[group]
        ud = 0.0 if group is None else v[group]
        angle = wheel.tooth_angle_rad if angles_rad is None else float(angles_rad[i])
        a_end = angle + u / wheel.feed_radius_m
        d = float(wheel.feed_departure_m(a_end)) if polygon else 0.0
        c = (1.0 + float(wheel.feed_departure_slope(a_end)) / wheel.feed_radius_m) if polygon else 1.0
        arriving_abs = v[arriving] + zd  # the arriving link's and the wheel's speeds in the absolute frame
        wheel_abs = ud + zd
        if group is None:
            ud_new = 0.0
            impact = 0.5 * link_mass * (arriving_abs - c * wheel_abs) ** 2
        else:
            mg = masses[group]
            ud_new = (mg * wheel_abs + link_mass * c * arriving_abs) / (mg + link_mass * c**2) - zd
            impact = 0.5 * mg * link_mass * (arriving_abs - c * wheel_abs) ** 2 / (mg + link_mass * c**2)
            q_new[group], v_new[group] = u, ud_new
        # the leaving link stays at its seat: the span ahead keeps a seated span's stretch; a carriage
        # under an idler wheel lengthens that span by gain * u_c, so the seat is that much behind
        ahead = topo.spans[ends.ahead_span]
        q_new[leaving] = u + d - (ahead.carriage_gain * q[ahead.carriage] if ahead.carriage is not None else 0.0)
        v_new[leaving] = c * (ud_new + zd) - zd
        speeds.append(float(abs(arriving_abs - c * wheel_abs)))
        impacts.append(float(impact))
    return q_new, v_new, tuple(speeds), tuple(impacts)


def transfer_matrix(machine: MachineOnWheels) -> np.ndarray:
    """A with [q; v] -> A [q; v], the polygon-free transfer (linear)."""
    n = machine.topology.n_dof
    out = np.empty((2 * n, 2 * n))
    for j in range(2 * n):
        e = np.zeros(2 * n)
        e[j] = 1.0
        q, v, _, _ = transfer(machine, e[:n], e[n:], linear=True)
        out[:, j] = np.concatenate([q, v])
    return out


def cycle_grid(cam, samples_per_cycle: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times of one index cycle (both ends), the cam's lift and acceleration there."""
    t = cam.cycle_s * np.arange(samples_per_cycle + 1) / samples_per_cycle
    s, _, a, _ = cam.svaj(t)
    return t, np.asarray(s, dtype=float), np.asarray(a, dtype=float)


def periodic_state(
    machine: MachineOnWheels,
    cam,
    samples_per_cycle: int = 360,
    *,
    relabel: bool = True,
    tol: float = 1e-7,
    max_iterations: int = 20,
) -> CycleResponse:
    """The steady state of continuous indexing over one index cycle (relabelled by default, see the
    module docstring); the cam's acceleration is held linearly between the samples. `tol` bounds the
    period residual of the polygonal model's Newton shooting relative to the state's scale: the
    integrator's own error is about 1e-8 of it (its residual stalls there), so 1e-7 is the tightest
    that is reliably met; the linear model's state is exact (one linear solve) and ignores it."""
    t, s, a = cycle_grid(cam, samples_per_cycle)
    if not relabel and machine.seat_change_lift_m is not None:
        raise DynamicsError("relabel: the labelled steady state keeps its seats; it is for tooth phase 0 only")
    system = machine.system()
    n = system.n_dof
    jac, rhs = _linear_cycle_map(machine, t, s, a, relabel)
    lu = lu_factor(np.eye(2 * n) - jac)
    x0 = lu_solve(lu, rhs)
    zdot = _cam_speed(cam)
    if machine.polygonal:
        x0 = _newton(machine, lu, x0, t, s, a, relabel, tol, max_iterations, zdot)
    return _cycle(machine, x0, t, s, a, relabel, zdot)


def _cam_speed(cam):
    return lambda time: float(cam.svaj(np.array([time]))[1][0])


def _linear_cycle_map(machine: MachineOnWheels, t, s, a, relabel: bool):
    """(J, r) with x -> J x + r the polygon-free model's one index cycle, transfer included: A Phi and
    A r at the dwell; Phi_2 A Phi_1 and Phi_2 A r_1 + r_2 split at a seat change inside the cycle
    (the cam's acceleration held linearly between the samples as on the whole grid)."""
    system = machine.system()
    load = machine.inertial_load()
    n = system.n_dof
    t_seat = sampled_seat_change_s(t, s, machine.seat_change_lift_m)
    if t_seat is None:
        phi = monodromy(system, t)
        r = propagate(system, t, -np.outer(a, load), np.zeros(2 * n))[-1]
        return (transfer_matrix(machine) @ phi, transfer_matrix(machine) @ r) if relabel else (phi, r)
    (t1, a1), (t2, a2) = _split(t, a, t_seat)
    phi1, phi2 = monodromy(system, t1), monodromy(system, t2)
    r1 = propagate(system, t1, -np.outer(a1, load), np.zeros(2 * n))[-1]
    r2 = propagate(system, t2, -np.outer(a2, load), np.zeros(2 * n))[-1]
    shift = transfer_matrix(machine)
    return phi2 @ shift @ phi1, phi2 @ (shift @ r1) + r2


def _split(t, a, t_seat):
    """The sample grid and the cam's acceleration split at t_seat, both pieces with it as a node (the
    acceleration held linearly between the samples as on the whole grid)."""
    a_seat = np.interp(t_seat, t, a)
    before, after = t < t_seat, t > t_seat
    return (np.append(t[before], t_seat), np.append(a[before], a_seat)), (
        np.insert(t[after], 0, t_seat),
        np.insert(a[after], 0, a_seat),
    )


def labelled_periodic_state(machine: MachineOnWheels, cam, samples_per_cycle: int = 360) -> CycleResponse:
    return periodic_state(machine, cam, samples_per_cycle, relabel=False)


def _run(machine, x0, t, s, a, zdot):
    """q, v over the cycle and the seat change inside it (machine_ivp.MachineResponse.seating, None
    at the dwell)."""
    n = x0.size // 2
    if machine.polygonal:
        r = integrate_cycle(
            machine, lambda x: np.interp(x, t, a), lambda x: np.interp(x, t, s), t, x0[:n], x0[n:], zdot=zdot
        )
        return r.q_m, r.v_m_s, r
    if machine.seat_change_lift_m is not None:
        return _run_linear_split(machine, x0, t, s, a, zdot)
    resp = solve(
        machine.system(),
        SampledForce(t, -np.outer(a, machine.inertial_load())),
        t,
        method="exact",
        x0=x0[:n],
        v0=x0[n:],
    )
    return resp.x, resp.v, None


def _run_linear_split(machine, x0, t, s, a, zdot):
    """The polygon-free model with its seat change inside the cycle: the exact solver to the instant
    (the cam's acceleration held linearly between the samples as on the whole grid), the transfer
    there, the exact solver on."""
    n = x0.size // 2
    t_seat = sampled_seat_change_s(t, s, machine.seat_change_lift_m)
    load, system = machine.inertial_load(), machine.system()
    (t1, a1), (t2, a2) = _split(t, a, t_seat)
    first = solve(system, SampledForce(t1, -np.outer(a1, load)), t1, method="exact", x0=x0[:n], v0=x0[n:])
    z_rel = float(np.interp(t_seat, t, s) - s[0])
    q1, v1, seating = seat_change_inside(machine, first.x[-1], first.v[-1], z_rel, float(zdot(t_seat)))
    second = solve(system, SampledForce(t2, -np.outer(a2, load)), t2, method="exact", x0=q1, v0=v1)
    after = 0 if np.any(t == t_seat) else 1  # a sample at the instant itself is the state after it
    q = np.concatenate([first.x[:-1], second.x[after:]])
    v = np.concatenate([first.v[:-1], second.v[after:]])
    return q, v, MachineResponse(t, q, v, 0, t_seat, seating)


def _end_state(machine, x0, t, s, a, relabel, zdot=None):
    q, v, _ = _run(machine, x0, t, s, a, zdot)
    if not relabel or machine.seat_change_lift_m is not None:  # no seat change left at the dwell
        return np.concatenate([q[-1], v[-1]])
    qn, vn, _, _ = transfer(machine, q[-1], v[-1])
    return np.concatenate([qn, vn])


def _newton(machine, lu, x0, t, s, a, relabel, tol, max_iterations, zdot):
    n = x0.size // 2
    scale = np.concatenate(
        [np.full(n, max(np.max(np.abs(x0[:n])), 1e-300)), np.full(n, max(np.max(np.abs(x0[n:])), 1e-300))]
    )
    for _ in range(max_iterations):
        residual = _end_state(machine, x0, t, s, a, relabel, zdot) - x0
        if np.max(np.abs(residual) / scale) <= tol:
            return x0
        x0 = x0 + lu_solve(lu, residual)
    raise SolverFailedError(f"machine steady state: period residual above {tol:g} after {max_iterations} iterations")


def _cycle(machine, x0, t, s, a, relabel, zdot) -> CycleResponse:
    q, v, run = _run(machine, x0, t, s, a, zdot)
    m = np.diag(machine.mass_matrix())
    acc = -(q @ machine.stiffness_matrix().T + v @ machine.damping_matrix().T) - np.outer(a, machine.inertial_load())
    inside = run is not None and run.seat_change_s is not None
    if machine.polygonal:
        radii = np.array([e.wheel.feed_radius_m for e in machine.wheel_ends])
        # after a seat change inside the cycle the angles count one tooth back (machine_ivp)
        z_ref = np.full(t.size, s[0])
        if inside:
            z_ref[t >= run.seat_change_s] += machine.sprocket.pitch_m
        acc = acc + np.array([machine.polygon_force((s_i - z0) / radii, q_i) for s_i, z0, q_i in zip(s, z_ref, q)])
    acc = acc / m
    speeds, impacts, change = (), (), 0.0
    if inside:
        speeds, impacts, change = run.seating
    elif relabel:
        q_new, v_new, speeds, impacts = transfer(machine, q[-1], v[-1])
        end = np.array([w.tooth_angle_rad for w in (e.wheel for e in machine.wheel_ends)])
        change = machine.stored_energy_J(q_new, v_new, 0.0, np.zeros(end.size)) - machine.stored_energy_J(
            q[-1], v[-1], 0.0, end
        )
    return CycleResponse(t, q, v, acc, a, speeds, impacts, change)


def link_residual_and_peak(
    machine: MachineOnWheels, cycle: CycleResponse, dwell_mask: np.ndarray, link: int
) -> tuple[float, float]:
    """At 0-based `link` (the link at that place at the start of the index): residual vibration,
    max |x - z| over the dwell samples, and peak |absolute acceleration| over the cycle. A link held
    to the cam has neither vibration nor acceleration beyond the cam's."""
    dof = int(machine.topology.link_dof()[link])
    y = np.zeros_like(cycle.t_s) if dof < 0 else cycle.q_m[:, dof]
    a = cycle.zddot_m_s2 + (0.0 if dof < 0 else cycle.a_m_s2[:, dof])
    mask = np.asarray(dwell_mask, dtype=bool)
    if not mask.any():
        raise DynamicsError("dwell_mask: no sample lies in a dwell; expected at least one")
    return float(np.max(np.abs(y[mask]))), float(np.max(np.abs(a)))
