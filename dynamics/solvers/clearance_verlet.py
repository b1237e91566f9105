"""Fast integrator of the clearance chain: explicit velocity Verlet at a step set by the contact frequency.

One step h (state y, w = y', and the acceleration a carried from the previous step):

    w_half = w + h/2 a;   y <- y + h w_half;   w_pred = w + h a
    a      <- a(t + h, y, w_pred);             w <- w_half + h/2 a

The positions are the classical velocity Verlet's (symplectic for the elastic forces); the
velocity-dependent forces (damping, friction) are evaluated at the predicted velocity w_pred, which
is off by O(h^2), so the scheme stays second order with one force evaluation per step. The span law
is continuous and piecewise linear in e (a kink at each contact change, no jump), so every contact
change is resolved by the step itself without event location, at second order: the kink costs an
O(h^2) local velocity error at each of the O(1) changes per unit time. The Kelvin-Voigt law's
dashpot force does jump at a contact change: that jump is located within the step (`_switch_impulse`,
an impulse correction at the span law's crossing fraction), else it costs O(h) per impact. The predicted velocity may
instead be the Adams-Bashforth extrapolation w + h (3/2 a - 1/2 a_prev) (`predictor="ab2"`, global
law only, see PREDICTORS): still one force evaluation per step, still second order, smaller error.
Why not the exact linear propagator between switching events: with 85 spans each in one of three
states, every switch changes the system matrix, and a new (2N)^2 exponential per switch costs more
than thousands of explicit steps.

Stability: the step's amplification for one damped mode (omega, zeta) is `spectral_radius`; the
largest stable omega h, `stable_omega_h(zeta)`, is 2 for zeta = 0 and falls with zeta. The step is
a fraction `safety` of that limit at the highest full-contact frequency (free play only softens the
chain), and divides the output interval evenly.

Speed: with numba installed the step loop runs compiled (`_run_loops`: loops over preallocated
arrays, no temporaries, its helpers inlined); without numba the vectorised numpy form (`_run`, the
same steps and outputs, tested equal) runs, about 50x slower (benchmarks/bench_clearance.py; docs/performance.md,
"Clearance chain"). What makes the compiled step fast: the global law's product C w, otherwise
half of a step, is taken in the two blocks of the chain's mirror symmetry (`reflection_blocks`: 4224
padded multiply-adds instead of 7225, four rows per pass over w, the blocks computed once per chain);
the helpers are inlined into the loop under FASTMATH; the span law, the friction law's saturated
branch and the contact statistics are written without branches, so that they vectorise; tanh is
computed in arithmetic (`_tanh_branch_free`, dynamics.solvers.friction_tanh, the machine's too), over
every link in one vectorised pass, and only when some link is off saturation (`TANH_IS_ONE`); the
steps leave out the powers, which only output steps need. Above DENSE_LINK_LIMIT links (or when the model
asks for it) the global law's product is the O(N) form of dynamics.models.reduced_damping (`_sqrt_product`:
one cyclic tridiagonal solve per quadrature node, the nodes as the vectorised inner loop).

Impacts (`_impacts_loop`, `_impacts_array`): the closing speed, force spike, approach energy and
contact dissipation of each impact, taken at the contact threshold's crossing within the step
(dynamics.scene.ImpactStatistics defines them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dynamics.errors import DynamicsError, SolverDivergedError
from dynamics.solvers import cache, kernel_cache
from dynamics.solvers.friction_tanh import TANH_IS_ONE
from dynamics.solvers.friction_tanh import tanh_branch_free as _tanh_branch_free

try:  # optional: the compiled loop (README, "Dependencies and why")
    import numba
except ImportError:  # pragma: no cover - exercised where numba is absent
    numba = None

# The euler predictor's step is this fraction of its stability limit: chosen for accuracy, not
# stability. On the default scene (85 links, 180 rpm, periodic steady state) it gives 9 steps per
# output sample at 4 samples per degree and station metrics within 2.7e-2 of the converged answer
# (worst of the 20; benchmarks/bench_accuracy.py). The Kelvin-Voigt law's default.
DEFAULT_SAFETY = 0.25
# stats: impacts, free-play span-steps, recorded span-steps, peak T, min T, peak |T| in a contact begun by
# an impact, diverged at step, impact force spike, impact kinetic energy, energy the impact contacts'
# dashpots dissipated, largest closing speed, closing speeds stored (`_impacts_loop`);
# energy: cam work, damping dissipation (tensioner's included), friction dissipation
N_STATS = 12
N_ENERGY = 3
# The closing speeds of at most this many impacts are kept for their distribution (the default scene
# has a few hundred per window); beyond it the count, the largest speed and the sums stay exact.
SPEED_CAPACITY = 1 << 16
# Velocity predictors for the velocity-dependent forces, w_pred = w + h (a + theta (a - a_prev)):
# "euler" (theta 0: w + h a, off by O(h^2)), the default; "ab2" (theta 1/2, Adams-Bashforth 2: off
# by O(h^3) where a is smooth), which cuts the global damping law's error 2-5x at the same step
# (docs/performance.md, "Clearance chain") at a lower stability limit (`stable_omega_h`). Not for the
# Kelvin-Voigt law: its dashpot force jumps at each impact, and there "ab2" loses the clean second
# order (measured on the case of tests/test_clearance_fast_vs_reference.py: orders 1.2 and 1.5).
PREDICTORS = {"euler": 0.0, "ab2": 0.5}
# The default run of the global law (issue 24): "ab2" at 0.31 of its own (lower) stability limit: the
# same steps per output sample as euler at 0.25 on the default scene's two materials (9 aluminium, 10
# titanium; 0.30 gives titanium 11), so the same cost, and the 32 station metrics within 1.5e-3 of the
# converged answer on the default scene (benchmarks/bench_accuracy.py; its error is not monotone in the
# step below about 20 steps per sample). The Kelvin-Voigt law keeps euler. Tighter: dynamics.scene's
# step control (simulate_chain(accuracy=)).
DEFAULT_PREDICTOR = "ab2"
DEFAULT_SAFETIES = {
    ("global", "euler"): DEFAULT_SAFETY,
    ("global", "ab2"): 0.31,
    ("kelvin-voigt", "euler"): DEFAULT_SAFETY,
}
# Rows of a damping block are padded to a multiple of 4 (`_rows_times` takes four at a time) and its
# columns to a multiple of 16 (whole vector iterations of the inner loop: no scalar remainder).
ROW_MULTIPLE, COLUMN_MULTIPLE = 4, 16
# C counts as symmetric under the loop's reflection when it is to this fraction of its largest entry.
REFLECTION_TOL = 1e-12
# numba fast-math flags of the compiled step: reassociation (so that the damping product's sums
# vectorise), FMA contraction, division by reciprocal, signed zeros ignored. Not "nnan" or "ninf": the
# pull-only chain's k g is inf, and the divergence check must see NaN.
FASTMATH = {"reassoc", "contract", "arcp", "nsz"}


def _accel(y, w, u, ud, zd, zdd, par, ipar, cmat):
    """Accelerations, span forces and contact of one state; also the cam force and the powers."""
    m, k, kd, preload, kg, beta, fc, inv_vs, mt, kt, ct, f0 = (
        par[0],
        par[1],
        par[2],
        par[3],
        par[4],
        par[5],
        par[6],
        par[7],
        par[8],
        par[9],
        par[10],
        par[11],
    )
    s, tens, kv = ipar[0], ipar[1], ipar[2]
    n = y.shape[0]
    p_damp = 0.0
    f_cam = 0.0
    e = np.empty(n)
    ed = np.empty(n)
    e[: n - 1] = y[1:] - y[: n - 1]
    e[n - 1] = y[0] - y[n - 1]
    ed[: n - 1] = w[1:] - w[: n - 1]
    ed[n - 1] = w[0] - w[n - 1]
    if tens:
        e[s] += 2.0 * u
        ed[s] += 2.0 * ud
    d = preload + k * e
    pull = d >= 0.0
    push = d <= -kg
    contact = pull | push
    t_el = np.where(pull, d, np.where(push, d + kg, 0.0))
    # the span forces' net on each link first (neighbouring preloads cancel exactly), then the damping
    # and drive forces as `cw` (subtracted): added to preload-sized terms they would lose their low bits
    f = np.empty(n)
    f[1:] = t_el[1:] - t_el[: n - 1]
    f[0] = t_el[0] - t_el[n - 1]
    if kv:
        dash = np.where(contact, beta * k * ed, 0.0)
        t_all = t_el + dash
        cw = np.empty(n)
        cw[1:] = dash[: n - 1] - dash[1:]
        cw[0] = beta * kd * w[0] - dash[0] + dash[n - 1]
        p_damp = np.sum(dash * ed) + beta * kd * w[0] * w[0]
        f_cam = -kd * y[0] - beta * kd * w[0]
    else:
        t_all = t_el
        cw = cmat @ w  # a dense C or a dynamics.models.reduced_damping.ReducedDamping
        p_damp = np.dot(w, cw)
        f_cam = -kd * y[0] - np.sum(cw)
    cw[0] += kd * y[0]
    f -= cw
    fr = -fc * _tanh_array((zd + w) * inv_vs)
    f += fr
    p_fric = -np.sum(fr * (zd + w))
    a = f / m - zdd
    au = 0.0
    if tens:
        au = (f0 - kt * u - ct * ud - 2.0 * t_all[s]) / mt
        p_damp += ct * ud * ud
    return a, au, t_el, contact, f_cam * zd, p_damp, p_fric


def _tanh_array(x):
    """tanh, element-wise, from numpy's exp: the compiled path's `_tanh_branch_free` to 2.3e-16 (both
    are within that of the library's tanh, tested), exactly +-1 where it is too."""
    q = np.exp(-2.0 * np.abs(x))
    return np.copysign((1.0 - q) / (1.0 + q), x)


def _run(
    y,
    w,
    u,
    ud,
    zd,
    zdd,
    h,
    theta,
    out_every,
    record_from,
    par,
    ipar,
    cmat,
    track_energy,
    out_y,
    out_w,
    out_a,
    out_u,
    out_ud,
    stats,
    energy,
    speeds,
):
    """Steps over the nodes of zd/zdd (len n_steps + 1); writes outputs every `out_every` steps
    (out_* have n_steps // out_every + 1 rows), statistics from step `record_from` on, the closing
    speeds of the recorded impacts into `speeds` (`_impacts_array`)."""
    n_steps = zd.shape[0] - 1
    clocks = np.zeros((2, y.shape[0]))  # per span: time since its impact, dashpot power at the last step
    bound = par[12]
    a, au, t_el, contact, pc, pd, pf = _accel(y, w, u, ud, zd[0], zdd[0], par, ipar, cmat)
    a_prev, au_prev = a, au  # the first step's predictor is w + h a whatever theta
    wp_prev, up_prev = w, ud  # the velocities the last dashpot forces were taken at
    powers = np.array([pc, pd, pf])
    free = ~contact
    phase = np.zeros(y.shape[0], dtype=np.bool_)
    row = _keep(
        -1, h, 0, y, w, a, u, ud, powers, powers, False, True, out_y, out_w, out_a, out_u, out_ud, energy, stats, np.inf
    )
    if record_from == 0:
        _record(t_el, contact, phase, stats, False, free)
    for i in range(n_steps):
        wh = w + 0.5 * h * a
        uh = ud + 0.5 * h * au
        y = y + h * wh
        u = u + h * uh
        wp = w + h * (a + theta * (a - a_prev))
        up = ud + h * (au + theta * (au - au_prev))
        a_prev, au_prev = a, au
        a, au, t_el, contact, pc2, pd2, pf2 = _accel(y, wp, u, up, zd[i + 1], zdd[i + 1], par, ipar, cmat)
        w = wh + 0.5 * h * a
        ud = uh + 0.5 * h * au
        if ipar[2]:
            before = _kinetic_J(w, ud, par, ipar)
            w, ud = _dashpot_switch_array(
                h, y - h * wh, y, u - h * uh, u, wp_prev, wp, up_prev, up, ~free, par, ipar, w, ud
            )
            wp_prev, up_prev = wp, up
            if track_energy:  # the impulses' work, dissipated by the dashpots
                energy[1] += before - _kinetic_J(w, ud, par, ipar)
        on_output = (i + 1) % out_every == 0
        if track_energy or on_output:
            a_out, au_out, t_el, contact, pc2, pd2, pf2 = _accel(y, w, u, ud, zd[i + 1], zdd[i + 1], par, ipar, cmat)
            row = _keep(
                i,
                h,
                row,
                y,
                w,
                a_out,
                u,
                ud,
                np.array([pc2, pd2, pf2]),
                powers,
                track_energy,
                on_output,
                out_y,
                out_w,
                out_a,
                out_u,
                out_ud,
                energy,
                stats,
                bound,
            )
            if row < 0:
                return
        _impacts_array(
            h,
            y,
            w,
            a,
            y - h * wh,
            wh - 0.5 * h * a_prev,
            a_prev,
            u,
            ud,
            au,
            u - h * uh,
            uh - 0.5 * h * au_prev,
            au_prev,
            par,
            ipar,
            t_el,
            contact,
            free,
            phase,
            clocks,
            stats,
            speeds,
            i + 1 >= record_from,
        )
        new_impacts = contact & free
        phase = (phase | new_impacts) & contact
        free = ~contact
        if i + 1 >= record_from:
            _record(t_el, contact, phase, stats, True, new_impacts)


def _keep(
    i,
    h,
    row,
    y,
    w,
    a_out,
    u,
    ud,
    p_new,
    powers,
    track_energy,
    on_output,
    out_y,
    out_w,
    out_a,
    out_u,
    out_ud,
    energy,
    stats,
    bound,
):
    """After step i: add the step's energy terms (trapezoidal in the powers) and store an output row.
    Returns the next row, or -1 when |y| passed `bound` (divergence; the step is noted in stats)."""
    if track_energy:
        for q in range(3):
            energy[q] += 0.5 * h * (powers[q] + p_new[q])
            powers[q] = p_new[q]
    if on_output:
        out_y[row] = y
        out_w[row] = w
        out_a[row] = a_out
        out_u[row] = u
        out_ud[row] = ud
        row += 1
        if not (np.max(np.abs(y)) < bound):
            stats[6] = i + 1
            return -1
    return row


def _record(t_el, contact, phase, stats, count_impacts, new_impacts):
    if count_impacts:
        stats[0] += np.sum(new_impacts)
    stats[1] += t_el.shape[0] - np.sum(contact)
    stats[2] += t_el.shape[0]
    stats[3] = max(stats[3], np.max(t_el))
    stats[4] = min(stats[4], np.min(t_el))
    if np.any(phase):
        stats[5] = max(stats[5], np.max(np.abs(t_el[phase])))


def _rows_times(mat, x, out):
    """out = mat x, four rows at a time (rows a multiple of 4, `_padded`): each load of x serves
    four rows, and the compiler vectorises the inner loop (FASTMATH: the sums may be reassociated).
    Summed in mat's own precision: the machine's step (dynamics.solvers.machine_verlet) also passes
    a float32 C (`DAMPING_PRODUCT_PRECISIONS`: half the cache, twice the lanes)."""
    zero = mat[0, 0] - mat[0, 0]
    for i in range(0, mat.shape[0], 4):
        s0 = zero
        s1 = zero
        s2 = zero
        s3 = zero
        for j in range(mat.shape[1]):
            xj = x[j]
            s0 += mat[i, j] * xj
            s1 += mat[i + 1, j] * xj
            s2 += mat[i + 2, j] * xj
            s3 += mat[i + 3, j] * xj
        out[i] = s0
        out[i + 1] = s1
        out[i + 2] = s2
        out[i + 3] = s3


def _mirror_product(sym, anti, n, w, ws, wa, cs, ca, out):
    """out[:n] = C w[:n] with C as `reflection_blocks` gives it, the one form of the product both
    compiled steps take (this module's and dynamics.solvers.machine_verlet's, where w is the
    machine's velocities, the links first, and the blocks are row slices of its packed C): w split
    into its symmetric and antisymmetric parts under the reflection (link 0, and link n/2 for even n,
    map onto themselves; link p pairs with link n - p), each multiplied by its block; a C without
    the symmetry (no antisymmetric rows) is multiplied whole. ws, wa: the blocks' padded columns
    (wa's padding left 0), cs, ca: their rows."""
    if anti.shape[0] == 0:
        for j in range(n):
            ws[j] = w[j]
        _rows_times(sym, ws, cs)
        for j in range(n):
            out[j] = cs[j]
        return
    pairs = (n - 1) // 2
    nf = n - 2 * pairs
    r = math.sqrt(0.5)
    ws[0] = w[0]
    if nf == 2:
        ws[1] = w[pairs + 1]
    for p in range(pairs):
        ws[nf + p] = r * (w[1 + p] + w[n - 1 - p])
        wa[p] = r * (w[1 + p] - w[n - 1 - p])
    _rows_times(sym, ws, cs)
    _rows_times(anti, wa, ca)
    out[0] = cs[0]
    if nf == 2:
        out[pairs + 1] = cs[1]
    for p in range(pairs):
        out[1 + p] = r * (cs[nf + p] + ca[p])
        out[n - 1 - p] = r * (cs[nf + p] - ca[p])


def _sqrt_product(coefficients, weights, factors, sm, acc, y, w, out):
    """out = C w for the reduced global law (dynamics.models.reduced_damping): a0 m w + a1 K w + 2 zeta K acc,
    acc = sum_j c_j (K / m + tau_j I)^-1 w by one cyclic tridiagonal solve per node (Thomas, then
    Sherman-Morrison with the node's z), all nodes at once: `factors` is (3, N, p), so the recurrences
    run over the links with the nodes as the (vectorised) inner loop. y: (N + 1, p) scratch, its last
    row the backward recurrence's running value. The backward pass takes the forward coefficient as
    e times the pivot's inverse (what factors[1] holds, to the bit) and sums the weighted solutions as
    it goes, so a product reads two (N, p) arrays and y twice instead of three arrays and y four times.
    coefficients = [a0 m, a1 k, a1 k_d, 2 zeta k, 2 zeta k_d, -k / m]."""
    n = w.shape[0]
    p = weights.shape[0]
    e = coefficients[5]
    run = y[n]
    for j in range(p):
        y[0, j] = w[0] * factors[0, 0, j]
    for i in range(1, n):
        wi = w[i]
        for j in range(p):
            y[i, j] = (wi - e * y[i - 1, j]) * factors[0, i, j]
    s = 0.0
    for j in range(p):
        run[j] = y[n - 1, j]
        s += weights[j] * run[j]
    acc[n - 1] = s
    for i in range(n - 2, -1, -1):
        s = 0.0
        for j in range(p):
            v = y[i, j] - e * factors[0, i, j] * run[j]
            run[j] = v
            s += weights[j] * v
        acc[i] = s
    for j in range(p):  # Sherman-Morrison's factor per node, weighted (run holds the solutions' row 0)
        sm[j, 2] = weights[j] * sm[j, 0] * (run[j] + sm[j, 1] * y[n - 1, j])
    for i in range(n):
        s = 0.0
        for j in range(p):
            s += sm[j, 2] * factors[2, i, j]
        acc[i] -= s
    c0, c1, c3 = coefficients[0], coefficients[1], coefficients[3]
    for i in range(n):
        ip = i - 1 if i > 0 else n - 1
        inx = i + 1 if i + 1 < n else 0
        out[i] = c0 * w[i] + c1 * (2.0 * w[i] - w[ip] - w[inx]) + c3 * (2.0 * acc[i] - acc[ip] - acc[inx])
    out[0] += coefficients[2] * w[0] + coefficients[4] * acc[0]


def _switch_impulse(h, d_old, d_new, was_in_contact, ed_old, ed_new, kg, beta_k):
    """The dashpot impulse a Kelvin-Voigt span's contact change within the step needs beyond the
    step's own (trapezoidal: h/2 of the force at each end): its dashpot force jumps there, and the
    step would place the jump at mid-step, an O(h) impulse error per impact (first order). Located at
    the crossing fraction f of the span law's threshold (`_crossing`): entering contact, the force acts
    (1 - f) h, not h/2; leaving, f h. 0 for a span whose contact did not change."""
    now = (d_new >= 0.0) | (d_new <= -kg)
    if now == was_in_contact:
        return 0.0
    if now:
        f = _crossing(d_old, d_new, 0.0 if d_new >= 0.0 else -kg)
        return (0.5 - f) * h * beta_k * ed_new
    f = _crossing(d_old, d_new, 0.0 if d_old >= 0.0 else -kg)
    return (f - 0.5) * h * beta_k * ed_old


def _dashpot_switch_loop(h, y, wh, u, uh, wp_old, wp, up_old, up, free, par, ipar, w):
    """`_switch_impulse` of every span added to w (and the carriage's ud, returned); y is the step's
    end, y - h wh its start, `free` the start's free-play flags, wp_old / wp the velocities the
    dashpot forces at the start / end were taken at."""
    m, k, preload, kg, beta = par[0], par[1], par[3], par[4], par[5]
    s, tens = ipar[0], ipar[1]
    n = y.shape[0]
    ud_change = 0.0
    for j in range(n):
        l = j + 1 if j + 1 < n else 0
        e_new = y[l] - y[j]
        e_old = e_new - h * (wh[l] - wh[j])
        ed_old = wp_old[l] - wp_old[j]
        ed_new = wp[l] - wp[j]
        if tens and j == s:
            e_new += 2.0 * u
            e_old += 2.0 * (u - h * uh)
            ed_old += 2.0 * up_old
            ed_new += 2.0 * up
        impulse = _switch_impulse(
            h, preload + k * e_old, preload + k * e_new, not free[j], ed_old, ed_new, kg, beta * k
        )
        w[j] += impulse / m
        w[l] -= impulse / m
        if tens and j == s:
            ud_change -= 2.0 * impulse / par[8]
    return ud_change


def _kinetic_J(w, ud, par, ipar):
    """Kinetic energy of the links' velocities w relative to the cam and of the carriage (a kick
    whose link parts sum to zero changes the absolute kinetic energy by the change of this)."""
    ke = 0.0
    for i in range(w.shape[0]):
        ke += w[i] * w[i]
    ke *= 0.5 * par[0]
    if ipar[1]:
        ke += 0.5 * par[8] * ud * ud
    return ke


def _dashpot_switch_array(h, y_old, y, u_old, u, wp_old, wp, up_old, up, was_in_contact, par, ipar, w, ud):
    """`_dashpot_switch_loop` on whole arrays (the numpy path): (w, ud) with the impulses added."""
    m, k, preload, kg, beta = par[0], par[1], par[3], par[4], par[5]
    s, tens = ipar[0], ipar[1]

    def stretch(q, qu):
        e = np.roll(q, -1) - q
        if tens:
            e[s] += 2.0 * qu
        return e

    d_old, d_new = preload + k * stretch(y_old, u_old), preload + k * stretch(y, u)
    ed_old, ed_new = stretch(wp_old, up_old), stretch(wp, up)
    now = (d_new >= 0.0) | (d_new <= -kg)
    threshold = np.where(now, np.where(d_new >= 0.0, 0.0, -kg), np.where(d_old >= 0.0, 0.0, -kg))
    span = d_old - d_new
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(span == 0.0, 1.0, np.clip((d_old - threshold) / span, 0.0, 1.0))
    impulse = np.where(now, (0.5 - f) * ed_new, (f - 0.5) * ed_old) * (h * beta * k)
    impulse = np.where(now != was_in_contact, impulse, 0.0)
    w = w + (impulse - np.roll(impulse, 1)) / m
    if tens:
        ud = ud - 2.0 * impulse[s] / par[8]
    return w, ud


def _span_law_into(y, u, par, ipar, t_el, contact):
    """Elastic span forces and contact flags of the positions y (and the carriage's u)."""
    k, preload, kg = par[1], par[3], par[4]
    s, tens = ipar[0], ipar[1]
    n = y.shape[0]
    for j in range(n - 1):
        t_el[j], contact[j] = _span(preload + k * (y[j + 1] - y[j]), kg)
    t_el[n - 1], contact[n - 1] = _span(preload + k * (y[0] - y[n - 1]), kg)
    if tens:
        t_el[s], contact[s] = _span(preload + k * (y[s + 1 if s + 1 < n else 0] - y[s] + 2.0 * u), kg)


def _span(d, kg):
    """(force, in contact) of a span at d = P + k e, without a branch: max(d, 0) + min(d + k g, 0)
    is d in pulling contact, 0 in free play, d + k g pushing."""
    return max(d, 0.0) + min(d + kg, 0.0), (d >= 0.0) | (d <= -kg)


def _damping_into(w, ud, par, ipar, blocks, work, contact, cw):
    """cw = the damping forces on the links (subtracted from the span forces): C w (global law) or
    the dashpots of the spans in contact and the drive's (Kelvin-Voigt). Returns the idler span's
    dashpot force (0 for the global law)."""
    k, kd, beta = par[1], par[2], par[5]
    s, tens, kv = ipar[0], ipar[1], ipar[2]
    n = w.shape[0]
    dash_s = 0.0
    if not kv:
        if ipar[3]:
            _sqrt_product(blocks[2], blocks[3], blocks[4], blocks[5], work[4], work[5], w, cw)
        else:
            _mirror_product(blocks[0], blocks[1], n, w, work[0], work[1], work[2], work[3], cw)
        return dash_s
    for i in range(n):
        cw[i] = 0.0
    cw[0] = beta * kd * w[0]
    for j in range(n):
        if contact[j]:
            l = j + 1 if j + 1 < n else 0
            ed = w[l] - w[j]
            if tens and j == s:
                ed += 2.0 * ud
            dash = beta * k * ed
            cw[j] -= dash
            cw[l] += dash
            if j == s:
                dash_s = dash
    return dash_s


def _friction_into(zd, w, par, fr):
    """fr = the friction law at the links' absolute velocities zd + w; returns its power (dissipated
    when positive). The saturated law first (a vectorised pass); where some link is off saturation,
    every link's tanh in a second vectorised pass (`_tanh_branch_free` is exactly +-1 on the saturated
    ones, so their force is the first pass's). Compiled on its own with numpy's error model, as the
    machine's: numba's check of a division by zero would keep the division out of vectors."""
    fc, inv_vs = par[6], par[7]
    n = w.shape[0]
    unsaturated = 0
    for i in range(n):
        x = (zd + w[i]) * inv_vs
        fr[i] = -fc if x > 0.0 else fc
        unsaturated += abs(x) < TANH_IS_ONE
    if unsaturated:
        for i in range(n):
            fr[i] = -fc * _tanh_branch_free((zd + w[i]) * inv_vs)
    p_fric = 0.0
    for i in range(n):
        p_fric -= fr[i] * (zd + w[i])
    return p_fric


def _carriage(u, ud, t_s, par, ipar):
    """(carriage acceleration, carriage damping power) for the idler span's force t_s; (0, 0) without one."""
    if not ipar[1]:
        return 0.0, 0.0
    mt, kt, ct, f0 = par[8], par[9], par[10], par[11]
    return (f0 - kt * u - ct * ud - 2.0 * t_s) / mt, ct * ud * ud


def _accel_into(y, w, u, ud, zd, zdd, par, ipar, blocks, work, cw, fr, a, t_el, contact):
    """`_accel` into preallocated arrays (`work` is the damping product's, see `_mirror_product`).
    Returns (carriage acceleration, cam power, damping power, friction power)."""
    kd = par[2]
    n = y.shape[0]
    _span_law_into(y, u, par, ipar, t_el, contact)
    dash_s = _damping_into(w, ud, par, ipar, blocks, work, contact, cw)
    total = 0.0
    p_damp = 2.0 * ud * dash_s  # the idler dashpot's work on the carriage
    for i in range(n):
        total += cw[i]
        p_damp += w[i] * cw[i]
    f_cam = -kd * y[0] - total
    cw[0] += kd * y[0]
    p_fric = _friction_into(zd, w, par, fr)
    _net_acceleration(t_el, cw, fr, par[0], zdd, a)
    au, p_carriage = _carriage(u, ud, t_el[ipar[0]] + dash_s, par, ipar)
    return au, f_cam * zd, p_damp + p_carriage, p_fric


def _net_acceleration(t_el, cw, fr, m, zdd, a):
    """a = (span forces' net - cw + friction) / m - z'': the spans' net first, as in `_accel`."""
    n = t_el.shape[0]
    prev = t_el[n - 1]
    for i in range(n):
        t = t_el[i]
        a[i] = ((t - prev) - cw[i] + fr[i]) / m - zdd
        prev = t


def _run_loops(
    y,
    w,
    u,
    ud,
    zd,
    zdd,
    h,
    theta,
    out_every,
    record_from,
    par,
    ipar,
    blocks,
    track_energy,
    out_y,
    out_w,
    out_a,
    out_u,
    out_ud,
    stats,
    energy,
    speeds,
):
    """`_run` as loops over preallocated arrays, compiled with numba; same steps, same outputs. The
    damping matrix comes as `reflection_blocks`."""
    n_steps = zd.shape[0] - 1
    n = y.shape[0]
    bound, kd = par[12], par[2]
    y = y.copy()
    w = w.copy()
    a = np.empty(n)
    a_out = np.empty(n)
    cw = np.empty(n)
    fr = np.empty(n)
    wh = np.empty(n)
    wp = np.empty(n)
    t_el = np.empty(n)
    contact = np.empty(n, dtype=np.bool_)
    free = np.empty(n, dtype=np.bool_)
    phase = np.zeros(n, dtype=np.bool_)
    clocks = np.zeros((2, n))
    work = (
        np.zeros(blocks[0].shape[1]),
        np.zeros(blocks[1].shape[1]),
        np.zeros(blocks[0].shape[0]),
        np.zeros(blocks[1].shape[0]),
        np.zeros(n),
        np.zeros((n + 1, blocks[3].shape[0])),
    )
    au, pc, pd, pf = _accel_into(y, w, u, ud, zd[0], zdd[0], par, ipar, blocks, work, cw, fr, a, t_el, contact)
    a_prev = a.copy()  # the first step's predictor is w + h a whatever theta
    au_prev = au
    wp_prev = w.copy()  # the velocities the last dashpot forces were taken at (Kelvin-Voigt)
    up_prev = ud
    powers = np.array([pc, pd, pf])
    p_new = np.empty(3)
    for j in range(n):
        free[j] = not contact[j]
    _record_step(t_el, contact, phase, free, stats, record_from == 0)
    row = _keep(
        -1, h, 0, y, w, a, u, ud, powers, powers, False, True, out_y, out_w, out_a, out_u, out_ud, energy, stats, np.inf
    )
    hh = 0.5 * h
    for i in range(n_steps):
        for j in range(n):
            wh[j] = w[j] + hh * a[j]
            y[j] += h * wh[j]
            wp[j] = w[j] + h * (a[j] + theta * (a[j] - a_prev[j]))
            a_prev[j] = a[j]
        uh = ud + hh * au
        u += h * uh
        up = ud + h * (au + theta * (au - au_prev))
        au_prev = au
        # `_accel_into` at (y, wp) without the powers, which only output steps need; written out here
        # because a shared helper for both was about 4 % slower (exploratory timing, interleaved runs)
        _span_law_into(y, u, par, ipar, t_el, contact)
        dash_s = _damping_into(wp, up, par, ipar, blocks, work, contact, cw)
        cw[0] += kd * y[0]
        _friction_into(zd[i + 1], wp, par, fr)
        _net_acceleration(t_el, cw, fr, par[0], zdd[i + 1], a)
        for j in range(n):
            w[j] = wh[j] + hh * a[j]
        au, _ = _carriage(u, up, t_el[ipar[0]] + dash_s, par, ipar)
        ud = uh + hh * au
        if ipar[2]:
            before = _kinetic_J(w, ud, par, ipar) if track_energy else 0.0
            ud += _dashpot_switch_loop(h, y, wh, u, uh, wp_prev, wp, up_prev, up, free, par, ipar, w)
            if track_energy:  # the impulses' work, dissipated by the dashpots
                energy[1] += before - _kinetic_J(w, ud, par, ipar)
            for j in range(n):
                wp_prev[j] = wp[j]
            up_prev = up
        _impacts_loop(
            h,
            y,
            w,
            a,
            wh,
            a_prev,
            u,
            ud,
            au,
            uh,
            au_prev,
            par,
            ipar,
            t_el,
            contact,
            free,
            phase,
            clocks,
            stats,
            speeds,
            i + 1 >= record_from,
        )
        _record_step(t_el, contact, phase, free, stats, i + 1 >= record_from)
        on_output = (i + 1) % out_every == 0
        if track_energy or on_output:
            _, pc2, pd2, pf2 = _accel_into(
                y, w, u, ud, zd[i + 1], zdd[i + 1], par, ipar, blocks, work, cw, fr, a_out, t_el, contact
            )
            p_new[0], p_new[1], p_new[2] = pc2, pd2, pf2
            row = _keep(
                i,
                h,
                row,
                y,
                w,
                a_out,
                u,
                ud,
                p_new,
                powers,
                track_energy,
                on_output,
                out_y,
                out_w,
                out_a,
                out_u,
                out_ud,
                energy,
                stats,
                bound,
            )
            if row < 0:
                return


def _impact_duration_s(par) -> float:
    """One impact's duration: half a period of the two links' contact oscillation, pi sqrt(m_eff / k)
    with m_eff = m / 2 (two equal links closing on one span)."""
    return math.pi * math.sqrt(0.5 * par[0] / par[1])


def _crossing(d_old, d_new, threshold):
    """Fraction of the step at which P + k e crossed `threshold` (linear in the step: e is smooth
    there, the span law's force being continuous through its kinks)."""
    span = d_old - d_new
    if span == 0.0:
        return 1.0
    return min(max((d_old - threshold) / span, 0.0), 1.0)


def _impacts_loop(
    h,
    y,
    w,
    a,
    wh,
    a_prev,
    u,
    ud,
    au,
    uh,
    au_prev,
    par,
    ipar,
    t_el,
    contact,
    free,
    phase,
    clocks,
    stats,
    speeds,
    recording,
):
    """The impacts of one step, before `_record_step` moves the flags on (`free` and `phase` are the
    previous step's). An impact is a span entering contact from free play; at it the closing speed
    |e'| and the kinetic energy of the approach 1/2 m_eff e'^2 are taken at the crossing (the crossing
    interpolated in the step, the speed there extrapolated from the free-play side with its
    acceleration: second order whether or not a dashpot switches on with the contact); while the contact it began lasts, the largest |T| within one impact duration
    (`_impact_duration_s`) is its force spike and the Kelvin-Voigt dashpot's work (trapezoidal, from
    and to the crossings) the energy the contact dissipates. `clocks[0]`: time since each span's
    impact; `clocks[1]`: its dashpot power at the last step. The previous state is recovered from the
    step's own quantities: y - h w_half, w_half - h/2 a_prev."""
    m, k, preload, kg, beta = par[0], par[1], par[3], par[4], par[5]
    s, tens, kv = ipar[0], ipar[1], ipar[2]
    n = y.shape[0]
    hh = 0.5 * h
    window = _impact_duration_s(par)
    for j in range(n):
        c = contact[j]
        impact = c and free[j]
        ongoing = phase[j] and c
        ending = phase[j] and not c
        if not (impact or ongoing or ending):
            continue
        l = j + 1 if j + 1 < n else 0
        ed_new = w[l] - w[j]
        if tens and j == s:
            ed_new += 2.0 * ud
        if ongoing:
            clocks[0, j] += h
            p_new = beta * k * ed_new * ed_new if kv else 0.0
            if recording:
                if clocks[0, j] <= window:
                    stats[7] = max(stats[7], abs(t_el[j]))
                stats[9] += hh * (clocks[1, j] + p_new)
            clocks[1, j] = p_new
            continue
        e_new = y[l] - y[j]
        e_old = (y[l] - h * wh[l]) - (y[j] - h * wh[j])
        ed_old = (wh[l] - hh * a_prev[l]) - (wh[j] - hh * a_prev[j])
        ea_old = a_prev[l] - a_prev[j]
        ea_new = a[l] - a[j]
        if tens and j == s:
            e_new += 2.0 * u
            e_old += 2.0 * (u - h * uh)
            ed_old += 2.0 * (uh - hh * au_prev)
            ea_old += 2.0 * au_prev
            ea_new += 2.0 * au
        d_old = preload + k * e_old
        d_new = preload + k * e_new
        if impact:
            frac = _crossing(d_old, d_new, 0.0 if d_new >= 0.0 else -kg)
            ed_c = ed_old + frac * h * ea_old
            p_new = beta * k * ed_new * ed_new if kv else 0.0
            clocks[0, j] = (1.0 - frac) * h
            clocks[1, j] = p_new
            if recording:
                speed = abs(ed_c)
                stats[7] = max(stats[7], abs(t_el[j]))
                stats[8] += 0.25 * m * ed_c * ed_c
                stats[9] += 0.5 * (1.0 - frac) * h * ((beta * k * ed_c * ed_c if kv else 0.0) + p_new)
                stats[10] = max(stats[10], speed)
                stored = int(stats[11])
                if stored < speeds.shape[0]:
                    speeds[stored] = speed
                    stats[11] = stored + 1
        else:
            frac = _crossing(d_old, d_new, 0.0 if d_old >= 0.0 else -kg)
            ed_c = ed_new - (1.0 - frac) * h * ea_new
            if recording:
                stats[9] += 0.5 * frac * h * (clocks[1, j] + (beta * k * ed_c * ed_c if kv else 0.0))
            clocks[1, j] = 0.0


def _impacts_array(
    h,
    y,
    w,
    a,
    y_old,
    w_old,
    a_old,
    u,
    ud,
    au,
    u_old,
    ud_old,
    au_old,
    par,
    ipar,
    t_el,
    contact,
    free,
    phase,
    clocks,
    stats,
    speeds,
    recording,
):
    """`_impacts_loop` in numpy, for the numpy path (the previous state given whole); same results."""
    m, k, preload, kg, beta = par[0], par[1], par[3], par[4], par[5]
    s, tens, kv = ipar[0], ipar[1], ipar[2]
    impact = contact & free
    ongoing = phase & contact
    ending = phase & ~contact
    if not (impact.any() or ongoing.any() or ending.any()):
        return
    window = _impact_duration_s(par)
    beta_k = beta * k if kv else 0.0

    def stretch(q, v):
        return np.roll(q, -1) - q + (2.0 * v * (np.arange(q.shape[0]) == s) if tens else 0.0)

    ed_new = stretch(w, ud)
    p_new = beta_k * ed_new**2
    clocks[0, ongoing] += h
    if recording and ongoing.any():
        early = ongoing & (clocks[0] <= window)
        if early.any():
            stats[7] = max(stats[7], float(np.max(np.abs(t_el[early]))))
        stats[9] += float(np.sum(0.5 * h * (clocks[1, ongoing] + p_new[ongoing])))
    clocks[1, ongoing] = p_new[ongoing]
    if not (impact.any() or ending.any()):
        return
    d_old = preload + k * stretch(y_old, u_old)
    d_new = preload + k * stretch(y, u)
    ed_old = stretch(w_old, ud_old)
    ea_old, ea_new = stretch(a_old, au_old), stretch(a, au)
    for j in np.flatnonzero(impact | ending):
        if impact[j]:
            frac = _crossing(d_old[j], d_new[j], 0.0 if d_new[j] >= 0.0 else -kg)
            ed_c = ed_old[j] + frac * h * ea_old[j]
            clocks[0, j] = (1.0 - frac) * h
            clocks[1, j] = p_new[j]
            if recording:
                stats[7] = max(stats[7], abs(t_el[j]))
                stats[8] += 0.25 * m * ed_c * ed_c
                stats[9] += 0.5 * (1.0 - frac) * h * (beta_k * ed_c * ed_c + p_new[j])
                stats[10] = max(stats[10], abs(ed_c))
                stored = int(stats[11])
                if stored < speeds.shape[0]:
                    speeds[stored] = abs(ed_c)
                    stats[11] = stored + 1
        else:
            frac = _crossing(d_old[j], d_new[j], 0.0 if d_old[j] >= 0.0 else -kg)
            ed_c = ed_new[j] - (1.0 - frac) * h * ea_new[j]
            if recording:
                stats[9] += 0.5 * frac * h * (clocks[1, j] + beta_k * ed_c * ed_c)
            clocks[1, j] = 0.0


def _record_step(t_el, contact, phase, free, stats, recording):
    """The impact bookkeeping of one step (`free` holds the previous step's free-play flags, `phase`
    marks contacts begun by an impact) and, when `recording`, its statistics added to stats
    (`integrate`'s layout). Without branches (bit operations on the flags): the loop vectorises."""
    impacts = 0
    n_free = 0
    t_max = -np.inf
    t_min = np.inf
    peak = 0.0
    for j in range(t_el.shape[0]):
        c = contact[j]
        impact = c & free[j]
        ph = (phase[j] | impact) & c
        phase[j] = ph
        free[j] = not c
        impacts += impact
        n_free += not c
        t = t_el[j]
        t_max = max(t_max, t)
        t_min = min(t_min, t)
        peak = max(peak, abs(t) * ph)
    if not recording:
        return
    stats[0] += impacts
    stats[1] += n_free
    stats[2] += t_el.shape[0]
    stats[3] = max(stats[3], t_max)
    stats[4] = min(stats[4], t_min)
    stats[5] = max(stats[5], peak)


if numba is not None:
    # helpers inlined into the step loop (numba IR inlining: no call, and the loop fuses their work)
    for _name in (
        "_rows_times",
        "_mirror_product",
        "_sqrt_product",
        "_span_law_into",
        "_span",
        "_damping_into",
        "_tanh_branch_free",  # the machine kernel inlines this one too
        "_carriage",
        "_accel_into",
        "_net_acceleration",
        "_record_step",
        "_impact_duration_s",
        "_crossing",
        "_switch_impulse",
        "_dashpot_switch_loop",
        "_kinetic_J",
        "_impacts_loop",
    ):
        globals()[_name] = numba.njit(cache=True, fastmath=FASTMATH, inline="always")(globals()[_name])
    _keep = numba.njit(cache=True)(_keep)
    _friction_into = numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")(_friction_into)
    _run_compiled = numba.njit(cache=True, fastmath=FASTMATH)(_run_loops)
    # their cache entries are stale when friction_tanh.py (inlined) changes too, not only this file
    kernel_cache.key_on_dependencies(globals(), __name__)
else:  # pragma: no cover
    _run_compiled = None


def spectral_radius(omega_h: float, zeta: float, predictor: str = "euler") -> float:
    """Largest |eigenvalue| of one step on the mode q'' + 2 zeta omega q' + omega^2 q = 0 (state q,
    q', carried acceleration, the previous step's acceleration) with the given velocity predictor."""
    theta = PREDICTORS[predictor]
    wh, c = float(omega_h), 2.0 * zeta * float(omega_h)  # accelerations scaled by h^2: -wh^2 q - c h q'
    # state (q, h q', h^2 a, h^2 a_prev)
    m = np.zeros((4, 4))
    for col in range(4):
        q, v, a, a_prev = np.eye(4)[col]
        v_half = v + 0.5 * a
        q1 = q + v_half
        v_pred = v + a + theta * (a - a_prev)
        a1 = -wh * wh * q1 - c * v_pred
        m[:, col] = (q1, v_half + 0.5 * a1, a1, a)
    return float(np.max(np.abs(np.linalg.eigvals(m))))


def stable_omega_h(zeta: float, predictor: str = "euler") -> float:
    """Largest omega h with spectral radius <= 1 (bisection; 2 for zeta = 0)."""
    lo, hi = 0.0, 2.0 + 1e-12
    if spectral_radius(hi, zeta, predictor) <= 1.0 + 1e-12:
        return hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if spectral_radius(mid, zeta, predictor) <= 1.0 + 1e-12:
            lo = mid
        else:
            hi = mid
    return lo


@dataclass(frozen=True)
class Run:
    """Outputs of one integration: states at the output nodes, window statistics, energy terms."""

    y: np.ndarray  # (m, N)
    w: np.ndarray
    a: np.ndarray
    u: np.ndarray  # (m,) carriage displacement (0 without tensioner)
    ud: np.ndarray
    impacts: int
    free_play_fraction: float
    peak_tension_N: float
    min_tension_N: float
    peak_force_in_impact_contact_N: float  # largest |T| while a contact begun by an impact lasts (its whole length)
    cam_work_J: float
    dissipated_damping_J: float
    dissipated_friction_J: float
    step_s: float
    n_steps: int
    impact_force_spike_N: float = 0.0  # largest |T| within one impact duration of an impact (`_impacts_loop`)
    impact_speeds_m_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # |e'| of each recorded impact
    impact_max_speed_m_s: float = 0.0  # (the speeds keep at most SPEED_CAPACITY impacts; the max all of them)
    impact_kinetic_energy_J: float = 0.0  # sum over the recorded impacts of 1/2 m_eff e'^2, m_eff = m / 2
    impact_dissipated_J: float = 0.0  # Kelvin-Voigt dashpots' work in contacts begun by impacts (0: global law)


def integrate(
    model,
    zd_nodes,
    zdd_nodes,
    step_s: float,
    y0,
    w0,
    *,
    u0: float = 0.0,
    ud0: float = 0.0,
    out_every: int = 1,
    record_from: int = 0,
    track_energy: bool = False,
    compiled: bool | None = None,
    predictor: str = "euler",
) -> Run:
    """Step the clearance chain `model` (dynamics.models.clearance.ClearanceChain) over the nodes at which
    the cam's velocity and acceleration are given (uniform step `step_s`, len n_steps + 1), from
    (y0, w0, u0, ud0). `compiled`: None = numba when installed, False = the numpy path. `predictor`:
    the velocity at which the damping and friction forces are taken (PREDICTORS)."""
    theta = PREDICTORS[_predictor(predictor)]
    if theta and model.span_damping != "global":
        raise DynamicsError(
            f"predictor: {predictor!r} is for the global damping law (the Kelvin-Voigt dashpot "
            f"jumps at impacts); use predictor='euler'"
        )
    zd = np.ascontiguousarray(zd_nodes, dtype=float)
    zdd = np.ascontiguousarray(zdd_nodes, dtype=float)
    n_steps = zd.size - 1
    if zdd.shape != zd.shape or n_steps < 1 or n_steps % out_every:
        raise DynamicsError("integrate: expected cam nodes of equal length, a whole number of output intervals")
    if not (np.isfinite(step_s) and step_s > 0):
        raise DynamicsError(f"step_s: expected a positive step, got {step_s!r}")
    c = model.chain
    n = c.n_links
    y0 = np.array(y0, dtype=float).reshape(n)
    w0 = np.array(w0, dtype=float).reshape(n)
    scale = max(
        np.max(np.abs(y0)),
        np.max(np.abs(zd)) * step_s * n_steps,
        np.max(np.abs(zdd)) * (step_s * n_steps) ** 2,
        c.preload_N / c.stiffness_N_per_m,
        1e-9,
    )
    par, ipar, cmat = packed_parameters(model, 1e6 * scale)
    m_out = n_steps // out_every + 1
    out = [np.zeros((m_out, n)) for _ in range(3)] + [np.zeros(m_out), np.zeros(m_out)]
    stats = np.zeros(N_STATS)
    stats[3], stats[4] = -np.inf, np.inf
    energy = np.zeros(N_ENERGY)
    speeds = np.zeros(SPEED_CAPACITY)
    use_numba = (numba is not None) if compiled is None else compiled
    if use_numba and numba is None:
        raise DynamicsError("integrate: compiled=True but numba is not installed")
    runner, damping = (_run_compiled, _damping_blocks(model, cmat)) if use_numba else (_run, cmat)
    with np.errstate(over="ignore", invalid="ignore"):
        runner(
            y0,
            w0,
            float(u0),
            float(ud0),
            zd,
            zdd,
            float(step_s),
            theta,
            int(out_every),
            int(record_from),
            par,
            ipar,
            damping,
            bool(track_energy),
            *out,
            stats,
            energy,
            speeds,
        )
    if stats[6] or not np.all(np.isfinite(out[0])):
        where = stats[6] if stats[6] else "?"
        raise SolverDivergedError(
            f"clearance-verlet: solution diverged at step {where} (step {step_s:.3g} s); reduce the step "
            f"below the stability limit of the contact frequency"
        )
    recorded = max(stats[2], 1.0)
    return Run(
        *out,
        impacts=int(stats[0]),
        free_play_fraction=float(stats[1] / recorded),
        peak_tension_N=float(stats[3]),
        min_tension_N=float(stats[4]),
        peak_force_in_impact_contact_N=float(stats[5]),
        impact_force_spike_N=float(stats[7]),
        impact_speeds_m_s=speeds[: int(stats[11])].copy(),
        impact_max_speed_m_s=float(stats[10]),
        impact_kinetic_energy_J=float(stats[8]),
        impact_dissipated_J=float(stats[9]),
        cam_work_J=float(energy[0]),
        dissipated_damping_J=float(energy[1]),
        dissipated_friction_J=float(energy[2]),
        step_s=float(step_s),
        n_steps=int(n_steps),
    )


@dataclass(frozen=True)
class RingPacking:
    """The ring's topological quantities as its compiled step takes them (`packed_parameters`), read
    from its topology by `ring_packing`; SI."""

    link_mass_kg: float
    span_stiffness_N_per_m: float
    drive_stiffness_N_per_m: float
    preload_N: float
    idler_span: int | None  # the span the carriage sits in (None: no carriage)
    carriage_mass_kg: float  # (1 without a carriage: a placeholder the step never divides by)
    carriage_rate_N_per_m: float


def ring_packing(topology) -> RingPacking:
    """The ring's quantities from its topology (a dynamics.models.topology.ChainTopology, the spans
    packed by its `span_arrays`, as the machine's step packs them), so that the ring's step and the
    machine's read the one topology: N links of equal mass, span j from link j to link j + 1 (the
    last closes the loop), the drive spring on link 0, and at most one carriage, the last DOF, inside
    one span at gain 2 (moving it by u lengthens the loop by 2 u) and tied to the frame by its spring.
    DynamicsError for any other topology (the ring's step has no other)."""
    ends, gains = topology.span_arrays()
    n = ends.shape[0]
    links = np.arange(n)
    carried = np.flatnonzero(ends[:, 2] >= 0)
    masses = np.asarray(topology.masses_kg, dtype=float)
    ground = dict(topology.ground)
    expected_ground = {0, n} if carried.size else {0}
    if (
        n < 2
        or np.any(ends[:, 0] != links)
        or np.any(ends[:, 1] != (links + 1) % n)
        or carried.size > 1
        or np.any(ends[carried, 2] != n)
        or np.any(gains[carried] != 2.0)
        or topology.n_dof != n + carried.size
        or np.any(masses[:n] != masses[0])
        or set(ground) != expected_ground
        or len(topology.ground) != len(ground)
        or topology.couplings
    ):
        raise DynamicsError(
            "ring_packing: expected a ring topology (span j from link j to link j + 1, the drive spring "
            "on link 0, at most one carriage as the last DOF); the clearance chain's step takes no other"
        )
    span = int(carried[0]) if carried.size else None
    return RingPacking(
        float(masses[0]),
        float(topology.span_stiffness_N_per_m),
        float(ground[0]),
        float(topology.preload_N),
        span,
        float(masses[n]) if carried.size else 1.0,
        float(ground[n]) if carried.size else 0.0,
    )


def packed_parameters(model, bound: float = np.inf):
    """(par, ipar, cmat): the model as the kernels take it (`_accel(y, w, u, ud, zd, zdd, *packed)`);
    `bound` is the |y| above which a run counts as diverged. The masses, stiffnesses, preload, idler
    span and carriage from the model's topology (`ring_packing`), the damping and friction laws from
    the model."""
    c, t = model.chain, model.tensioner
    ring = ring_packing(model.topology)
    kv = model.span_damping == "kelvin-voigt"
    par = np.array(
        [
            ring.link_mass_kg,
            ring.span_stiffness_N_per_m,
            ring.drive_stiffness_N_per_m,
            ring.preload_N,
            ring.span_stiffness_N_per_m * model.clearance_m,
            model.beta_s,
            c.coulomb_force_N,
            1.0 / c.friction_velocity_scale_m_s,
            ring.carriage_mass_kg,
            ring.carriage_rate_N_per_m,
            t.damping_N_s_per_m if t else 0.0,
            2.0 * ring.preload_N,  # the preload on the carriage (at its gain, 2: `ring_packing`)
            bound,
        ]
    )
    reduced = not kv and model.damping_is_reduced
    carriage = ring.idler_span is not None
    span = ring.idler_span if carriage else model.idler_span  # (read, unused, without a carriage)
    ipar = np.array([span, int(carriage), int(kv), int(reduced)], dtype=np.int64)
    cmat = np.zeros((1, 1)) if kv else model.damping_operator
    return par, ipar, cmat


def _damping_blocks(model, cmat):
    """The damping as the compiled step takes it: (symmetric block, antisymmetric block, then the
    reduced form's coefficients, weights, factors, sm: `ReducedDamping.packed`). A dense C:
    `reflection_blocks(cmat)`, computed once per chain (the solvers' cache), and an empty reduced part;
    the reduced form (`cmat` a ReducedDamping): its packed parts and dummy blocks; the Kelvin-Voigt
    law, which has no C: dummies."""
    empty = (np.zeros(6), np.zeros(0), np.zeros((3, 1, 0)), np.zeros((0, 3)))
    dummy = (_padded(np.zeros((1, 1))), _padded(np.zeros((0, 0))))
    if model.span_damping == "kelvin-voigt":
        return dummy + empty
    if model.damping_is_reduced:
        coefficients, weights, factors, sm = cmat.packed()
        # the compiled product's layout: factors (3, N, p); sm's third column its scratch
        return dummy + (
            coefficients,
            weights,
            np.ascontiguousarray(factors.transpose(1, 2, 0)),
            np.ascontiguousarray(np.column_stack([sm, np.zeros(sm.shape[0])])),
        )
    return cache.cached(("reflection-blocks", model.chain), lambda: reflection_blocks(cmat)) + empty


def reflection_blocks(cmat: np.ndarray):
    """C as the compiled step takes it: (symmetric block, antisymmetric block), padded (`_padded`).

    The loop's reflection that keeps link 1 (link i <-> link N + 2 - i, 1-based) maps the chain onto
    itself: equal links and spans, the drive on link 1, the idler span onto itself. C commutes with
    it, so in the coordinates w_fixed (link 1, and the middle link for even N) and (w_p +- w_N-p) /
    sqrt 2 of each mirrored pair it is block diagonal (`_mirror_product`): about N^2 / 2
    multiply-adds instead of N^2. A C without that symmetry comes back whole, with an empty
    antisymmetric block."""
    n = cmat.shape[0]
    pairs = (n - 1) // 2
    lo = np.arange(1, pairs + 1)
    hi = n - lo
    fixed = np.array([0] if n % 2 else [0, n // 2])
    mirror = (n - np.arange(n)) % n
    scale = np.max(np.abs(cmat), initial=0.0)
    if n < 3 or np.max(np.abs(cmat[np.ix_(mirror, mirror)] - cmat)) > REFLECTION_TOL * scale:
        return _padded(cmat), _padded(np.zeros((0, 0)))
    r = math.sqrt(0.5)
    sym, anti = np.zeros((n, fixed.size + pairs)), np.zeros((n, pairs))
    sym[fixed, np.arange(fixed.size)] = 1.0
    sym[lo, fixed.size + np.arange(pairs)] = r
    sym[hi, fixed.size + np.arange(pairs)] = r
    anti[lo, np.arange(pairs)] = r
    anti[hi, np.arange(pairs)] = -r
    return _padded(sym.T @ cmat @ sym), _padded(anti.T @ cmat @ anti)


def _padded(block: np.ndarray) -> np.ndarray:
    rows = -(-block.shape[0] // ROW_MULTIPLE) * ROW_MULTIPLE
    cols = -(-block.shape[1] // COLUMN_MULTIPLE) * COLUMN_MULTIPLE
    out = np.zeros((rows, cols))
    out[: block.shape[0], : block.shape[1]] = block
    return out


def stable_step_s(model, safety: float = DEFAULT_SAFETY, predictor: str = "euler") -> float:
    """`safety` times the largest stable step at the highest full-contact frequency."""
    if not (0 < safety <= 1):
        raise DynamicsError(f"safety: expected a fraction in (0, 1], got {safety!r}")
    omega = model.max_frequency_rad_s()
    return safety * stable_omega_h(model.damping_ratio_at(omega), _predictor(predictor)) / omega


def substeps_for(model, output_step_s: float, safety: float = DEFAULT_SAFETY, predictor: str = "euler") -> int:
    """Steps per output interval so that the step is at most `safety` of the stability limit."""
    return max(1, int(math.ceil(output_step_s / stable_step_s(model, safety, predictor) - 1e-9)))


def default_predictor(model) -> str:
    """The velocity predictor a run takes unless told: DEFAULT_PREDICTOR where it applies (the global
    law), "euler" for the Kelvin-Voigt law (see PREDICTORS)."""
    return DEFAULT_PREDICTOR if model.span_damping == "global" else "euler"


def default_safety(model, predictor: str) -> float:
    """The step's fraction of the stability limit a run takes unless told (DEFAULT_SAFETIES)."""
    return DEFAULT_SAFETIES.get((model.span_damping, _predictor(predictor)), DEFAULT_SAFETY)


def _predictor(name: str) -> str:
    if name not in PREDICTORS:
        raise DynamicsError(f"predictor: expected one of {', '.join(PREDICTORS)}, got {name!r}")
    return name
