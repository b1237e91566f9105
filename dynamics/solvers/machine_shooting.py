"""The clearance machine's relabelled periodic steady state by Anderson-accelerated cycling (issue #24).

The steady state of continuous indexing is the state x0 at an index's start with x0 = T(P(x0))
(dynamics.solvers.machine_steady: P one index cycle of the clearance machine, T the seat change at
the dwell). Plain cycling (dynamics.solvers.machine_verlet.relabelled_periodic_state) steps
x -> T(P(x)) until the start state changes by at most `tol` per cycle; its error falls by the slowest
mode's decay per cycle, exp(-zeta omega_1 T), and on long chains omega_1 is small (the 2,000-link
machine had not settled after 11 minutes). Here the same map is iterated with Anderson acceleration
(dynamics.solvers.shooting.accelerated_fixed_point: the next start is the combination of the last
`depth` images whose residuals combine to the least-squares smallest one), which removes the slowly
decaying directions in a few cycles, whatever their decay. The acceptance test is plain cycling's:
one cycle from the accepted start changes it by at most `tol` relative to the largest |q| and |q'|
over that cycle, and the state returned is that cycle's end, so the fixed point is the same to the
tolerance. An extrapolated start the step cannot take (outside the motion seen) restarts the
history from the last cycle's end; where the extrapolation stops helping (no steady state), the
search goes on with plain cycles.
"""

from __future__ import annotations

import numpy as np

from dynamics.solvers import machine_verlet as mv
from dynamics.solvers import shooting


def relabelled_periodic_state(
    model, cam, step_s, n_steps, q0, v0, *, tol, max_cycles, predictor, depth: int = shooting.DEFAULT_DEPTH
):
    """As dynamics.solvers.machine_verlet.relabelled_periodic_state (same arguments, same return:
    (q0, v0, cycles, residual, found, the last cycle's MachineRun)), the cycling accelerated."""
    zr, zd, zdd = mv.cycle_nodes(cam, step_s, n_steps)
    every = max(n_steps // 90, 1)
    while n_steps % every:
        every -= 1
    n = np.asarray(q0).size
    last = {}
    tiny = np.finfo(float).tiny

    def one_cycle(x):
        run = mv.integrate(model, zr, zd, zdd, step_s, x[:n], x[n:], out_every=every, predictor=predictor)
        q1, v1, _ = mv.seat_change(model, run.q[-1], run.v[-1], float(zr[-1]))
        last["run"] = run
        sq, sv = max(float(np.max(np.abs(run.q))), tiny), max(float(np.max(np.abs(run.v))), tiny)
        return np.concatenate([q1, v1]), np.concatenate([np.full(n, sq), np.full(n, sv)])

    x0 = np.concatenate([np.asarray(q0, dtype=float), np.asarray(v0, dtype=float)])
    search = shooting.accelerated_fixed_point(one_cycle, x0, tol=tol, max_periods=max_cycles, depth=depth)
    end = search.state
    return end[:n].copy(), end[n:].copy(), search.periods, search.residual, search.converged, last["run"]
