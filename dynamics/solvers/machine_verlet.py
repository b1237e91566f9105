"""Fast integrator of the clearance chain on its wheels (dynamics.models.clearance_machine): the
clearance chain's explicit velocity Verlet (dynamics.solvers.clearance_verlet: the same step, the same
velocity predictors and stability limit) on any chain topology, the spans as a loop over the packed
arrays (behind, ahead, carriage, wheel), the forces back through the transposed incidence, the
polygonal feed d(a) of each wheel as a time-dependent offset of its two wheel-end spans evaluated at
every step, the global damping law as the plain product C q' (the machine has no mirror symmetry; in
single precision on the wheels, DAMPING_PRODUCT_PRECISIONS; the single-link drive's C has, and its
machine packs it in the ring's two blocks, `mirror_packed`, multiplied by the ring's own
product, clearance_verlet._mirror_product).
The Kelvin-Voigt dashpot's force jump at a contact change is located within the step as the ring's
(clearance_verlet._switch_impulse, `_span_impulses_into`: an impulse through the span's incidence,
its work counted as damping), so the step stays second order through the switches.
Compiled with numba when installed (the same functions run as Python otherwise, slowly).

One index cycle at a time: the polygonal feed's angle is counted from the dwell at the cycle's start
(`z_rel`, the cam's lift since then), where the seats change (dynamics.solvers.machine_steady.transfer).

Impacts (a span entering contact from free play), measured as the ring's kernel does
(clearance_verlet._impacts_loop, tested equal to round-off on the ring's topology): the crossing of
the span law's threshold interpolated within the step (`_crossing`), the closing speed there
extrapolated from the free-play side with the span's e' and e'' at the step's start (`_span_rates`,
through a wheel-end span's polygonal feed too; the start state recovered from the step's own
quantities, only in steps with an impact), its approach energy 1/4 m e'^2 (m_eff = m / 2), the force
spike the largest |T| within one impact duration pi sqrt(m_eff / k) counted from the crossing, and
(Kelvin-Voigt law) the span dashpots' work over the contacts begun by impacts while they last
(trapezoidal over the steps, from and to the crossings). Second order in the step, where the step's
end was first order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.models.machine_damping import chain_damping_into
from dynamics.solvers import kernel_cache
from dynamics.solvers.clearance_verlet import (
    FASTMATH,
    PREDICTORS,
    SPEED_CAPACITY,
    _crossing,
    _mirror_product,
    _rows_times,
    _switch_impulse,
    _tanh_branch_free,
    stable_omega_h,
)
from dynamics.solvers.friction_tanh import TANH_IS_ONE
from dynamics.solvers.shooting import search_out_every

try:
    import numba
except ImportError:  # pragma: no cover
    numba = None

# stats: impacts, free span-steps, recorded span-steps, peak T, min T, diverged at step, force spike,
# impact kinetic energy, largest closing speed, closing speeds stored, dashpot work in impact contacts,
# peak |T| in a contact begun by an impact (its whole length)
N_STATS = 12
# the station peaks over every step (`_station_nodes_into` in the step, `step_peaks` after it), per station: max |a| (absolute),
# max |x - z|, max |v - z'|, max |a - z''|, max |x - z| at the dwell's nodes: the max/min metrics of
# dynamics.response.metrics.LinkMetrics (PEAK_METRICS names them), as the machine's frame of places has them
PEAK_METRICS = (
    "max_abs_acceleration_m_s2",
    "max_deviation_m",
    "max_velocity_deviation_m_s",
    "max_acceleration_deviation_m_s2",
    "residual_vibration_m",
)
N_PEAKS = len(PEAK_METRICS)
# the station RMS metrics over every step (`step_moments` after the step, from the same node values as
# the peaks): the displacement, velocity and acceleration that dynamics.response.metrics.link_metrics
# squares (absolute: x = z + q, x' = z' + q', x'' = z'' + q''), the RMS over time the square root of
# their integral over the window (the trapezoid rule on the step's nodes) over the window's length
RMS_METRICS = ("rms_displacement_m", "rms_velocity_m_s", "rms_acceleration_m_s2")
# node flags (`integrate(node_flags=)`): the node is in the output window / in a dwell of the cam
IN_WINDOW, IN_DWELL = 1, 2
# entries of MachineArrays.par (ClearanceMachine.arrays: the last, par[8], whether links seat on tooth
# springs); more: the ring's mirror blocks (`mirror_packed`)
N_PAR = 9


def _wheels_into(q, v, z_rel, zd, wheel_float, wd, wsl, wdt):
    """Per wheel: the feed's departure d, its slope dd/du and its rate dd/dt at the wheel's angle
    (wheel_float as `_step_wheels` gives it; MachineArrays.wheel_float's four columns work too, the
    dwell's sine then computed here). One sine per wheel and step (the trigonometry was a tenth of
    the step): the cosine from it where the pin is within 1 rad of the strand's tangent (cos > 0.54,
    the root to a few ulps), else its own call."""
    for i in range(wheel_float.shape[0]):
        r, rm, g0, dof = wheel_float[i, 0], wheel_float[i, 1], wheel_float[i, 2], int(wheel_float[i, 3])
        u = q[dof] if dof >= 0 else 0.0
        ud = v[dof] if dof >= 0 else 0.0
        ang = (z_rel + u) / rm
        sine = math.sin(g0 + ang)
        cosine = math.sqrt(1.0 - sine * sine) if abs(g0 + ang) < 1.0 else math.cos(g0 + ang)
        sine0 = wheel_float[i, 4] if wheel_float.shape[1] > 4 else math.sin(g0)
        wd[i] = r * (sine - sine0) - rm * ang
        wsl[i] = (r * cosine - rm) / rm
        wdt[i] = wsl[i] * (zd + ud)


def _accel_into(
    q,
    v,
    z_rel,
    zd,
    zdd,
    span_int,
    span_float,
    dof_float,
    wheel_float,
    par,
    cmat,
    red,
    work,
    t_el,
    ed,
    contact,
    e_out,
    a,
):
    """a = M^-1 (forces) - r z'' of one state; span forces t_el, their stretches e_out and rates ed and
    contact flags;
    into work[6] the powers (cam, damping, friction) of the absolute-frame energy balance:

        d/dt [1/2 sum M (q' + r z')^2 + sum span energy + 1/2 sum k_g q^2 - f0 . q]
            = z' (sum over the DOFs that move with the cam of their force without friction
                  + sum over the wheel-end spans of T s dd/du)           (the cam's power)
              - (C q' . q' or the dashpots' T_d e' + c_g q'^2)           (damping)
              - (-F_friction . (q' + z'))                                (friction)"""
    k, preload, kg, beta_k, kv, fc, inv_vs = par[0], par[1], par[2], par[3], par[4] > 0.5, par[5], par[6]
    n = q.shape[0]
    wd, wsl, wdt, f, powers = work[0], work[1], work[2], work[3], work[6]
    _wheels_into(q, v, z_rel, zd, wheel_float, wd, wsl, wdt)
    for i in range(n):
        f[i] = dof_float[i, 5]
    p_damp = 0.0
    p_poly = 0.0
    for j in range(span_int.shape[0]):
        b, fw, c, wi = span_int[j, 0], span_int[j, 1], span_int[j, 2], span_int[j, 3]
        e = 0.0
        de = 0.0
        if fw >= 0:
            e += q[fw]
            de += v[fw]
        if b >= 0:
            e -= q[b]
            de -= v[b]
        if c >= 0:
            e += span_float[j, 0] * q[c]
            de += span_float[j, 0] * v[c]
        if wi >= 0:
            e += span_float[j, 1] * wd[wi]
            de += span_float[j, 1] * wdt[wi]
        d = preload + k * e
        t = max(d, 0.0) + min(d + kg, 0.0)
        on = (d >= 0.0) | (d <= -kg)
        t_el[j] = t
        e_out[j] = e
        ed[j] = de
        contact[j] = on
        if kv and on:
            t += beta_k * de
            p_damp += beta_k * de * de
        if fw >= 0:
            f[fw] -= t
        if b >= 0:
            f[b] += t
        if c >= 0:
            f[c] -= span_float[j, 0] * t
        if wi >= 0:
            p_poly += span_float[j, 1] * wsl[wi] * t
            dof = int(wheel_float[wi, 3])
            if dof >= 0:
                f[dof] -= span_float[j, 1] * wsl[wi] * t
    if not kv and red[0].shape[0] > 0:  # the O(N) form (dynamics.models.machine_damping) on the chain's DOFs
        dofs, scratch = red[0], red[6]
        wv, cw = scratch[4], scratch[5]
        for i in range(dofs.shape[0]):
            wv[i] = v[dofs[i]]
        # its factors in one precision, the other's array empty (`kernel_damping`)
        if red[8].shape[1] > 0:
            chain_damping_into(red[1], red[2], red[8], red[4], red[5], red[7], wv, cw, scratch)
        else:
            chain_damping_into(red[1], red[2], red[3], red[4], red[5], red[7], wv, cw, scratch)
        for i in range(dofs.shape[0]):
            f[dofs[i]] -= cw[i]
            p_damp += wv[i] * cw[i]
    elif not kv and cmat[1].shape[0] > 0:  # the dense C in single precision (`kernel_damping`)
        p_damp += _dense_damping_into(cmat[1], par, v, work[9], work[10], work[5], work[8], f)
    elif not kv:
        p_damp += _dense_damping_into(cmat[0], par, v, work[4], work[7], work[5], work[8], f)
    if par[8] > 0.0:  # tooth springs k_t (y - u - offset), Kelvin-Voigt: their dashpot beta k_t (y' - u')
        for i in range(n):
            if dof_float[i, 8] > 0.0:
                w, kt, o = int(dof_float[i, 7]), dof_float[i, 8], int(dof_float[i, 9])
                fs = kt * (q[i] - q[o] - (q[w] if w >= 0 else 0.0))
                if kv:
                    dv = v[i] - (v[w] if w >= 0 else 0.0)
                    fs += beta_k / k * kt * dv
                    p_damp += beta_k / k * kt * dv * dv
                f[i] -= fs
                if w >= 0:
                    f[w] += fs
    cam = 0.0
    for i in range(n):
        f[i] -= dof_float[i, 2] * q[i] + dof_float[i, 3] * v[i]
        p_damp += dof_float[i, 3] * v[i] * v[i]
        cam += dof_float[i, 1] * f[i]
    p_fric = 0.0
    if fc > 0.0:  # the friction law: the sign alone where every DOF is saturated (the cam in motion)
        unsaturated = 0
        for i in range(n):
            unsaturated += abs((zd + v[i]) * inv_vs) < TANH_IS_ONE
        if unsaturated:
            p_fric = _friction_into(v, zd, inv_vs, fc, dof_float, f)
        else:
            for i in range(n):
                fr = fc * dof_float[i, 4] * math.copysign(1.0, zd + v[i])
                f[i] -= fr
                p_fric += fr * (v[i] + dof_float[i, 1] * zd)
    for i in range(n):
        a[i] = f[i] * dof_float[i, 0] - dof_float[i, 1] * zdd
    powers[0] = zd * (cam + p_poly)
    powers[1] = p_damp
    powers[2] = p_fric


def _dense_damping_into(cmat, par, v, ws, wa, cv_out, cw, f):
    """f -= C v by the dense C in its own precision (ws, wa: padded columns of that precision): the
    ring's mirror blocks (`mirror_packed`) where par has them, else four rows at a time on the
    padded C (`_rows_times`); returns the damping's power C v . v."""
    p_damp = 0.0
    if par.shape[0] > N_PAR:  # the ring's C in its mirror blocks: the ring's product
        rs, links = int(par[N_PAR]), int(par[N_PAR + 1])
        _mirror_product(cmat[:rs], cmat[rs:], links, v, ws, wa, cv_out[:rs], cv_out[rs:], cw)
        for i in range(links):
            f[i] -= cw[i]
            p_damp += v[i] * cw[i]
        return p_damp
    n = v.shape[0]
    for i in range(n):
        ws[i] = v[i]
    _rows_times(cmat, ws, cv_out)
    for i in range(n):
        f[i] -= cv_out[i]
        p_damp += v[i] * cv_out[i]
    return p_damp


def _friction_into(v, zd, inv_vs, fc, dof_float, f):
    """f -= the friction law fc w tanh((z' + q') / v_s) on the DOFs with friction (w = dof_float[:, 4],
    0 elsewhere) where some DOF is off the law's saturation (in a dwell most are); returns its power.
    Every DOF's tanh by `_tanh_branch_free`, vectorised (one exp call and its branches per DOF cost
    100-180 us of a dwell step at 10,000 links: more than the span forces; the force evaluation is
    now 1.16x faster there, docs/performance.md). Compiled on its own, with numpy's error model (a
    division by zero not checked): numba's check kept the division out of vectors."""
    p_fric = 0.0
    for i in range(v.shape[0]):
        fr = fc * dof_float[i, 4] * _tanh_branch_free((zd + v[i]) * inv_vs)
        f[i] -= fr
        p_fric += fr * (v[i] + dof_float[i, 1] * zd)
    return p_fric


def mirror_packed(cmat: np.ndarray, par: np.ndarray, n_links: int):
    """(cmat, par) for the ring's product (clearance_verlet._mirror_product on two row slices of cmat)
    when the links' block of the machine's C (its first n_links DOFs, nothing coupling them to the
    rest) commutes with the loop's reflection about link 0, as the single-link drive's does: its two
    mirror blocks (clearance_verlet.reflection_blocks, padded) stacked, the symmetric on top, par
    extended by the symmetric block's padded rows and n_links. None otherwise."""
    from dynamics.solvers.clearance_verlet import reflection_blocks

    c = np.asarray(cmat)
    if np.any(c[:n_links, n_links:]) or np.any(c[n_links:, :n_links]):
        return None
    sym, anti = reflection_blocks(np.ascontiguousarray(c[:n_links, :n_links]))
    if anti.shape[0] == 0:
        return None
    packed = np.zeros((sym.shape[0] + anti.shape[0], max(sym.shape[1], anti.shape[1])))
    packed[: sym.shape[0], : sym.shape[1]] = sym
    packed[sym.shape[0] :, : anti.shape[1]] = anti
    return packed, np.r_[par[:N_PAR], sym.shape[0], n_links]


def _kinetic_abs_J(v, zd, dof_float):
    """Kinetic energy of the DOFs' absolute velocities v + r z'."""
    ke = 0.0
    for i in range(v.shape[0]):
        x = v[i] + dof_float[i, 1] * zd
        ke += 0.5 * dof_float[i, 6] * x * x
    return ke


def _span_impulses_into(
    h,
    e_old,
    e_new,
    was_on,
    ed_old,
    ed_new,
    span_int,
    span_float,
    dof_float,
    wheel_float,
    par,
    work,
    q,
    v,
):
    """The contact changes located within the step on the topology's spans (stretches e_old, e_new at
    the step's ends, `was_on` the start's contact flags): the Kelvin-Voigt dashpot's switch
    (clearance_verlet `_switch_impulse`, an impulse), applied to its span's ends through the same B^T
    as its force (the carriage's share, the wheel-end span's gain dd/du at the step's end, work[1]),
    divided by the DOFs' masses."""
    k, preload, kg, beta_k = par[0], par[1], par[2], par[3]
    wsl = work[1]
    for j in range(span_int.shape[0]):
        d_old, d_new = preload + k * e_old[j], preload + k * e_new[j]
        impulse = _switch_impulse(h, d_old, d_new, was_on[j], ed_old[j], ed_new[j], kg, beta_k)
        if impulse == 0.0:
            continue
        b, fw, c, wi = span_int[j, 0], span_int[j, 1], span_int[j, 2], span_int[j, 3]
        if fw >= 0:
            v[fw] -= impulse * dof_float[fw, 0]
        if b >= 0:
            v[b] += impulse * dof_float[b, 0]
        if c >= 0:
            v[c] -= span_float[j, 0] * impulse * dof_float[c, 0]
        if wi >= 0:
            dof = int(wheel_float[wi, 3])
            if dof >= 0:
                v[dof] -= span_float[j, 1] * wsl[wi] * impulse * dof_float[dof, 0]


def _station_nodes_into(q, v, a, node, stations, values):
    """values[node, s] = (q, q', q'') at station s's DOF (0 for a place held to the cam): what
    `step_peaks` folds into the peaks after the run (a few stores per node; folding them here, in the
    step, cost a sixth of the step at 85 links)."""
    for s in range(stations.shape[0]):
        d = stations[s]
        if d >= 0:
            values[node, s, 0] = q[d]
            values[node, s, 1] = v[d]
            values[node, s, 2] = a[d]


def _switches_at_stations(e_old, e_new, par, span_int, wheel_float, stations, switch):
    """switch[s]: the fraction of the step at which a span with an end at station s's DOF changed
    contact (the crossing of the span law's threshold interpolated, `_crossing`); left as it is (-1)
    where none did."""
    k, preload, kg = par[0], par[1], par[2]
    for j in range(span_int.shape[0]):
        d_old, d_new = preload + k * e_old[j], preload + k * e_new[j]
        on_old = (d_old >= 0.0) | (d_old <= -kg)
        on_new = (d_new >= 0.0) | (d_new <= -kg)
        if on_old == on_new:
            continue
        on_side = d_new if on_new else d_old
        frac = _crossing(d_old, d_new, 0.0 if on_side >= 0.0 else -kg)
        b, fw, c, wi = span_int[j, 0], span_int[j, 1], span_int[j, 2], span_int[j, 3]
        wdof = int(wheel_float[wi, 3]) if wi >= 0 else -1
        for s in range(stations.shape[0]):
            d = stations[s]
            if d >= 0 and (d == b or d == fw or d == c or d == wdof):
                switch[s] = frac


def _accel_work(n, wheel_float, cmat):
    """The scratch arrays `_accel_into` takes as `work`, for n DOFs, the wheels' rows and the dense
    damping's (double, single) pair `cmat` (`kernel_damping`): each precision's padded columns."""
    nw = max(wheel_float.shape[0], 1)
    double, single = cmat
    return (
        np.zeros(nw),
        np.zeros(nw),
        np.zeros(nw),
        np.zeros(n),
        np.zeros(double.shape[1]),
        np.zeros(max(double.shape[0], single.shape[0])),
        np.zeros(3),
        np.zeros(double.shape[1]),  # the mirror product's antisymmetric columns
        np.zeros(n),  # and its C v
        np.zeros(single.shape[1], dtype=np.float32),  # the same two in single precision
        np.zeros(single.shape[1], dtype=np.float32),
    )


def _run_loops(
    q,
    v,
    z_rel,
    zd,
    zdd,
    h,
    theta,
    out_every,
    record_from,
    span_int,
    span_float,
    dof_float,
    wheel_float,
    par,
    cmat,
    red,
    bound,
    out_q,
    out_v,
    out_a,
    out_t,
    stats,
    speeds,
    track_energy,
    energy,
    stations,
    station_values,
    switches,
):
    """The step loop (module docstring); `energy` (cam work, damping and friction dissipation)
    integrated trapezoidally in the powers at the steps' states when `track_energy` (one more force
    evaluation per step); the stations' motion at every node into `station_values` (`_station_nodes_into`:
    the acceleration the step computed, with its predicted velocity, and at an output node the
    output's) and their spans' contact changes into `switches` (`_switches_at_stations`, at the node
    ending the step: the peaks are not smooth there under either law, step_peaks)."""
    n_steps = zd.shape[0] - 1
    n = q.shape[0]
    ns = span_int.shape[0]
    q = q.copy()
    v = v.copy()
    a = np.empty(n)
    a_prev = np.empty(n)
    a_out = np.empty(n)
    wh = np.empty(n)
    wp = np.empty(n)
    t_el = np.empty(ns)
    ed = np.empty(ns)
    contact = np.empty(ns, dtype=np.bool_)
    was = np.empty(ns, dtype=np.bool_)  # the spans' contact at the step's start
    clock = np.zeros(ns)  # time since each contact begun by an impact began (from its crossing)
    in_impact = np.zeros(ns, dtype=np.bool_)  # a contact begun by an impact, while it lasts
    dash_prev = np.zeros(ns)  # its dashpot's power at the last step
    q_s = np.empty(n)  # the step's start state where an impact needs it
    v_s = np.empty(n)
    work = _accel_work(n, wheel_float, cmat)
    window = math.pi * math.sqrt(0.5 * par[7] / par[0])
    e_old = np.empty(ns)  # the span stretches at the step's start and end (the located switches)
    e_new = np.empty(ns)
    e_out = np.empty(ns)
    _accel_into(
        q,
        v,
        z_rel[0],
        zd[0],
        zdd[0],
        span_int,
        span_float,
        dof_float,
        wheel_float,
        par,
        cmat,
        red,
        work,
        t_el,
        ed,
        contact,
        e_old,
        a,
    )
    p_prev = work[6].copy()
    kv = par[4] > 0.5
    ed_old = ed.copy()  # the span rates the last dashpot forces were taken at
    for j in range(n):
        a_prev[j] = a[j]
    for j in range(ns):
        was[j] = contact[j]
    out_q[0] = q
    out_v[0] = v
    out_a[0] = a
    out_t[0] = t_el
    row = 1
    _station_nodes_into(q, v, a, 0, stations, station_values)
    if record_from == 0:
        _record(t_el, contact, stats)
    hh = 0.5 * h
    for i in range(n_steps):
        for j in range(n):
            wh[j] = v[j] + hh * a[j]
            q[j] += h * wh[j]
            wp[j] = v[j] + h * (a[j] + theta * (a[j] - a_prev[j]))
        a, a_prev = a_prev, a  # the step's start acceleration kept by name, not copied: a is written anew
        _accel_into(
            q,
            wp,
            z_rel[i + 1],
            zd[i + 1],
            zdd[i + 1],
            span_int,
            span_float,
            dof_float,
            wheel_float,
            par,
            cmat,
            red,
            work,
            t_el,
            ed,
            contact,
            e_new,
            a,
        )
        for j in range(n):
            v[j] = wh[j] + hh * a[j]
        if stations.shape[0] > 0:
            _switches_at_stations(e_old, e_new, par, span_int, wheel_float, stations, switches[i + 1])
        changed = 0  # Kelvin-Voigt: spans whose contact changed within the step (`contact`: the step's end)
        for j in range(ns if kv else 0):
            changed += contact[j] != was[j]
        if changed:
            before = _kinetic_abs_J(v, zd[i + 1], dof_float) if track_energy and kv else 0.0
            _span_impulses_into(
                h,
                e_old,
                e_new,
                was,
                ed_old,
                ed,
                span_int,
                span_float,
                dof_float,
                wheel_float,
                par,
                work,
                q,
                v,
            )
            if track_energy and kv:  # the impulses' work, dissipated by the dashpots
                energy[1] += before - _kinetic_abs_J(v, zd[i + 1], dof_float)
        for j in range(ns if kv else 0):
            ed_old[j] = ed[j]
        recording = i + 1 >= record_from
        have_start = False
        # most steps have no impact and no contact begun by one: a branch-free pass (it vectorises)
        # finds those, and the spans' loop below, with its branches, runs only in the others; the
        # same pass takes the step's statistics (`_record`'s: summed in locals, stored once)
        events = 0
        n_free = 0
        peak, low = stats[3], stats[4]
        for j in range(ns):
            events += (contact[j] > was[j]) | in_impact[j]
            n_free += not contact[j]
            peak = max(peak, t_el[j])
            low = min(low, t_el[j])
        if recording:
            stats[1] += n_free
            stats[2] += ns
            stats[3], stats[4] = peak, low
        for j in range(ns if events else 0):
            impact = contact[j] and not was[j]
            if not (impact or in_impact[j]):
                continue
            # the span's rate at the step's end (the final velocities): the Kelvin-Voigt dashpot's power
            # (written out: a call here, on every step of a contact, made the Kelvin-Voigt window 3x slower)
            ed_new = 0.0
            if kv:
                b, fw, c, wi = span_int[j, 0], span_int[j, 1], span_int[j, 2], span_int[j, 3]
                if fw >= 0:
                    ed_new += v[fw]
                if b >= 0:
                    ed_new -= v[b]
                if c >= 0:
                    ed_new += span_float[j, 0] * v[c]
                if wi >= 0:
                    dof = int(wheel_float[wi, 3])
                    ed_new += span_float[j, 1] * work[1][wi] * (zd[i + 1] + (v[dof] if dof >= 0 else 0.0))
            p_new = par[3] * ed_new * ed_new  # (0: global law)
            d_old = par[1] + par[0] * e_old[j]
            d_new = par[1] + par[0] * e_new[j]
            if impact:
                if not have_start:  # the step's start state, recovered from the step's own quantities
                    for m in range(n):
                        q_s[m] = q[m] - h * wh[m]
                        v_s[m] = wh[m] - hh * a_prev[m]
                    have_start = True
                ed_s, edd_s = _span_rates(
                    j, v_s, a_prev, z_rel[i], zd[i], zdd[i], q_s, span_int, span_float, wheel_float
                )
                frac = _crossing(d_old, d_new, 0.0 if d_new >= 0.0 else -par[2])
                ed_c = ed_s + frac * h * edd_s  # extrapolated from the free-play side
                clock[j] = (1.0 - frac) * h
                in_impact[j] = True
                dash_prev[j] = p_new
                if recording:
                    speed = abs(ed_c)
                    stats[6] = max(stats[6], abs(t_el[j]))
                    stats[11] = max(stats[11], abs(t_el[j]))
                    stats[0] += 1
                    stats[7] += 0.25 * par[7] * ed_c * ed_c
                    stats[10] += 0.5 * (1.0 - frac) * h * (par[3] * ed_c * ed_c + p_new)
                    stats[8] = max(stats[8], speed)
                    stored = int(stats[9])
                    if stored < speeds.shape[0]:
                        speeds[stored] = speed
                        stats[9] = stored + 1
            elif contact[j]:
                clock[j] += h
                if recording:
                    if clock[j] <= window:
                        stats[6] = max(stats[6], abs(t_el[j]))
                    stats[11] = max(stats[11], abs(t_el[j]))
                    stats[10] += hh * (dash_prev[j] + p_new)
                dash_prev[j] = p_new
            else:  # the contact begun by an impact ends within the step
                frac = _crossing(d_old, d_new, 0.0 if d_old >= 0.0 else -par[2])
                ed_c = 0.0
                if kv:  # extrapolated back from the free-play side
                    ed_c, edd_new = _span_rates(
                        j, v, a, z_rel[i + 1], zd[i + 1], zdd[i + 1], q, span_int, span_float, wheel_float
                    )
                    ed_c -= (1.0 - frac) * h * edd_new
                if recording:
                    stats[10] += 0.5 * frac * h * (dash_prev[j] + par[3] * ed_c * ed_c)
                in_impact[j] = False
                dash_prev[j] = 0.0
        contact, was = was, contact  # the step's end is the next one's start (`contact` is written anew)
        e_old, e_new = e_new, e_old
        on_output = (i + 1) % out_every == 0
        if track_energy or on_output:
            _accel_into(
                q,
                v,
                z_rel[i + 1],
                zd[i + 1],
                zdd[i + 1],
                span_int,
                span_float,
                dof_float,
                wheel_float,
                par,
                cmat,
                red,
                work,
                t_el,
                ed,
                contact,
                e_out,
                a_out,
            )
            if track_energy:
                for m in range(3):
                    energy[m] += hh * (p_prev[m] + work[6][m])
                    p_prev[m] = work[6][m]
        _station_nodes_into(q, v, a_out if on_output else a, i + 1, stations, station_values)
        if on_output:
            out_q[row] = q
            out_v[row] = v
            out_a[row] = a_out
            out_t[row] = t_el
            row += 1
            big = 0.0
            for j in range(n):
                big = max(big, abs(q[j]))
            if not (big < bound):
                stats[5] = i + 1
                return


def _span_rates(j, v, acc, z_rel, zd, zdd, q, span_int, span_float, wheel_float):
    """Span j's stretch rate e' and its second derivative e'' at one state (the DOFs' q, q' = v,
    q'' = acc, the cam's lift since the dwell, speed and acceleration): B v and B acc through the
    span's incidence, and a wheel-end span's feed d(a), a = (z_rel + u) / R_m, differentiated along
    the wheel's motion: d' = s (z' + u'), d'' = s (z'' + u'') - R sin(g0 + a) (z' + u')^2 / R_m^2,
    s = dd/du (`_wheels_into`)."""
    b, fw, c, wi = span_int[j, 0], span_int[j, 1], span_int[j, 2], span_int[j, 3]
    de = 0.0
    dde = 0.0
    if fw >= 0:
        de += v[fw]
        dde += acc[fw]
    if b >= 0:
        de -= v[b]
        dde -= acc[b]
    if c >= 0:
        de += span_float[j, 0] * v[c]
        dde += span_float[j, 0] * acc[c]
    if wi >= 0:
        r, rm, g0, dof = wheel_float[wi, 0], wheel_float[wi, 1], wheel_float[wi, 2], int(wheel_float[wi, 3])
        u = q[dof] if dof >= 0 else 0.0
        ud = zd + (v[dof] if dof >= 0 else 0.0)
        udd = zdd + (acc[dof] if dof >= 0 else 0.0)
        ang = g0 + (z_rel + u) / rm
        slope = (r * math.cos(ang) - rm) / rm
        de += span_float[j, 1] * slope * ud
        dde += span_float[j, 1] * (slope * udd - r * math.sin(ang) * ud * ud / (rm * rm))
    return de, dde


def _record(t_el, contact, stats):
    # summed in locals, stored once: through stats itself each span waited on the last one's store
    # (a tenth of the step at 85 links)
    free, seen, peak, low = stats[1], stats[2], stats[3], stats[4]
    for j in range(t_el.shape[0]):
        free += not contact[j]
        seen += 1
        peak = max(peak, t_el[j])
        low = min(low, t_el[j])
    stats[1], stats[2], stats[3], stats[4] = free, seen, peak, low


if numba is not None:
    for _name in (
        "_wheels_into",
        "_accel_into",
        "_record",
        "_kinetic_abs_J",
        "_span_impulses_into",
        "_span_rates",
        "_station_nodes_into",
        "_switches_at_stations",
        "_accel_work",
    ):
        globals()[_name] = numba.njit(cache=True, fastmath=FASTMATH, inline="always")(globals()[_name])
    _friction_into = numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")(_friction_into)
    _dense_damping_into = numba.njit(cache=True, fastmath=FASTMATH)(_dense_damping_into)
    _run = numba.njit(cache=True, fastmath=FASTMATH)(_run_loops)
else:  # pragma: no cover
    _run = _run_loops


# The global law's dense product C q' (the machine up to DENSE_LINK_LIMIT links), summed in C's
# precision (`_rows_times`). On the wheels it is single: the product was 0.9 of the step's 2.4 us
# at 85 links (C in double does not fit the core's cache beside the step's arrays), single takes about
# half of that, and its rounding (1e-7 of C q') moves the station metrics by about 1e-7 (bench_machine's
# window), four orders below the step's 1e-3. The link drive keeps double: on this kernel it replicates
# the ring's (dynamics.solvers.clearance_verlet, double), tested equal to 1e-12.
DAMPING_PRODUCT_PRECISIONS = {"single": np.float32, "double": np.float64}


def default_damping_precision(model) -> str:
    """The dense damping product's precision for `model` (DAMPING_PRODUCT_PRECISIONS)."""
    return "double" if model.machine.drive == "link" else "single"


@dataclass(frozen=True)
class MachineRun:
    """Outputs of one integration: DOF states and span forces at the output nodes, window statistics."""

    q: np.ndarray  # (m, n_dof) relative to the cam
    v: np.ndarray
    a: np.ndarray  # relative accelerations q''
    tension_N: np.ndarray  # (m, n_spans) elastic span forces
    impacts: int
    free_play_fraction: float
    peak_tension_N: float
    min_tension_N: float
    impact_force_spike_N: float
    impact_kinetic_energy_J: float
    impact_max_speed_m_s: float
    impact_speeds_m_s: np.ndarray
    step_s: float
    impact_dissipated_J: float = 0.0  # Kelvin-Voigt dashpots' work in contacts begun by impacts (0: global law)
    peak_force_in_impact_contact_N: float = 0.0  # largest |T| while a contact begun by an impact lasts
    cam_work_J: float = 0.0  # the energy terms, when integrate(track_energy=True)
    dissipated_damping_J: float = 0.0
    dissipated_friction_J: float = 0.0
    # (stations, N_PEAKS) the station peaks (PEAK_METRICS) over every node of the window
    # (integrate(stations=)); NaN where no node counted; None: not tracked
    station_peaks: np.ndarray | None = None
    # (output intervals, stations, RMS_METRICS, 3) per output interval the trapezoid rule's integrals
    # of 1, y and y^2 over its steps (`step_moments`), y the station's displacement in the run's lift
    # frame (q + z_rel), its absolute velocity and acceleration; None: not tracked
    station_moments: np.ndarray | None = None


def integrate(
    model,
    z_rel_nodes,
    zd_nodes,
    zdd_nodes,
    step_s: float,
    q0,
    v0,
    *,
    out_every: int = 1,
    record_from: int = 0,
    predictor: str = "euler",
    track_energy: bool = False,
    damping_precision: str | None = None,
    stations=None,
    node_flags=None,
    interpolate_peaks: bool = True,
) -> MachineRun:
    """Step the clearance machine `model` over the cam's nodes (lift since the dwell, velocity,
    acceleration; uniform step, n_steps + 1 nodes) from (q0, v0); the global law's dense product in
    `damping_precision` (DAMPING_PRODUCT_PRECISIONS; None: `default_damping_precision`). `stations`:
    DOFs (-1: a place that moves with the cam) whose peaks (PEAK_METRICS) are tracked at every node
    over the nodes `node_flags` (IN_WINDOW | IN_DWELL per node; None: every node in the window, none
    in a dwell), by the largest node or, `interpolate_peaks`, the parabola through the three nodes
    around it (`step_peaks`; not across a station's contact change, where the acceleration has a kink
    under the global law and jumps under the Kelvin-Voigt law: there the one-sided values), and their
    motion's integrals for the RMS over every step per output interval (`step_moments`, over every node
    whatever its flags)."""
    theta = PREDICTORS[predictor]
    precision = default_damping_precision(model) if damping_precision is None else damping_precision
    if precision not in DAMPING_PRODUCT_PRECISIONS:
        raise DynamicsError(
            f"damping_precision: expected one of {sorted(DAMPING_PRODUCT_PRECISIONS)}, got {damping_precision!r}"
        )
    if theta and model.span_damping != "global":
        raise DynamicsError(f"predictor: {predictor!r} is for the global damping law; use predictor='euler'")
    zr, zd, zdd = (np.ascontiguousarray(x, dtype=float) for x in (z_rel_nodes, zd_nodes, zdd_nodes))
    n_steps = zd.size - 1
    if zr.shape != zd.shape or zdd.shape != zd.shape or n_steps < 1 or n_steps % out_every:
        raise DynamicsError("integrate: expected cam nodes of equal length, a whole number of output intervals")
    arr = model.arrays
    n = arr.dof_float.shape[0]
    q0 = np.array(q0, dtype=float).reshape(n)
    v0 = np.array(v0, dtype=float).reshape(n)
    c = model.chain
    scale = max(np.max(np.abs(q0)), np.max(np.abs(zr)), c.preload_N / c.stiffness_N_per_m, 1e-9)
    m_out = n_steps // out_every + 1
    out = [np.zeros((m_out, n)) for _ in range(3)] + [np.zeros((m_out, arr.span_int.shape[0]))]
    stats = np.zeros(N_STATS)
    stats[3], stats[4] = -np.inf, np.inf
    speeds = np.zeros(SPEED_CAPACITY)
    energy = np.zeros(3)
    dofs = np.zeros(0, dtype=np.int64) if stations is None else np.asarray(stations, dtype=np.int64).reshape(-1)
    if np.any(dofs >= n) or np.any(dofs < -1):
        raise DynamicsError(f"integrate: expected station DOFs in -1..{n - 1}, got {dofs.tolist()}")
    flags = np.full(n_steps + 1, IN_WINDOW, dtype=np.int64) if node_flags is None else np.asarray(node_flags)
    if flags.shape != (n_steps + 1,):
        raise DynamicsError(f"integrate: expected one node flag per cam node ({n_steps + 1}), got {flags.shape}")
    station_values = np.zeros((n_steps + 1 if dofs.size else 0, dofs.size, 3))
    switches = np.full((n_steps + 1 if dofs.size else 0, dofs.size), -1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        _run(
            q0,
            v0,
            zr,
            zd,
            zdd,
            float(step_s),
            theta,
            int(out_every),
            int(record_from),
            arr.span_int,
            arr.span_float,
            np.asfortranarray(arr.dof_float),  # its columns contiguous: the DOF loops run as vectors
            _step_wheels(arr.wheel_float),
            arr.par,
            *kernel_damping(arr, precision),
            1e6 * scale,
            *out,
            stats,
            speeds,
            bool(track_energy),
            energy,
            dofs,
            station_values,
            switches,
        )
    if stats[5] or not np.all(np.isfinite(out[0])):
        raise SolverDivergedError(
            f"machine-verlet: solution diverged at step {stats[5] or '?'} (step {step_s:.3g} s); reduce the step"
        )
    recorded = max(stats[2], 1.0)
    return MachineRun(
        *out,
        impacts=int(stats[0]),
        free_play_fraction=float(stats[1] / recorded),
        peak_tension_N=float(stats[3]),
        min_tension_N=float(stats[4]),
        impact_force_spike_N=float(stats[6]),
        impact_kinetic_energy_J=float(stats[7]),
        impact_max_speed_m_s=float(stats[8]),
        impact_speeds_m_s=speeds[: int(stats[9])].copy(),
        impact_dissipated_J=float(stats[10]),
        peak_force_in_impact_contact_N=float(stats[11]),
        step_s=float(step_s),
        cam_work_J=float(energy[0]),
        dissipated_damping_J=float(energy[1]),
        dissipated_friction_J=float(energy[2]),
        station_peaks=None if stations is None else step_peaks(station_values, zdd, flags, switches, interpolate_peaks),
        station_moments=None if stations is None else step_moments(station_values, (zr, zd, zdd), step_s, out_every),
    )


def kernel_damping(arrays, precision: str) -> tuple:
    """(cmat, red) as the compiled step takes them (`_accel_into`): the dense C as a (double, single)
    pair, the `precision` one filled and the other empty, and the O(N) form's arrays
    (MachineArrays.reduced) with its factors likewise a pair, red[3] double and red[8] single. One type
    signature for every machine, so one compiled specialisation of the step serves the link drive,
    the wheels and the long chains' single-precision factors (each a compilation of about a minute
    of CPU on an empty cache: a first run above SINGLE_PRECISION_FACTORS_ABOVE_LINKS links paid it)."""
    dense = np.ascontiguousarray(arrays.cmat, dtype=DAMPING_PRODUCT_PRECISIONS[precision])
    red = arrays.reduced
    double, single = _precision_pair(red[3], (3, 0, 0))
    return _precision_pair(dense, (0, 0)), (*red[:3], double, *red[4:], single)


def _precision_pair(array: np.ndarray, empty_shape: tuple) -> tuple[np.ndarray, np.ndarray]:
    """(double, single): `array` in the slot of its precision, an empty array of `empty_shape` in the other."""
    if array.dtype == np.float64:
        return array, np.zeros(empty_shape, dtype=np.float32)
    return np.zeros(empty_shape), array


def _step_wheels(wheel_float: np.ndarray) -> np.ndarray:
    """MachineArrays.wheel_float with sin(gamma at the dwell) as a fifth column (`_wheels_into`)."""
    return np.ascontiguousarray(np.column_stack([wheel_float, np.sin(wheel_float[:, 2])]))


def stable_step_s(model, safety: float, predictor: str) -> float:
    omega = model.max_frequency_rad_s
    return safety * _stable_omega_h(model.damping_ratio_at(omega), predictor) / omega


@lru_cache(maxsize=64)
def _stable_omega_h(zeta: float, predictor: str) -> float:
    return stable_omega_h(zeta, predictor)


def substeps_for(model, output_step_s: float, safety: float, predictor: str) -> int:
    return max(1, int(math.ceil(output_step_s / stable_step_s(model, safety, predictor) - 1e-9)))


@dataclass(frozen=True)
class Seating:
    """The seat changes of an index cycle, at its end or inside it at a tooth phase other than 0
    (dynamics.solvers.machine_steady.transfer): per wheel the seating speed |(y'_in + z') - c (u' + z')|
    (z' = 0 at the dwell) and the kinetic energy its plastic impact takes, and the transfer's whole
    change of stored energy (the clearance law's span energy), SI."""

    speed_m_s: tuple[float, ...]
    impact_energy_J: tuple[float, ...]
    transfer_energy_change_J: float
    # the cam at the seat change (0 at the dwell): what dynamics.response.seating judges rigid seating by
    cam_speed_m_s: float = 0.0
    cam_acceleration_m_s2: float = 0.0


def cycle_nodes(cam, step_s: float, n_steps: int):
    """The cam over one index cycle from its start (lift since the dwell, velocity, acceleration)."""
    t = step_s * np.arange(n_steps + 1)
    s, v, a, _ = cam.svaj(t)
    s = np.asarray(s, dtype=float)
    return s - s[0], np.asarray(v, dtype=float), np.asarray(a, dtype=float)


def seat_change(model, q, v, z_rel_end_m: float, cycle_s: float | None = None, *, seating: bool = True):
    """(q, v) after the transfer at the dwell, and its Seating (None when not `seating`: the stored
    energies before and after, which only the Seating reports, are then not computed); `cycle_s` (the
    index cycle) the tooth model's engagement time (dynamics.solvers.tooth_transfer)."""
    from dynamics.solvers.machine_steady import transfer
    from dynamics.solvers.tooth_transfer import tooth_transfer

    if model.seats:  # a tooth stiffness: the links seat where they are, their seat offsets carried
        q_new, v_new, speeds, impacts = tooth_transfer(model, q, v, np.zeros(len(model.seats)), cycle_s)
    else:
        q_new, v_new, speeds, impacts = transfer(model.machine, q, v)
    if not seating:
        return q_new, v_new, None
    change = model.stored_energy_J(q_new, v_new, 0.0, 0.0) - model.stored_energy_J(q, v, 0.0, z_rel_end_m)
    return q_new, v_new, Seating(speeds, impacts, float(change))


def seat_change_inside(
    model,
    q,
    v,
    z_rel_m: float,
    zdot_m_s: float,
    zddot_m_s2: float = 0.0,
    cycle_s: float | None = None,
    *,
    seating: bool = True,
):
    """(q, v) after the transfer inside the index (tooth phase != 0) at the cam's lift since the dwell
    `z_rel_m`, speed `zdot_m_s` and acceleration `zddot_m_s2` (recorded in the Seating), and its
    Seating (None when not `seating`, as for `seat_change`); after it the lift counts one pitch on.
    `cycle_s`: as for `seat_change`."""
    from dynamics.solvers.machine_steady import transfer
    from dynamics.solvers.tooth_transfer import tooth_transfer

    mach = model.machine
    radii = np.array([ends.wheel.feed_radius_m for ends in mach.wheel_ends])
    pitch = mach.sprocket.pitch_m
    if model.seats:  # a tooth stiffness: the links seat where they are, their seat offsets carried
        q_new, v_new, speeds, impacts = tooth_transfer(model, q, v, (z_rel_m - pitch) / radii, cycle_s, zdot_m_s)
    else:
        q_new, v_new, speeds, impacts = transfer(mach, q, v, angles_rad=z_rel_m / radii, zdot_m_s=zdot_m_s)
    if not seating:
        return q_new, v_new, None
    after = model.stored_energy_J(q_new, v_new, zdot_m_s, z_rel_m - pitch)
    change = after - model.stored_energy_J(q, v, zdot_m_s, z_rel_m)
    return q_new, v_new, Seating(speeds, impacts, float(change), float(zdot_m_s), float(zddot_m_s2))


def index_cycle(
    model,
    cam,
    nodes,
    step_s: float,
    q0,
    v0,
    *,
    out_every: int,
    predictor: str,
    track_energy: bool = False,
    stations=None,
    flags_at=None,
    seating: bool = True,
):
    """One index cycle from its start over the cam's `nodes` (cycle_nodes), outputs every `out_every`
    steps: (MachineRun, Seating of a seat change inside it or None; None too when not `seating`:
    seat_change_inside). At tooth phase 0 this is
    `integrate` and the seats change after it (`seat_change`). Else
    the cycle is stepped in pieces: to the last output node before the seat change's instant (the
    cam's lift since the dwell at MachineOnWheels.seat_change_lift_m, located by brentq on the cam's
    law), a uniform sub-step (<= step_s) to the instant, the transfer there, a uniform sub-step to
    the next output node, then the remaining nodes with the lift counted one pitch on (the next
    index's frame, so nothing is left to do at the cycle's end); outputs at or after the instant
    are in the new labels. The statistics are merged over the pieces (the free-play fraction
    weighted by their durations). `stations` and `flags_at` (the node flags at times since the
    cycle's start): the station peaks (`integrate`)."""
    from dynamics.solvers.machine_ivp import cam_lift_m, cam_seat_change_s

    zr, zd, zdd = nodes
    n_steps = zd.size - 1
    flags = None if flags_at is None else flags_at(step_s * np.arange(n_steps + 1))
    peaks = {"stations": stations, "flags_at": flags_at}
    lift = model.machine.seat_change_lift_m

    def up_to(last: int):
        """The cycle's steps from its start to node `last`, from (q0, v0) as given."""
        nodes = slice(0, last + 1)
        return integrate(
            model,
            zr[nodes],
            zd[nodes],
            zdd[nodes],
            step_s,
            q0,
            v0,
            out_every=out_every,
            predictor=predictor,
            track_energy=track_energy,
            stations=stations,
            node_flags=None if flags is None else flags[nodes],
        )

    if lift is None:
        return up_to(n_steps), None

    s0 = cam_lift_m(cam, 0.0)
    t_seat = cam_seat_change_s(cam, n_steps * step_s, lift)
    pitch = model.machine.sprocket.pitch_m
    h_out = out_every * step_s
    before = (int(math.ceil(t_seat / h_out - 1e-9)) - 1) * out_every  # last output node before the instant
    nxt = before + out_every
    on_node = abs(nxt * step_s - t_seat) <= 1e-9 * step_s
    pieces, rows, durations = [], [], []
    moments = []  # per output interval, in the cycle's lift frame (the pieces after the seat change one pitch on)
    if before > 0:
        head = up_to(before)
        pieces.append(head)
        durations.append(before * step_s)
        rows.append(head)
        moments.append(head.station_moments)
        q0, v0 = head.q[-1], head.v[-1]
    to_seat = _sub_steps(model, cam, (before * step_s, t_seat), step_s, s0, q0, v0, predictor, track_energy, **peaks)
    pieces.append(to_seat)
    durations.append(t_seat - before * step_s)
    seat_interval = to_seat.station_moments  # the output interval around the seat change
    if before == 0:
        rows.append(_first_row(to_seat))
    _, zd_seat, zdd_seat, _ = (float(x[0]) for x in cam.svaj(np.array([t_seat])))
    q1, v1, seated = seat_change_inside(
        model,
        to_seat.q[-1],
        to_seat.v[-1],
        cam_lift_m(cam, t_seat) - s0,
        zd_seat,
        zdd_seat,
        n_steps * step_s,
        seating=seating,
    )
    if not on_node:
        to_node = _sub_steps(
            model, cam, (t_seat, nxt * step_s), step_s, s0 + pitch, q1, v1, predictor, track_energy, **peaks
        )
        pieces.append(to_node)
        durations.append(nxt * step_s - t_seat)
        rows.append(_last_row(to_node))
        if seat_interval is not None:
            seat_interval = seat_interval + shifted_moments(to_node.station_moments, pitch)
        q1, v1 = to_node.q[-1], to_node.v[-1]
    if nxt < n_steps:
        tail = integrate(
            model,
            zr[nxt:] - pitch,
            zd[nxt:],
            zdd[nxt:],
            step_s,
            q1,
            v1,
            out_every=out_every,
            predictor=predictor,
            track_energy=track_energy,
            stations=stations,
            node_flags=None if flags is None else flags[nxt:],
        )
        pieces.append(tail)
        durations.append((n_steps - nxt) * step_s)
        rows.append(tail if on_node else _rows_from(tail, 1))
    merged = _merged(pieces, rows, durations, step_s)
    if stations is None:
        return merged, seated
    moments.append(seat_interval)
    if nxt < n_steps:
        moments.append(shifted_moments(tail.station_moments, pitch))
    return replace(merged, station_moments=np.concatenate(moments)), seated


def _sub_steps(
    model, cam, span_s, step_s: float, s_ref: float, q0, v0, predictor, track_energy, stations=None, flags_at=None
):
    """Over span_s = (t0, t1) in the fewest equal steps of at most step_s, the lift counted from s_ref;
    outputs at both ends; the station peaks as index_cycle's."""
    t0, t1 = span_s
    n = max(1, int(math.ceil((t1 - t0) / step_s - 1e-9)))
    t = t0 + (t1 - t0) * np.arange(n + 1) / n
    s, v, a, _ = cam.svaj(t)
    z_rel = np.asarray(s, dtype=float) - s_ref
    return integrate(
        model,
        z_rel,
        np.asarray(v, float),
        np.asarray(a, float),
        (t1 - t0) / n,
        q0,
        v0,
        out_every=n,
        predictor=predictor,
        track_energy=track_energy,
        stations=stations,
        node_flags=None if flags_at is None else flags_at(t),
    )


@dataclass(frozen=True)
class _Rows:
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tension_N: np.ndarray


def _rows_from(run, first: int, last: int | None = None) -> _Rows:
    pick = slice(first, last)
    return _Rows(run.q[pick], run.v[pick], run.a[pick], run.tension_N[pick])


def _first_row(run) -> _Rows:
    return _rows_from(run, 0, 1)


def _last_row(run) -> _Rows:
    return _rows_from(run, -1)


def _merged(pieces, rows, durations, step_s: float) -> MachineRun:
    """One MachineRun of consecutive pieces: the output rows given, the statistics over all pieces
    (the free-play fraction weighted by the pieces' durations)."""
    steps = np.asarray(durations, dtype=float)
    return MachineRun(
        *(np.concatenate([getattr(r, name) for r in rows]) for name in ("q", "v", "a", "tension_N")),
        impacts=sum(p.impacts for p in pieces),
        free_play_fraction=float(sum(p.free_play_fraction * w for p, w in zip(pieces, steps)) / steps.sum()),
        peak_tension_N=max(p.peak_tension_N for p in pieces),
        min_tension_N=min(p.min_tension_N for p in pieces),
        impact_force_spike_N=max(p.impact_force_spike_N for p in pieces),
        impact_kinetic_energy_J=sum(p.impact_kinetic_energy_J for p in pieces),
        impact_max_speed_m_s=max(p.impact_max_speed_m_s for p in pieces),
        impact_speeds_m_s=np.concatenate([p.impact_speeds_m_s for p in pieces]),
        step_s=float(step_s),
        impact_dissipated_J=sum(p.impact_dissipated_J for p in pieces),
        peak_force_in_impact_contact_N=max(p.peak_force_in_impact_contact_N for p in pieces),
        cam_work_J=sum(p.cam_work_J for p in pieces),
        dissipated_damping_J=sum(p.dissipated_damping_J for p in pieces),
        dissipated_friction_J=sum(p.dissipated_friction_J for p in pieces),
        station_peaks=merged_peaks([p.station_peaks for p in pieces]),
    )


def step_peaks(values, zdd, flags, switches, interpolate: bool = True) -> np.ndarray:
    """The station peaks (stations x PEAK_METRICS; NaN where no node counted) of the stations' motion
    at every node (values: nodes x stations x (q, q', q''), relative to the cam; zdd the cam's
    acceleration; flags IN_WINDOW | IN_DWELL per node; switches: nodes x stations, the fraction of
    the step ending at the node at which a span at the station changed contact, -1 none). The
    deviations |q| and |q'| are smooth where they peak (the chain's low modes): their largest node. The accelerations |q'' + z''| and |q''| peak on impact spikes a
    few steps wide: their largest node and, with `interpolate`, the vertex of the parabola through
    the three nodes around each node larger than both neighbours (within their bracket: at most 1/8
    of the outer two's difference above it), not across a contact change at the station, where the
    acceleration has a kink (global law: the span law's slope changes) or a jump (the Kelvin-Voigt
    dashpot's force): there the two one-sided values at the change, each extrapolated by the quadratic
    through the three nodes on its side (`_one_sided`; docs/physics.md, Station peaks)."""
    out = np.full((values.shape[1], N_PEAKS), -1.0)
    _step_peaks_into(
        values, np.asarray(zdd, dtype=float), np.asarray(flags, dtype=np.int64), switches, bool(interpolate), out
    )
    return np.where(out < 0.0, np.nan, out)


def _step_peaks_into(values, zdd, flags, switches, interpolate, out):
    """step_peaks' folding, one pass over the nodes per station and metric (out starts at -1)."""
    for s in range(values.shape[1]):
        for i in range(values.shape[0]):
            if flags[i] & IN_WINDOW:
                x, xd = abs(values[i, s, 0]), abs(values[i, s, 1])
                out[s, 1] = max(out[s, 1], x)
                out[s, 2] = max(out[s, 2], xd)
                if flags[i] & IN_DWELL:
                    out[s, 4] = max(out[s, 4], x)
        for col in (0, 3):
            best, older, last = -1.0, -1.0, -1.0
            for i in range(values.shape[0]):
                y = _abs_acceleration(values, zdd, flags, i, s, col)
                best = max(best, y)
                if interpolate and i >= 2:
                    smooth = switches[i - 1, s] < 0.0 and switches[i, s] < 0.0
                    if smooth and older >= 0.0 and y >= 0.0 and last >= older and last >= y:
                        bend = 2.0 * last - older - y
                        if bend > 0.0:
                            best = max(best, last + (y - older) * (y - older) / (8.0 * bend))
                if interpolate and i >= 1 and switches[i, s] >= 0.0:  # a change in the step to node i
                    f = switches[i, s]
                    best = max(best, _one_sided(values, zdd, flags, switches, i - 1, -1, f, s, col))
                    best = max(best, _one_sided(values, zdd, flags, switches, i, 1, 1.0 - f, s, col))
                older, last = last, y
            out[s, col] = best


def _abs_acceleration(values, zdd, flags, i, s, col):
    """|q'' + z''| (col 0) or |q''| (col 3) at node i of station s; -1 outside the window."""
    if not flags[i] & IN_WINDOW:
        return -1.0
    return abs(values[i, s, 2] + (zdd[i] if col == 0 else 0.0))


def _one_sided(values, zdd, flags, switches, j, side, x, s, col):
    """The acceleration (_abs_acceleration) at a contact change x steps beyond node j, extrapolated from
    node j and the nodes on its `side` (-1 before it, +1 after it) with no change between them: the
    quadratic through three (Newton's differences: its error is third order in the step, the linear
    one's second order, which overshoots an impact's curved flank by up to its second difference), the
    line through two where only two are there; -1 where fewer are."""
    n = values.shape[0]
    y0 = _abs_acceleration(values, zdd, flags, j, s, col)
    j1, j2 = j + side, j + 2 * side
    if y0 < 0.0 or j1 < 0 or j1 >= n or switches[max(j, j1), s] >= 0.0:
        return -1.0
    y1 = _abs_acceleration(values, zdd, flags, j1, s, col)
    if y1 < 0.0:
        return -1.0
    linear = y0 + x * (y0 - y1)
    if j2 < 0 or j2 >= n or switches[max(j1, j2), s] >= 0.0:
        return linear
    y2 = _abs_acceleration(values, zdd, flags, j2, s, col)
    if y2 < 0.0:
        return linear
    return linear + 0.5 * x * (x + 1.0) * (y0 - 2.0 * y1 + y2)


if numba is not None:  # a pass over every node of the window: in Python it cost a sixth of the step
    _abs_acceleration = numba.njit(cache=True)(_abs_acceleration)
    _one_sided = numba.njit(cache=True)(_one_sided)
    _step_peaks_into = numba.njit(cache=True)(_step_peaks_into)
    # the kernels' cache entries are stale when a file they compile in changes (clearance_verlet.py's
    # helpers, friction_tanh.py, machine_damping.py), not only this one
    kernel_cache.key_on_dependencies(globals(), __name__)


def merged_peaks(peaks):
    """The station peaks of consecutive runs (MachineRun.station_peaks): the larger, NaN where no
    run counted a node; None when none tracked them."""
    tracked = [p for p in peaks if p is not None]
    return np.fmax.reduce(tracked) if tracked else None


def step_moments(values, nodes, step_s: float, out_every: int) -> np.ndarray:
    """Per output interval (out_every steps) and station the trapezoid rule's integrals of 1, y and y^2
    over its steps (output intervals x stations x RMS_METRICS x 3), y the motion the RMS metrics
    square: values (nodes x stations x (q, q', q''), relative to the cam) plus the cam's nodes
    (z_rel, z', z''); the displacement in the run's lift frame (`shifted_moments` moves it). Each
    interval's sum runs over its steps in order (as numpy sums an axis that is not the last), and the
    integral of 1, the same for every station and metric, is summed once."""
    y = values + np.stack([np.asarray(z, dtype=float) for z in nodes], axis=1)[:, None, :]
    half = 0.5 * step_s
    intervals = (y.shape[0] - 1) // out_every
    out = np.empty((intervals, *y.shape[1:], 3))
    out[..., 0] = np.cumsum(np.full(out_every, step_s))[-1]  # h (1 + 1) / 2 per step, summed in order
    for k, power in ((1, y), (2, y * y)):
        out[..., k] = (half * (power[1:] + power[:-1])).reshape(intervals, out_every, *y.shape[1:]).sum(axis=1)
    return out


def shifted_moments(moments, lift_m: float):
    """`step_moments` with the displacement counted from `lift_m` lower (y -> y + lift_m): exact, as
    the trapezoid rule is linear in its nodes' values; None stays None."""
    if moments is None:
        return None
    out = np.array(moments, dtype=float)
    zeroth, first, second = (moments[..., 0, k] for k in range(3))
    out[..., 0, 1] = first + lift_m * zeroth
    out[..., 0, 2] = second + 2.0 * lift_m * first + lift_m * lift_m * zeroth
    return out


def station_rms(moments) -> np.ndarray:
    """The RMS over time (stations x RMS_METRICS) of summed `step_moments` (stations x RMS_METRICS x 3):
    sqrt(integral of y^2 / the window's length)."""
    m = np.asarray(moments, dtype=float)
    return np.sqrt(m[..., 2] / m[..., 0])


def next_index_start(
    model,
    cam,
    nodes,
    step_s: float,
    q0,
    v0,
    *,
    out_every: int,
    predictor: str,
    track_energy: bool = False,
    stations=None,
    flags_at=None,
    seating: bool = True,
):
    """The relabelled map x0 -> T(P(x0)): the state at the start of the next index in the next
    index's labels, with the seats changed inside the cycle (a tooth phase other than 0) or after it.
    Returns (q1, v1, the cycle's MachineRun, the seat change's Seating, None when not `seating`: a
    search's cycles need only the state); the energy terms and station peaks as index_cycle's."""
    run, inside = index_cycle(
        model,
        cam,
        nodes,
        step_s,
        q0,
        v0,
        out_every=out_every,
        predictor=predictor,
        track_energy=track_energy,
        stations=stations,
        flags_at=flags_at,
        seating=seating,
    )
    if model.machine.seat_change_lift_m is not None:  # the seats changed inside the cycle
        return run.q[-1], run.v[-1], run, inside
    q1, v1, seated = seat_change(
        model, run.q[-1], run.v[-1], float(nodes[0][-1]), (nodes[1].size - 1) * step_s, seating=seating
    )
    return q1, v1, run, seated


def relabelled_periodic_state(model, cam, step_s, n_steps, q0, v0, *, tol, max_cycles, predictor):
    """The state at the start of an index with x0 = T(P(x0)) (dynamics.solvers.machine_steady), by
    stepping cycle after cycle with the seat change between them until the start state changes by
    less than `tol` (relative to the largest |q| and |q'| over the cycle). Returns (q0, v0, cycles,
    residual, found, the last cycle's MachineRun)."""
    every = search_out_every(n_steps)
    residual = math.inf
    cycles = index_cycles(model, cam, step_s, n_steps, q0, v0, out_every=every, predictor=predictor, seating=False)
    for cycle in range(1, max_cycles + 1):
        q0, v0, run, _, residual = next(cycles)
        if residual <= tol:
            return q0, v0, cycle, residual, True, run
    return q0, v0, max_cycles, residual, False, run


def index_cycles(
    model,
    cam,
    step_s,
    n_steps,
    q0,
    v0,
    *,
    out_every: int,
    predictor: str,
    relabel=True,
    track_energy=False,
    seating=True,
):
    """Index cycle after index cycle from (q0, v0), without end: per cycle (q1, v1, its MachineRun, its
    Seating or None, its change): the next cycle's start and `cycle_change` to it. `relabel`: the
    relabelled map (next_index_start); False: the labelled frame, the cycle stepped with no seat change
    (the same links on the same seats every cycle). `track_energy`: the runs' energy terms. `seating`
    False: no Seating (None), its energies not computed (a search needs the states only)."""
    nodes = cycle_nodes(cam, step_s, n_steps)
    steps = dict(out_every=out_every, predictor=predictor, track_energy=track_energy)
    while True:
        if relabel:
            q1, v1, run, changed = next_index_start(model, cam, nodes, step_s, q0, v0, seating=seating, **steps)
        else:
            run, changed = integrate(model, *nodes, step_s, q0, v0, **steps), None
            q1, v1 = run.q[-1], run.v[-1]
        yield q1, v1, run, changed, cycle_change(run, (q0, v0), (q1, v1))
        q0, v0 = q1, v1


def cycle_scales(run) -> tuple[float, float]:
    """The largest |q| and |q'| over a cycle's `run` (at least the smallest float): the scales a cycle's
    change is measured against."""
    tiny = np.finfo(float).tiny
    return max(float(np.max(np.abs(run.q))), tiny), max(float(np.max(np.abs(run.v))), tiny)


def cycle_change(run, start, end) -> float:
    """The change from a cycle's start state to `end` (each (q, v)), relative to the largest |q| and
    |q'| over the cycle's `run` (the test relabelled_periodic_state accepts a state by)."""
    sq, sv = cycle_scales(run)
    return max(float(np.max(np.abs(end[0] - start[0]))) / sq, float(np.max(np.abs(end[1] - start[1]))) / sv)
