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

A long chain's default run searches at a coarse step and settles at the default safety (above rho 0.92
at the window's step, dynamics.machine_scene._settle_substeps), whose fixed point differs from the
coarse one along the slow modes. defect_corrected_periodic_state finds the fine step's (here: the
default safety's) fixed point with coarse cycles (dynamics.solvers.shooting.defect_corrected_fixed_point):
one cycle at the default safety gives the two steps' difference d at the current start, the coarse map
plus d is searched with the coarse search's Anderson history (its secant pairs are the coarse map's),
and a cycle at the default safety accepts the result by the same test; d is renewed there until it
does. The coarse search stops short of its own fixed point (DEFECT_COARSE_TOL_FACTOR times the
tolerance), which the default safety never sees: the corrected search carries its history on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from dynamics.solvers import cache, shooting
from dynamics.solvers import machine_verlet as mv
from dynamics.solvers.machine_modes import lowest_frequency_Hz

# The Newton step is left out on the modes the linear machine keeps more than this fraction of per
# index cycle (plain cycling and Anderson take them): there its step multiplies a residual by up to
# 1 / (1 - decay), 45 for the slowest mode at 10,000 links (0.978), more than the machine's own map
# (friction, the polygonal feed) keeps of them, evidently: measured at 10,000 links on the
# linear machine's search from rest: with every slow mode the residual went 1.0, 0.035, 1.8, 0.6,
# 1.0, ... (no steady state); without those above 0.9 it falls (1.0, 0.50, 0.26, 0.19, 0.08, 0.04).
# No mode is above it up to about 2,100 links (the slowest keeps 0.893 at 2,000, 0.902 at 2,200).
NEWTON_DECAY_CAP = 0.9
# The cap holds only where the slowest mode keeps more than this of itself per cycle: up to it the
# step takes every slow mode. With the slowest mode just above the cap the linear machine's search
# hardly settled (2,500 links: its change per cycle 0.2-1.7 over the first 20 cycles, 2e-2 after
# 60; the same with Anderson's history 16). Measured on the default wheels and link, 180 rpm, from
# rest to 1e-3 at SEARCH_SAFETY, cycles with the cap / with every slow mode: 2,200 links (slowest
# 0.901) 60, NOT found / 3; 2,500 (0.912) 60, NOT found / 3; 3,000 (0.926) 56 / 4; 4,000 (about
# 0.946) 48 / 5; but 5,000 (0.956) 16 / 10, 6,000 (about 0.964) 15 / 56, 7,500 15 / 60, NOT found,
# 10,000 (0.977) 21 / 50: 0.95 keeps the cap from about 4,500 links on, today's search there.
NEWTON_EVERY_SLOW_MODE_UP_TO_DECAY = 0.95
# With free play the Newton step (built on the closed machine's modes) helps the search up to
# NEWTON_FREE_PLAY_LINKS links and misleads it above: the slack spans and the guide's friction in
# the dwell change the slow directions, more of the chain the longer it is. Measured on the default
# wheels, 0.094 mm, 180 rpm, from the linear machine's state, to 1e-4, cycles with the step / with
# Anderson alone: 10 / 11 at 1,000 links, 14 / 20 at 2,000; at 5,000 the search with the step
# stalled near 5e-3 per cycle (61 cycles, no steady state; plain cycling there: the slowest mode
# keeps about 0.96 of itself per cycle against the closed machine's 0.83) where Anderson alone found it
# in 31 cycles (depth 8); at 10,000 near 1e-2 against 1e-4 in 59. Between 2,000 and 5,000 not measured. The
# linear machine (free play 0) always takes the step.
NEWTON_FREE_PLAY_LINKS = 2000
# Anderson alone keeps this many cycles (the step's search: shooting.DEFAULT_DEPTH): measured there
# (the benchmark's chain, from the linear machine's state, to 1e-4), 26 cycles at 5,000 links and 39
# at 10,000 against 31 and 59 with 8. It needs up to FREE_PLAY_STALL cycles without halving its best
# residual before it gives the extrapolation up: its residual rose for the first 9 cycles at 10,000
# links while the history filled and later took up to 17 (depth 8) and 11 (depth 16) to halve.
FREE_PLAY_DEPTH = 16
FREE_PLAY_STALL = 24
# defect_corrected_periodic_state's coarse search stops at this multiple of the settle's tolerance:
# its own fixed point is not the one the window needs, and the defect correction's first corrected
# search carries the same Anderson history on to the default safety's, so the coarse search's last
# cycles were partly stepped twice. Stopped well below the two steps' offset (the fine cycle's change
# at the coarse fixed point: 5.7e-3 at 5,000 and 10,000 links), the first renewal starts about as far
# from the fine fixed point as before. Measured on the default wheels, 0.094 mm, 180 rpm, from the
# same linear state in one process (coarse search + corrected coarse + default-safety cycles; station
# metrics against factor 1): 10,000 links (tol 1.0e-4) 1: 38 + 21 + 4, 10: 33 + 19 + 3 (1.3e-4);
# 5,000 links (tol 2.0e-4) 1: 24 + 12 + 3, 10: 17 + 15 + 3, 30: 15 + 17 + 4 (each from the default
# safety's fixed point searched to 1e-7: 4.5e-4, 1.5e-4, 1.2e-3); 10,000 links at 20: 19 + 32 + 4
# (what the coarse search leaves, the corrected search takes).
DEFECT_COARSE_TOL_FACTOR = 10.0


def relabelled_periodic_state(
    model,
    cam,
    step_s,
    n_steps,
    q0,
    v0,
    *,
    tol,
    max_cycles,
    predictor,
    depth: int | None = None,
    on_cycle=None,
    on_period=None,
):
    """As dynamics.solvers.machine_verlet.relabelled_periodic_state (same arguments, same return:
    (q0, v0, cycles, residual, found, the last cycle's MachineRun)), the cycling accelerated.
    `depth`: Anderson's history (0: plain cycling); None: shooting.DEFAULT_DEPTH with the slow-mode
    Newton step, FREE_PLAY_DEPTH where the search goes without it (above NEWTON_FREE_PLAY_LINKS).
    `on_cycle(residual, end, run)`: called after every index cycle stepped with its change per cycle
    (the acceptance test's measure), its end state (q, q') after the seat change and its MachineRun,
    for measuring a search (benchmarks/bench_long_search.py); it does not change the search.
    `on_period(residual)`: shooting.accelerated_fixed_point's (a progress line)."""
    n = np.asarray(q0).size
    last = {}
    one_cycle = _cycle_map(model, cam, step_s, n_steps, n, predictor, last, on_cycle)
    x0 = np.concatenate([np.asarray(q0, dtype=float), np.asarray(v0, dtype=float)])
    search = shooting.accelerated_fixed_point(
        one_cycle, x0, tol=tol, max_periods=max_cycles, on_period=on_period, **_search_options(model, cam, depth)
    )
    end = search.state
    return end[:n].copy(), end[n:].copy(), search.periods, search.residual, search.converged, last["run"]


def defect_corrected_periodic_state(
    model, cam, coarse, fine, q0, v0, *, tol, max_cycles, predictor, on_cycle=None, on_period=None
) -> DefectCorrectedState:
    """The relabelled steady state at the fine step searched mostly at the coarse one: the accelerated
    search (relabelled_periodic_state's) at `coarse` (step_s, steps per index cycle) from (q0, v0) to
    DEFECT_COARSE_TOL_FACTOR `tol`, then, where it is found, the fixed point at `fine` by defect
    correction with coarse cycles
    (shooting.defect_corrected_fixed_point: the coarse search's history carried on), accepted by the
    fine step's test to the same `tol`. `max_cycles` bounds the coarse search's cycles and, apart,
    the settle's (coarse and fine together), as a settle's cycles are apart from the search's
    budget elsewhere (dynamics.machine_scene): at 10,000 links the coarse search takes 39 of the
    default 60 and the settle about 23. `on_cycle(residual,
    end, run, step_s)`: as relabelled_periodic_state's, with the cycle's step; `on_period(residual)`:
    after every cycle, with the residual its search accepts by (shooting.defect_corrected_fixed_point's:
    the corrected map's for the settle's coarse cycles)."""
    n = np.asarray(q0).size
    last = {}

    def cycle_map(step):
        observe = None if on_cycle is None else (lambda r, end, run: on_cycle(r, end, run, step[0]))
        return _cycle_map(model, cam, *step, n, predictor, last, observe)

    options = _search_options(model, cam, None)
    coarse_cycle = cycle_map(coarse)
    x0 = np.concatenate([np.asarray(q0, dtype=float), np.asarray(v0, dtype=float)])
    coarse_tol = DEFECT_COARSE_TOL_FACTOR * tol
    found = shooting.accelerated_fixed_point(
        coarse_cycle, x0, tol=coarse_tol, max_periods=max_cycles, on_period=on_period, **options
    )
    if not found.converged:
        return DefectCorrectedState(found.state[:n].copy(), found.state[n:].copy(), found, None, last["run"])
    settled = shooting.defect_corrected_fixed_point(
        coarse_cycle, cycle_map(fine), found, tol=tol, max_periods=max_cycles, on_period=on_period, **options
    )
    end = settled.search.state
    return DefectCorrectedState(end[:n].copy(), end[n:].copy(), found, settled, last["run"])


@dataclass(frozen=True)
class DefectCorrectedState:
    """defect_corrected_periodic_state's result: the start state (q, q') (the fine step's fixed point
    where `settled` converged; the coarse search's end where it did not), the coarse search, the
    defect-corrected search from it (None where the coarse search found no steady state) and the
    last cycle's MachineRun."""

    q0: np.ndarray
    v0: np.ndarray
    coarse: shooting.FixedPointSearch
    settled: shooting.DefectCorrectedSearch | None
    last_run: object

    @property
    def found(self) -> bool:
        return self.settled is not None and self.settled.search.converged

    @property
    def cycles(self) -> int:
        return self.coarse.periods + (0 if self.settled is None else self.settled.search.periods)

    @property
    def residual(self) -> float:
        return (self.coarse if self.settled is None else self.settled.search).residual


def _cycle_map(model, cam, step_s, n_steps, n, predictor, last, on_cycle):
    """x = (q, q') -> (its index cycle's end after the seat change, the acceptance test's scale: the
    cycle's largest |q| and |q'|), the cycle's MachineRun kept in last["run"]."""
    zr, zd, zdd = mv.cycle_nodes(cam, step_s, n_steps)
    every = shooting.search_out_every(n_steps)

    def one_cycle(x):
        q1, v1, run, _ = mv.next_index_start(
            model, cam, (zr, zd, zdd), step_s, x[:n], x[n:], out_every=every, predictor=predictor, seating=False
        )
        last["run"] = run
        sq, sv = mv.cycle_scales(run)
        image, scale = np.concatenate([q1, v1]), np.concatenate([np.full(n, sq), np.full(n, sv)])
        if on_cycle is not None:
            on_cycle(float(np.max(np.abs(image - x) / scale)), (q1, v1), run)
        return image, scale

    return one_cycle


def _search_options(model, cam, depth: int | None) -> dict:
    """The accelerated search's depth, stall and preconditioner (relabelled_periodic_state's `depth`)."""
    newton = depth != 0 and (model.clearance_m == 0.0 or model.n_links <= NEWTON_FREE_PLAY_LINKS)
    precondition = _cached_slow_mode_newton(model, cam.cycle_s) if newton else None
    stall = shooting.DEFAULT_STALL if newton else FREE_PLAY_STALL
    if depth is None:
        depth = shooting.DEFAULT_DEPTH if newton else FREE_PLAY_DEPTH
    return {"depth": depth, "stall": stall, "precondition": precondition}


def slowest_decay_per_cycle(model, period_s: float) -> float:
    """exp(-zeta omega_1 T): the fraction of itself the machine's slowest mode keeps over one index
    cycle (omega_1 the lowest natural frequency of (K, M), the polygon-free machine at rest, the
    carriage in; zeta its damping ratio under the model's law), cached. The searches' error bound
    (dynamics.machine_scene.long_search_tol): a map contracting by this factor per cycle is within
    residual / (1 - decay) of its fixed point. O(N) above DENSE_LINK_LIMIT links
    (MachineOnWheels.lowest_natural_frequencies_Hz: shift-invert Lanczos on the sparse K and M); omega_1
    is the summary's lowest mode's, of the one solve (dynamics.solvers.machine_modes)."""
    return cache.cached(
        ("machine slowest decay", model.machine, model.span_damping, model.beta_s, period_s),
        lambda: _slowest_decay(model, period_s),
    )


def _slowest_decay(model, period_s: float) -> float:
    omega = 2.0 * np.pi * lowest_frequency_Hz(model.machine)
    return float(np.exp(-model.damping_ratio_at(omega) * omega * period_s))


def _cached_slow_mode_newton(model, period_s: float):
    return cache.cached(
        ("machine slow-mode newton", model.machine, model.span_damping, model.beta_s, period_s),
        lambda: slow_mode_newton(model, period_s, shooting.SLOW_DECAY),
    )


def slow_mode_newton(model, period_s: float, decay: float):
    """r -> the Newton step (I - Phi)^-1 r of the machine's linear one-cycle map on its slowly decaying
    modes (per cycle decay exp(-zeta omega T) above `decay`), r itself on the others: the machine's
    counterpart of dynamics.solvers.shooting.slow_mode_newton, with a diagonal, non-uniform M.

    The modes are those of (K, M) (the polygon-free machine at rest, the carriage in): of
    M^(-1/2) K M^(-1/2) by dynamics.solvers.shooting.slow_modes (a dense eigensolve up to
    DENSE_EIGENSOLVE_UP_TO DOFs). The
    seat change shifts every free link one place, which leaves these long-wave shapes nearly as they
    are (measured at 400 links: the relabelled map's slowest multipliers are the fixed frame's, 0.572),
    so the step removes the linear part of the slow directions and Anderson the rest. O(N m) per step
    (m the slow modes), no N x N array."""
    from scipy.linalg import expm

    from dynamics.solvers._common import serial_blas

    topo = model.topology
    n = topo.n_dof
    masses = np.asarray(topo.masses_kg, dtype=float)
    r = 1.0 / np.sqrt(masses)
    x = (sp.diags(r) @ topo.stiffness_matrix_sparse() @ sp.diags(r)).tocsc()

    def is_slow(omega):
        return np.exp(-np.array([model.damping_ratio_at(o) * o for o in omega]) * period_s) > decay

    if n <= shooting.DENSE_EIGENSOLVE_UP_TO:
        lam, vec = np.linalg.eigh(x.toarray())
        omega = np.sqrt(np.maximum(lam, 0.0))
        slow = is_slow(omega)
    else:
        omega, vec = shooting.slow_modes(x, is_slow)
        slow = np.ones(omega.size, dtype=bool)
    decay_per_cycle = np.exp(-np.array([model.damping_ratio_at(o) * o for o in omega]) * period_s)
    slowest = float(decay_per_cycle[slow].max()) if slow.any() else 0.0
    if slowest > NEWTON_EVERY_SLOW_MODE_UP_TO_DECAY:
        slow &= decay_per_cycle <= NEWTON_DECAY_CAP
    omega, vec = omega[slow], vec[:, slow]
    to_modes = np.ascontiguousarray((vec / r[:, None]).T)  # a = V^T M^(1/2) q
    from_modes = np.ascontiguousarray(vec * r[:, None])  # q = M^(-1/2) V a
    blocks = np.empty((omega.size, 2, 2))
    oscillators = np.zeros((omega.size, 2, 2))
    oscillators[:, 0, 1] = 1.0
    oscillators[:, 1, 0] = -(omega**2)
    oscillators[:, 1, 1] = -2.0 * np.array([model.damping_ratio_at(o) for o in omega]) * omega
    # one batched exponential, one BLAS thread: per-mode calls on a threaded BLAS took 0.3 s at
    # 1,000 links on a busy machine (0.06 s of CPU)
    with serial_blas():
        one_cycle = expm(oscillators * period_s) if omega.size else oscillators
    for j in range(omega.size):
        one_minus = np.eye(2) - one_cycle[j]
        # an undamped mode whose period divides T has no Newton step (I - Phi singular): plain there
        blocks[j] = np.linalg.inv(one_minus) if np.linalg.cond(one_minus) < 1e8 else np.eye(2)

    def newton_step(res: np.ndarray) -> np.ndarray:
        # res is (q, q') of the compiled step's state: the DOFs, then a tooth model's seat offsets
        # (ClearanceMachine.n_state), which the modes leave to Anderson
        half = res.size // 2
        q = np.stack([to_modes @ res[:n], to_modes @ res[half : half + n]], axis=1)  # (m, 2)
        dq = np.einsum("jab,jb->ja", blocks, q) - q
        out = res.copy()
        out[:n] += from_modes @ dq[:, 0]
        out[half : half + n] += from_modes @ dq[:, 1]
        return out

    return newton_step
