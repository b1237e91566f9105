"""The seat change of the machine seated through a tooth contact stiffness (issue #22;
dynamics.models.machine, `tooth_stiffness_N_per_m`), on the compiled step's state
(dynamics.models.clearance_machine.ClearanceMachine: the DOFs, then one seat offset per seated link).

Rigid seating (dynamics.solvers.machine_steady.transfer) puts the arriving link at its seat at once:
it moves it by its span's stretch, a jump in that span's force that sends a wave down the strand.
A tooth gap takes the roller over while the wheel turns: the roller meets the flank where it is and
slides into its gap as it articulates onto the wheel. In the 1-D model:

- every link moves one place ahead (the state of place j is the link's from place j - 1, positions
  and velocities kept); the wheels keep their state;
- the arriving link's tooth spring k_t (y - u - offset) engages at zero force: its seat offset is
  where it is relative to its seat, y - u; the offset then closes at a constant rate over one index
  cycle, `engage_s` (the roller settling into its gap while the wheel turns one tooth, its
  articulation), and is 0 when the next link seats: every seated link is in its gap after that, as
  with rigid seating. The offset's motion is the tooth flank's seating work (outside the step's cam,
  damping and friction terms). An offset carried for good instead (the link staying where it seated)
  lets the chain creep round the wheels by the strand's stretch T / k per index with no steady state
  (measured: the relabelled search did not settle, the offsets grew by about T / k per index);
- the polygonal feed: a seated link's path coordinate is its pin's along-strand position less the
  feed departure d of the pin that pulls the strand (the model puts d on the wheel-end spans only), so
  the arriving link's coordinate moves by -d and the leaving link's by +d (and their speeds by the
  rate of d), d at the wheel's angle in the new frame: every span's stretch is kept (exactly where
  the wheel's angle is the nominal one; off by d's change over the lag u / R_m otherwise, as for
  rigid seating). At tooth phase 0 the seats change at the dwell, where d = 0 at the nominal angle.

Nothing is dissipated at the instant: the seating speed |y' - u'| of the arriving link is reported, its
kinetic energy relative to the seat stays in the tooth spring's motion (damped by the model's damping),
and the transfer's change of stored energy is that of the seated links' mass with the polygonal action
(m (R / R_m)^2 seated against m free, at the speeds kept), of the leaving link's tooth spring (its
deflection under the strand's tension, released) and of d's change over the lag.
"""

from __future__ import annotations

import numpy as np

from dynamics.errors import DynamicsError


def tooth_transfer(model, q: np.ndarray, v: np.ndarray, angles_after_rad, engage_s: float, zdot_m_s: float = 0.0):
    """(q, v) after the seat changes of the ClearanceMachine `model` (tooth model), per wheel the
    seating speed |y' - u'| of the arriving link and its impact energy (0: no plastic impact).
    `angles_after_rad`: per wheel (in `wheel_ends` order) its nominal angle since the dwell in the new
    frame (0 at the dwell; the angle one tooth back inside the index); `engage_s` the time to the next
    seat change (one index cycle), over which the arriving link's offset closes; `zdot_m_s` the cam's
    speed."""
    if not (engage_s is not None and engage_s > 0):
        raise DynamicsError(f"engage_s: expected the time to the next seat change (> 0 s), got {engage_s!r}")
    mach = model.machine
    n_links, n_dof = mach.n_links, model.topology.n_dof
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    q_new, v_new = q.copy(), v.copy()
    q_new[:n_links] = np.roll(q[:n_links], 1)  # place j takes the link from place j - 1
    v_new[:n_links] = np.roll(v[:n_links], 1)
    speeds, impacts = [], []
    offset = n_dof
    for (dof, seated), ends, angle in zip(model.seats, mach.wheel_ends, angles_after_rad):
        w, wheel = len(seated), ends.wheel
        u, ud = (0.0, 0.0) if dof is None else (float(q[dof]), float(v[dof]))
        d, d_rate = 0.0, 0.0
        if mach.polygonal:
            a = float(angle) + u / wheel.feed_radius_m
            d = float(wheel.feed_departure_m(a))
            d_rate = float(wheel.feed_departure_slope(a)) / wheel.feed_radius_m * (zdot_m_s + ud)
        first, leaving = seated[0], seated[-1] + 1  # the places of the arriving and the leaving link, after
        q_new[first] -= d
        v_new[first] -= d_rate
        q_new[leaving % n_links] += d
        v_new[leaving % n_links] += d_rate
        q_new[offset : offset + w] = 0.0  # the last arriving link's offset has closed (to round-off)
        v_new[offset : offset + w] = 0.0
        q_new[offset] = q_new[first] - u
        v_new[offset] = -q_new[offset] / engage_s
        speeds.append(float(abs(v_new[first] - ud)))
        impacts.append(0.0)
        offset += w
    return q_new, v_new, tuple(speeds), tuple(impacts)
