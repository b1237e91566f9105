"""The tooth phase on the wheels (issue #22): the seats change inside the index when the cam has lifted
(1 - phase) p (dynamics.models.machine.MachineOnWheels.seat_change_lift_m). Reductions (phase 0 is
today's code path; phase -> 1 is phase 0 with the seat change moved to the index's start; z -> infinity
is the polygon-free model at the same phase), the chordal kinematics with the phase, the transfer's and
the window's energy balance across a seat change inside the index, the relabelled steady state, and
the clearance machine's pieces against the reference integrator."""

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import MachineLayout
from dynamics.models.machine import MachineOnWheels
from dynamics.models.wheels import Wheel, pitch_radius_m
from dynamics.solvers import machine_verlet as mv
from dynamics.solvers.machine_ivp import integrate_cycle
from dynamics.solvers.machine_steady import _cam_speed, _end_state, cycle_grid, periodic_state, transfer
from verification.machine_energy import energy_window, seating_energy

P = 0.1125
CAM = CamProgram.indexing("modified-sine", pitch_m=P, rpm=180.0)
CHAIN = ChainModel(16, 2.03, 2e7, preload_N=2224.0, damping_ratio=0.13)


def _machine(phase: float, teeth: int = 12, polygonal: bool = True, held: bool = False) -> MachineOnWheels:
    return MachineOnWheels(
        CHAIN,
        sprocket=Wheel(teeth, P, 3, inertia_kg_m2=0.0 if held else 0.3, tooth_phase=phase),
        idler=Wheel(teeth, P, 2, inertia_kg_m2=0.1, tooth_phase=phase),
        drive_torsional_stiffness_N_m_per_rad=np.inf if held else 2e6,
        polygonal=polygonal,
    )


def _random_state(machine, seed):
    rng = np.random.default_rng(seed)
    n = machine.topology.n_dof
    return 3e-5 * rng.standard_normal(n), 3e-2 * rng.standard_normal(n)


def _exact_cam(k):
    return lambda t: float(CAM.svaj(np.array([t]))[k][0])


# --- reductions --------------------------------------------------------------------------------------


def test_phase_zero_keeps_the_seat_change_at_the_dwell_on_todays_path():
    """Phase 0: no seat change inside the index (the solvers take today's path, bit for bit), and the
    transfer's new arguments at their dwell values are today's map exactly."""
    machine = _machine(0.0)
    assert machine.seat_change_lift_m is None
    tooth = np.array([e.wheel.tooth_angle_rad for e in machine.wheel_ends])
    for seed in range(3):
        q, v = _random_state(machine, seed)
        today = transfer(machine, q, v)
        explicit = transfer(machine, q, v, angles_rad=tooth, zdot_m_s=0.0)
        for a, b in zip(today, explicit):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    model = ClearanceMachine(machine, 0.0)
    h = CAM.cycle_s / 720
    nodes = mv.cycle_nodes(CAM, h, 720)
    q0 = 1e-5 * np.ones(machine.topology.n_dof)
    run, inside = mv.index_cycle(model, CAM, nodes, h, q0, q0, out_every=8, predictor="ab2")
    plain = mv.integrate(model, *nodes, h, q0, q0, out_every=8, predictor="ab2")
    assert inside is None
    np.testing.assert_array_equal(run.q, plain.q)


@pytest.mark.parametrize("polygonal", [False, True])
def test_the_seat_change_is_when_the_cam_has_lifted_one_minus_the_phase_of_a_pitch(polygonal):
    for phase in (0.1, 0.5, 0.9):
        assert _machine(phase, polygonal=polygonal).seat_change_lift_m == pytest.approx((1 - phase) * P, rel=1e-14)
    assert _machine(0.5, polygonal=polygonal).sprocket.seat_change_angle_rad == pytest.approx(np.pi / 12, rel=1e-14)


@pytest.mark.parametrize("teeth", [8, 12, 17, 25, 40])
def test_each_wheels_own_seat_change_is_the_one_instant_whatever_its_size(teeth):
    """A wheel's seats change when it has turned (1 - phase) of its tooth, and one of its teeth feeds one
    pitch whatever its size (R_m 2 pi / z = p): at one tooth phase every wheel's own seat change is at
    the cam's lift (1 - phase) p, the instant the solvers take for all (MachineOnWheels.seat_change_lift_m,
    the sprocket's), so an idler of another size than the sprocket changes its seats at the sprocket's
    instant exactly (to round-off); a different phase per wheel is refused."""
    for phase in (0.1, 0.25, 0.5, 0.75):
        wheel = Wheel(teeth, P, 2, inertia_kg_m2=0.1, tooth_phase=phase)
        own = wheel.seat_change_angle_rad * wheel.feed_radius_m
        assert own == pytest.approx(_machine(phase).seat_change_lift_m, rel=1e-14)
    with pytest.raises(DynamicsError, match="tooth_phase: the idler's"):
        MachineOnWheels(CHAIN, sprocket=Wheel(12, P, 3, 0.3, 0.25), idler=Wheel(teeth, P, 2, 0.1, 0.5))


def _response_after(cycle, t_from):
    keep = cycle.t_s > t_from
    return cycle.q_m[keep], cycle.a_m_s2[keep]


@pytest.mark.parametrize("polygonal", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_phase_towards_one_is_phase_zero_with_the_seat_change_moved_to_the_index_start(polygonal):
    """phi -> 1: the seats change at the start of the index instead of its end. The steady state's start
    state x0(phi) tends to phase 0's state before its transfer (x0(1-) = P(x0(0))), the cycle after the
    instant to phase 0's cycle, and the seating figures to phase 0's. The gap is the motion within the
    instant t_s (here 1 - phi = 1e-9: the cam's lift 1e-10 m at t_s = 1.2e-7 s), bounded by
    2 max|q'| t_s in the displacements, 2 max|q''| t_s in the velocities, plus the polygonal
    shooting's tolerance (1e-7 of the state's scale)."""
    from dynamics.solvers.machine_ivp import seat_change_time_s

    zero, near = _machine(0.0, polygonal=polygonal), _machine(1.0 - 1e-9, polygonal=polygonal)
    samples = 120 if polygonal else 360
    a, b = periodic_state(zero, CAM, samples), periodic_state(near, CAM, samples)
    t, s, acc = cycle_grid(CAM, samples)
    t_seat = seat_change_time_s(lambda x: np.interp(x, t, s), t[0], t[-1], s[0], near.seat_change_lift_m)
    assert 0 < t_seat < 2e-7
    shooting = 2e-7 if polygonal else 0.0
    q_gap = 2 * np.abs(a.v_m_s).max() * t_seat + shooting * np.abs(a.q_m).max()
    v_gap = 2 * np.abs(a.a_m_s2).max() * t_seat + shooting * np.abs(a.v_m_s).max()
    end_zero = _end_state(zero, np.concatenate([a.q_m[0], a.v_m_s[0]]), t, s, acc, False)  # before its transfer
    n = end_zero.size // 2
    assert np.max(np.abs(b.q_m[0] - end_zero[:n])) < q_gap
    assert np.max(np.abs(b.v_m_s[0] - end_zero[n:])) < v_gap
    assert np.max(np.abs(b.q_m[1:] - a.q_m[1:])) < q_gap
    assert np.max(np.abs(b.v_m_s[1:] - a.v_m_s[1:])) < v_gap
    np.testing.assert_allclose(b.seating_speed_m_s, a.seating_speed_m_s, rtol=1e-3)
    np.testing.assert_allclose(b.seating_impact_J, a.seating_impact_J, rtol=2e-3)


def test_the_polygon_free_model_honours_the_phase_and_z_to_infinity_reaches_it():
    """The phase is where the seats change, which the polygon-free model keeps (its feed is the mean
    one, its seating is not): phase 0.5 differs from phase 0 there too. z -> infinity removes the
    chordal part: the feed's departure over the index falls as 1/z^2 for every phase, and the
    polygonal model's seat change inside the index tends to the polygon-free one at the same phase
    (the transfer's c - 1 and d, O(1/z^2))."""
    phase = 0.5
    half = periodic_state(_machine(phase, polygonal=False), CAM, 360)
    zero = periodic_state(_machine(0.0, polygonal=False), CAM, 360)
    assert np.max(np.abs(half.q_m - zero.q_m)) > 1e-3 * np.abs(zero.q_m).max()
    sizes = []
    for z in (12, 48, 192):
        wheel = Wheel(z, P, 1, tooth_phase=phase)
        a = np.linspace(0.0, wheel.tooth_angle_rad, 401)
        sizes.append(np.max(np.abs(wheel.feed_departure_m(a))))
    assert sizes[1] / sizes[0] == pytest.approx(1 / 16, rel=0.02)
    assert sizes[2] / sizes[1] == pytest.approx(1 / 16, rel=0.01)
    gaps = []
    for z in (48, 192):
        poly, flat = _machine(phase, z), _machine(phase, z, polygonal=False)
        q, v = _random_state(poly, 0)
        angles = np.array([e.wheel.seat_change_angle_rad for e in poly.wheel_ends])
        a = transfer(poly, q, v, angles_rad=angles, zdot_m_s=3.0)
        b = transfer(flat, q, v, angles_rad=angles, zdot_m_s=3.0)
        gaps.append(max(np.max(np.abs(a[0] - b[0])) / np.abs(q).max(), np.max(np.abs(a[1] - b[1])) / np.abs(v).max()))
    assert gaps[1] < gaps[0] / 12  # 1/z^2: 16x per 4x teeth


# --- kinematics --------------------------------------------------------------------------------------


def _strand_end_by_construction(z: int, phase: float, angle: np.ndarray) -> np.ndarray:
    """Planar construction (as tests/test_wheels_kinematics.py) with the teeth turned by the phase:
    at the dwell the pulling pin is at (phase - 1/2) of a tooth from the strand's tangent point."""
    r = pitch_radius_m(P, z)
    tooth = 2 * np.pi / z
    g0 = (phase - 0.5) * tooth
    out = np.empty_like(angle)
    for i, a in enumerate(angle):
        pins = g0 + a - tooth * np.arange(-2 * z, 2 * z)
        j = np.flatnonzero((pins >= -np.pi / z - 1e-15) & (pins < np.pi / z - 1e-15))[0]
        seats = np.round((g0 + a - pins[j]) / tooth)
        out[i] = (r * np.exp(1j * pins[j])).imag + seats * P
    return out - r * np.sin(g0)


@pytest.mark.parametrize("z", [6, 12, 21])
@pytest.mark.parametrize("phase", [0.25, 0.5, 0.8])
def test_the_feed_the_solvers_use_is_the_chordal_construction_with_the_phase(z, phase):
    """Over one index the solvers feed the strand with d(a) (the pin seated at the dwell) before the
    seat change and d(a - tooth) after it (the next pin, the lift counted one pitch on): with the
    mean feed R_m a that is the planar construction's strand end; the seat change is at (1 - phase)
    of a tooth, where the position is continuous and the speed ratio cos(gamma) jumps from cos(pi/z)
    to cos(pi/z) (no jump in speed: the kink of the feed is in its acceleration)."""
    wheel = Wheel(z, P, 1, tooth_phase=phase)
    tooth, rm = wheel.tooth_angle_rad, wheel.feed_radius_m
    a = np.linspace(0.0, tooth, 2001)
    seat = wheel.seat_change_angle_rad
    solver = np.where(a < seat, wheel.feed_departure_m(a), wheel.feed_departure_m(a - tooth)) + rm * a
    construction = _strand_end_by_construction(z, phase, a)
    np.testing.assert_allclose(solver, construction, rtol=0, atol=1e-15)
    np.testing.assert_allclose(wheel.strand_end_m(a), construction, rtol=0, atol=1e-15)
    before, after = wheel.feed_departure_m(seat), wheel.feed_departure_m(seat - tooth)
    assert before == pytest.approx(after, abs=1e-15)
    ratio = 1.0 + np.where(a < seat, wheel.feed_departure_slope(a), wheel.feed_departure_slope(a - tooth)) / rm
    np.testing.assert_allclose(ratio * rm / wheel.pitch_radius_m, wheel.strand_end_speed_ratio(a), atol=1e-15)


@pytest.mark.parametrize("z", [6, 12, 40])
def test_steady_turning_with_the_phase_gives_the_chordal_speed_law(z):
    """omega constant, phase 0.3: strand-end speed omega R cos(gamma) between omega R cos(pi/z) and
    omega R, the seat changes at (1 - 0.3) of a tooth and then every tooth."""
    wheel = Wheel(z, P, 1, tooth_phase=0.3)
    omega = 18.0
    t = np.linspace(0.0, 3 * wheel.tooth_angle_rad / omega, 30001)
    x = wheel.strand_end_m(omega * t)
    v = np.gradient(x, t)
    closed = omega * wheel.pitch_radius_m * wheel.strand_end_speed_ratio(omega * t)
    kinks = np.floor((omega * t - wheel.seat_change_angle_rad) / wheel.tooth_angle_rad)
    smooth = np.ones_like(t, dtype=bool)
    jump = np.flatnonzero(np.diff(kinks))
    smooth[jump] = smooth[jump + 1] = False
    smooth[[0, -1]] = False
    assert jump.size == 3
    np.testing.assert_allclose(
        t[jump] * omega, wheel.seat_change_angle_rad + wheel.tooth_angle_rad * np.arange(3), atol=1e-3 / z
    )
    np.testing.assert_allclose(v[smooth], closed[smooth], rtol=2e-6)
    assert closed.min() >= omega * wheel.pitch_radius_m * np.cos(np.pi / z) * (1 - 1e-12)
    assert closed.max() <= omega * wheel.pitch_radius_m * (1 + 1e-12)


# --- energy ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("held", [False, True])
@pytest.mark.parametrize("polygonal", [False, True])
def test_the_transfer_inside_the_index_changes_the_stored_energy_by_the_seating_losses(held, polygonal):
    """No integrator: at a state inside the index (cam at 3 m/s), stored energy after the transfer
    minus before = -impacts + snaps from verification.machine_energy's independent oracle (the slip in
    the absolute frame). On a compliant drive exactly that; on a sprocket held to the cam the cam
    also does the work of the impulse that brings the arriving link to its tooth's speed c z',
    m c z' (c z' - y'_in - z') (the leaving link's kinetic energy appears as the arriving one's goes
    into the held group, which has no DOF: the two are equal)."""
    machine = _machine(0.4, polygonal=polygonal, held=held)
    tooth = np.array([e.wheel.tooth_angle_rad for e in machine.wheel_ends])
    angles = np.array([e.wheel.seat_change_angle_rad for e in machine.wheel_ends])
    zd = 3.0
    for seed in range(3):
        q, v = _random_state(machine, seed)
        impacts, snaps = seating_energy(machine, q, v, angles, zd)
        q_new, v_new, _, reported = transfer(machine, q, v, angles_rad=angles, zdot_m_s=zd)
        np.testing.assert_allclose(reported, impacts, rtol=1e-12)
        change = machine.stored_energy_J(q_new, v_new, zd, angles - tooth) - machine.stored_energy_J(q, v, zd, angles)
        cam_work = 0.0
        if held:
            ends = machine.wheel_ends[0]
            w = ends.wheel
            c = w.pitch_radius_m * np.cos(w.gamma_at_dwell_rad() + angles[0]) / w.feed_radius_m if polygonal else 1.0
            arriving = int(np.flatnonzero(machine.topology.incidence().toarray()[ends.behind_span] == -1.0)[0])
            cam_work = CHAIN.link_mass_kg * c * zd * (c * zd - v[arriving] - zd)
        size = sum(impacts) + sum(np.abs(snaps)) + abs(cam_work)
        assert min(impacts) > 0 and size > 1e-4
        assert change == pytest.approx(sum(snaps) - sum(impacts) + cam_work, abs=1e-10 * size)


def _check_window(window):
    seating = sum(sum(s.impact_J) + sum(np.abs(s.snap_J)) for s in window.transfers)
    assert seating > 1e-5 * window.work_J
    assert abs(window.imbalance_J) <= 1e-6 * window.work_J
    assert abs(window.imbalance_J) <= 1e-3 * seating


def test_energy_balance_across_a_seat_change_inside_the_index():
    """Work of the drive = dissipation + seating losses (impact, snap) + change of stored energy over
    one index cycle from rest with the seat change at mid-index (phase 0.5), to the tolerance of
    tests/test_machine_energy.py (1e-6 of the work and 1e-3 of the seating terms; measured 6e-11
    and 7e-8)."""
    _check_window(energy_window(_machine(0.5), CAM, 1))


@pytest.mark.slow
@pytest.mark.parametrize("phase", [0.25, 0.75])
@pytest.mark.parametrize("polygonal", [False, True])
def test_energy_balance_across_seat_changes_inside_the_index(phase, polygonal):
    _check_window(energy_window(_machine(phase, polygonal=polygonal), CAM, 2))


# --- the relabelled steady state ---------------------------------------------------------------------


def test_the_polygon_free_relabelled_steady_state_repeats_after_one_index_at_a_phase():
    """x0 = P_2(T(P_1(x0))) at phase 0.3: one index from it (seat change inside) returns to it to
    rounding; marching from rest reaches it."""
    machine = _machine(0.3, polygonal=False)
    steady = periodic_state(machine, CAM, 360)
    t, s, a = cycle_grid(CAM, 360)
    x0 = np.concatenate([steady.q_m[0], steady.v_m_s[0]])
    zdot = _cam_speed(CAM)
    np.testing.assert_allclose(_end_state(machine, x0, t, s, a, True, zdot), x0, rtol=0, atol=1e-12 * np.abs(x0).max())
    x = np.zeros_like(x0)
    for _ in range(40):
        x = _end_state(machine, x, t, s, a, True, zdot)
    np.testing.assert_allclose(x, x0, rtol=0, atol=1e-12 * np.abs(x0).max())


@pytest.mark.slow
@pytest.mark.parametrize("phase", [0.25, 0.5])
def test_the_polygonal_relabelled_steady_state_repeats_after_one_index_at_a_phase(phase):
    """The same with the polygonal feed (integrator, transfer inside the index): to the shooting's
    tolerance, 1e-7 of the state's scale."""
    machine = _machine(phase)
    steady = periodic_state(machine, CAM, 120)
    t, s, a = cycle_grid(CAM, 120)
    x0 = np.concatenate([steady.q_m[0], steady.v_m_s[0]])
    x1 = _end_state(machine, x0, t, s, a, True, _cam_speed(CAM))
    n = x0.size // 2
    assert np.max(np.abs(x1[:n] - x0[:n])) <= 1e-7 * np.abs(x0[:n]).max()
    assert np.max(np.abs(x1[n:] - x0[n:])) <= 1e-7 * np.abs(x0[n:]).max()


# --- the clearance machine ---------------------------------------------------------------------------


@pytest.mark.parametrize("phase", [0.25, 0.5])
def test_free_play_zero_is_the_linear_machine_through_the_seat_change_inside_the_index(phase):
    """Clearance 0: index_cycle's pieces (to the instant, the transfer, on) against the reference
    integrator (DOP853 on the exact cam, the transfer at the instant it locates) over one index
    from rest, 16 links on two 12-tooth wheels: the seat change's instant and seating speeds agree
    to 1e-5, the states to the Verlet step's second-order error (measured 2.5e-3 of the peaks at
    ab2's 0.31 of its limit on 30 links, where the snap's strand waves are short), falling by more
    than 8x when the step is quartered."""
    machine = _machine(phase)
    model = ClearanceMachine(machine, 0.0)
    n = machine.topology.n_dof
    q0 = np.zeros(n)
    samples = 120
    t = CAM.cycle_s * np.arange(samples + 1) / samples
    ref = integrate_cycle(machine, _exact_cam(2), _exact_cam(0), t, q0, q0, zdot=_exact_cam(1))
    errors = []
    for safety in (0.31, 0.31 / 4):
        sub = mv.substeps_for(model, t[1], safety, "ab2")
        nodes = mv.cycle_nodes(CAM, t[1] / sub, samples * sub)
        run, seating = mv.index_cycle(model, CAM, nodes, t[1] / sub, q0, q0, out_every=sub, predictor="ab2")
        assert run.q.shape == ref.q_m.shape
        errors.append(
            max(
                np.max(np.abs(run.q - ref.q_m)) / np.max(np.abs(ref.q_m)),
                np.max(np.abs(run.v - ref.v_m_s)) / np.max(np.abs(ref.v_m_s)),
            )
        )
        np.testing.assert_allclose(seating.speed_m_s, ref.seating[0], rtol=1e-2)
    assert errors[0] < 5e-3
    assert errors[1] < errors[0] / 8


def test_the_clearance_machines_relabelled_steady_state_at_a_phase_repeats_after_one_index():
    """Relabelled steady state of the clearance machine (free play 94 um) with the seat change at
    mid-index: one more index from it returns to it to the marching tolerance."""
    model = ClearanceMachine(_machine(0.5), 94e-6)
    sub = mv.substeps_for(model, CAM.cycle_s / 90, 0.31, "ab2")
    n = 90 * sub
    h = CAM.cycle_s / n
    zeros = np.zeros(model.topology.n_dof)
    q0, v0, _, _, found, last = mv.relabelled_periodic_state(
        model, CAM, h, n, zeros, zeros, tol=1e-9, max_cycles=80, predictor="ab2"
    )
    assert found
    run, seating = mv.index_cycle(model, CAM, mv.cycle_nodes(CAM, h, n), h, q0, v0, out_every=sub, predictor="ab2")
    assert seating is not None and min(seating.speed_m_s) > 0
    assert np.max(np.abs(run.q[-1] - q0)) < 1e-8 * np.max(np.abs(run.q))
    assert np.max(np.abs(run.v[-1] - v0)) < 1e-8 * np.max(np.abs(run.v))


def test_the_clearance_machines_energy_balance_across_seat_changes_inside_the_index():
    """As tests/test_clearance_machine.py's balance at phase 0, with the seat change at mid-index
    (phase 0.5; 16 links, tensioned idler wheel, compliant drive, polygonal feed, friction 0.35, free
    play with impacts, two index cycles): cam work = damping and friction dissipation + the seat
    changes' change of stored energy (machine_verlet.seat_change_inside) + the change of stored
    energy. The powers are integrated trapezoidally over the pieces, so the residual is the step's
    second-order error: it falls more than 10x from 400 to 1600 steps per cam degree (measured
    1.7e-6 -> 1.1e-7 of the cam work, 44 impacts), below the phase-0 test's 1e-6."""
    from dynamics.models.clearance import Tensioner

    w = Wheel(12, P, 3, 0.3, tooth_phase=0.5)
    chain = ChainModel(16, 2.03, 2e7, preload_N=2224.0, damping_ratio=0.13, friction_coefficient=0.35)
    layout = MachineLayout("wheels", w, Wheel(12, P, 2, 0.1, tooth_phase=0.5), 2e6, True)
    model = ClearanceMachine.of(chain, layout, Tensioner(2e5, 20.0, 500.0), 94e-6)
    residuals = []
    for sub in (400, 1600):
        h = CAM.cycle_s / (90 * sub)
        nodes = mv.cycle_nodes(CAM, h, 90 * sub)
        q = v = np.zeros(model.topology.n_dof)
        start = model.stored_energy_J(q, v, nodes[1][0], 0.0)
        work = dissipated = seat_changes = 0.0
        impacts = 0
        for _ in range(2):
            r, seating = mv.index_cycle(model, CAM, nodes, h, q, v, out_every=sub, predictor="euler", track_energy=True)
            work += r.cam_work_J
            dissipated += r.dissipated_damping_J + r.dissipated_friction_J
            impacts += r.impacts
            seat_changes += seating.transfer_energy_change_J
            q, v = r.q[-1], r.v[-1]
        end = model.stored_energy_J(q, v, nodes[1][0], 0.0)
        residuals.append(abs(work - dissipated + seat_changes - (end - start)) / abs(work))
    assert impacts > 10
    assert residuals[1] < residuals[0] / 10
    assert residuals[1] < 1e-6


def test_the_seat_change_instant_on_the_cams_law_and_on_its_samples():
    """The one root of the lift (machine_ivp.seat_change_time_s) through its two forms: on the cam's
    law (the compiled step and the verdict before the run) and on the lift sampled on the steady
    state's grid (linear between samples): the lift there is the seat change's, and the sampled
    instant is within linear interpolation's bound of the law's: a lift error of at most
    h^2 max|z''| / 8 over the cam's speed there."""
    from dynamics.solvers.machine_ivp import cam_lift_m, cam_seat_change_s, sampled_seat_change_s

    lift = 0.75 * P  # tooth phase 0.25
    t_seat = cam_seat_change_s(CAM, CAM.period_s, lift)
    assert 0.0 < t_seat < CAM.period_s
    assert cam_lift_m(CAM, t_seat) - cam_lift_m(CAM, 0.0) == pytest.approx(lift, rel=1e-12)
    _, speed, _, _ = CAM.svaj(np.array([t_seat]))
    dense = CAM.svaj(np.linspace(0.0, CAM.period_s, 20001))[2]
    for samples in (90, 180, 360):
        t, s, _ = cycle_grid(CAM, samples)
        h = t[1] - t[0]
        bound = h**2 * np.max(np.abs(dense)) / 8 / abs(speed[0])
        assert 0.0 < abs(sampled_seat_change_s(t, s, lift) - t_seat) <= bound
    assert sampled_seat_change_s(t, s, None) is None  # tooth phase 0: at the dwell
    with pytest.raises(DynamicsError, match="seat change"):
        cam_seat_change_s(CAM, CAM.period_s, 1.5 * P)  # more than an index's lift
