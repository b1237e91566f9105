"""dynamics.models.machine: the linear chain on its wheels reduces to today's chain in each limit where both
hold, its reference integrator agrees with the exact solver, and the issue's frequency figure."""

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain, Tensioner
from dynamics.models.machine import MachineOnWheels
from dynamics.models.system import SampledForce
from dynamics.models.wheels import Wheel
from dynamics.solvers import solve
from dynamics.solvers.machine_ivp import integrate_cycle

P = 0.1125
# the default scene: aluminium link from `python -m fem` (built-in link, al6061-t6), its body mass plus
# the default hardware (geometry.dimensions.DEFAULT_HARDWARE_MASS_KG) and nest (NEST_MASS_KG)
K_AL = 93309880.76383373
M_AL = 0.3729267739202092 + 0.72707182320442 + 0.93


def _cam(rpm=180.0):
    return CamProgram.indexing("modified-sine", pitch_m=P, rpm=rpm)


def _exact(system, load, cam, t, q0=None, v0=None):
    zdd = cam.svaj(t)[2]
    force = SampledForce(t, -np.outer(zdd, load))
    n = load.size
    return solve(
        system, force, t, method="exact", x0=np.zeros(n) if q0 is None else q0, v0=np.zeros(n) if v0 is None else v0
    )


def test_drive_link_is_todays_chain():
    chain = ChainModel(20, 2.03, 9.3e7, damping_ratio=0.13, preload_N=1500.0)
    machine = MachineOnWheels(chain, drive="link")
    today = chain.system()
    ours = machine.system()
    for a, b in ((ours.mass, today.mass), (ours.damping, today.damping), (ours.stiffness, today.stiffness)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(machine.inertial_load(), chain.mass_matrix() @ np.ones(20))


@pytest.mark.parametrize("n, kd, zeta", [(8, None, 0.13), (20, 3e7, 0.05), (85, None, 0.13)])
def test_a_one_link_sprocket_with_the_equivalent_drive_is_todays_driven_link(n, kd, zeta):
    chain = ChainModel(n, 2.03, 9.3e7, drive_stiffness_N_per_m=kd, damping_ratio=zeta)
    wheel = Wheel(12, P, 1)
    machine = MachineOnWheels(
        chain,
        sprocket=wheel,
        polygonal=False,
        drive_torsional_stiffness_N_m_per_rad=chain.drive_stiffness * wheel.feed_radius_m**2,
    )
    today, ours = chain.system(), machine.system()
    scale = chain.stiffness_N_per_m
    np.testing.assert_allclose(ours.stiffness, today.stiffness, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(ours.mass, today.mass, rtol=0, atol=1e-15)
    np.testing.assert_allclose(ours.damping, today.damping, rtol=0, atol=1e-12 * np.abs(today.damping).max())
    cam = _cam()
    t = np.linspace(0.0, 2 * cam.cycle_s, 721)
    a = _exact(today, chain.mass_matrix() @ np.ones(n), cam, t)
    b = _exact(ours, machine.inertial_load(), cam, t)
    np.testing.assert_allclose(b.x, a.x, rtol=0, atol=1e-12 * np.abs(a.x).max())


@pytest.mark.parametrize("n", [5, 16, 85])
def test_an_infinitely_stiff_drive_on_one_seated_link_holds_link_1_to_the_cam(n):
    chain = ChainModel(n, 2.03, 9.3e7)
    machine = MachineOnWheels(
        chain, sprocket=Wheel(12, P, 1), drive_torsional_stiffness_N_m_per_rad=np.inf, polygonal=False
    )
    np.testing.assert_array_equal(machine.stiffness_matrix(), chain.stiffness_matrix()[1:, 1:])
    np.testing.assert_allclose(
        machine.natural_frequencies_Hz(), chain.natural_frequencies_Hz(driven_link_held=True), rtol=1e-12
    )
    assert machine.topology.link_dof()[0] == -1  # link 1 is nobody's DOF: it moves with the cam


def test_an_idler_of_one_seated_link_without_inertia_on_a_fixed_axle_is_a_plain_link():
    chain = ChainModel(21, 2.03, 9.3e7)
    sprocket = Wheel(12, P, 3, inertia_kg_m2=0.4)
    plain = MachineOnWheels(chain, sprocket=sprocket, polygonal=False)
    with_idler = MachineOnWheels(chain, sprocket=sprocket, idler=Wheel(12, P, 1), polygonal=False)
    np.testing.assert_array_equal(with_idler.stiffness_matrix(), plain.stiffness_matrix())
    np.testing.assert_array_equal(with_idler.mass_matrix(), plain.mass_matrix())


@pytest.mark.parametrize("tensioner", [Tensioner(2.5e5, 12.0, 300.0), Tensioner(0.0, 3.0)])
def test_todays_idler_point_with_its_carriage_is_the_clearance_chains(tensioner):
    chain = ChainModel(17, 2.03, 9.3e7)
    k_old, m_old = ClearanceChain(chain, 0.0, tensioner=tensioner).full_contact_stiffness()
    machine = MachineOnWheels(chain, drive="link", tensioner=tensioner)
    np.testing.assert_allclose(machine.stiffness_matrix(), k_old, rtol=0, atol=1e-12 * 9.3e7)
    np.testing.assert_array_equal(machine.mass_matrix(), m_old)
    # the same idler point behind a one-link sprocket with the equivalent drive
    wheel = Wheel(12, P, 1)
    wheels = MachineOnWheels(
        chain,
        sprocket=wheel,
        tensioner=tensioner,
        polygonal=False,
        drive_torsional_stiffness_N_m_per_rad=chain.drive_stiffness * wheel.feed_radius_m**2,
    )
    np.testing.assert_allclose(wheels.stiffness_matrix(), k_old, rtol=0, atol=1e-12 * 9.3e7)


def test_the_integrator_agrees_with_the_exact_solver_on_the_linear_model():
    """Same ODE (the cam's acceleration held linearly between the samples, as the exact solver takes
    it): the difference is DOP853's global error at rtol 1e-11, about 1e-9 of the peak."""
    chain = ChainModel(12, 2.03, 2e7)
    machine = MachineOnWheels(
        chain,
        sprocket=Wheel(12, P, 3, inertia_kg_m2=0.3),
        idler=Wheel(12, P, 2),
        tensioner=Tensioner(2e5, 8.0, 200.0),
        polygonal=False,
    )
    cam = _cam()
    t = np.linspace(0.0, cam.cycle_s, 361)
    zdd = cam.svaj(t)[2]
    ref = _exact(machine.system(), machine.inertial_load(), cam, t)
    n = machine.topology.n_dof
    ivp = integrate_cycle(machine, lambda s: np.interp(s, t, zdd), lambda s: 0.0, t, np.zeros(n), np.zeros(n))
    np.testing.assert_allclose(ivp.q_m, ref.x, rtol=0, atol=1e-8 * np.abs(ref.x).max())


def _polygon_gap(z: int) -> float:
    chain = ChainModel(8, 2.03, 5e6)
    cam = _cam()
    t = np.linspace(0.0, cam.cycle_s, 181)
    s, _, a, _ = cam.svaj(t)
    runs = []
    for polygonal in (False, True):
        machine = MachineOnWheels(
            chain, sprocket=Wheel(z, P, 2, inertia_kg_m2=0.05), idler=Wheel(z, P, 2), polygonal=polygonal
        )
        n = machine.topology.n_dof
        runs.append(
            integrate_cycle(
                machine,
                lambda x: np.interp(x, t, a),
                lambda x: np.interp(x, t, s),
                t,
                np.zeros(n),
                np.zeros(n),
                rtol=1e-10,
            ).q_m
        )
    return float(np.max(np.abs(runs[1] - runs[0])) / np.max(np.abs(runs[0])))


def test_many_teeth_remove_the_polygonal_action():
    """The feed's departure and the seated pins' extra inertia both vanish as z^-2: the polygonal
    model's response tends to the polygon-free one at that rate."""
    gaps = [_polygon_gap(z) for z in (40, 80, 160)]
    assert gaps[0] > 1e-4  # a visible effect at 40 teeth
    for coarse, fine in zip(gaps, gaps[1:]):
        assert 3.5 < coarse / fine < 4.5  # second order in 1/z
    assert gaps[-1] < 1e-3


def test_the_issues_frequency_figure_on_the_default_scene():
    """Issue #22: holding the six links seated on the sprocket to the cam moves the first natural
    frequency of the default scene (85 aluminium links) from 38.1 Hz to 42.4 Hz."""
    chain = ChainModel(85, M_AL, K_AL)
    held = MachineOnWheels(
        chain, sprocket=Wheel(12, P, 6), drive_torsional_stiffness_N_m_per_rad=np.inf, polygonal=False
    )
    assert MachineOnWheels(chain, drive="link").natural_frequencies_Hz()[0] == pytest.approx(38.1, abs=0.05)
    assert held.natural_frequencies_Hz()[0] == pytest.approx(42.4, abs=0.05)
    # closed form: 79 free links between two ends held to the cam, a fixed-fixed string of 80 spans
    assert held.natural_frequencies_Hz()[0] == pytest.approx(
        2 * np.sqrt(K_AL / M_AL) * np.sin(np.pi / (2 * 80)) / (2 * np.pi), rel=1e-12
    )


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(drive="belt"), "drive"),
        (dict(drive="wheels"), "sprocket"),
        (dict(drive="wheels", sprocket=Wheel(12, P, 6), drive_torsional_stiffness_N_m_per_rad=-1.0), "drive_torsional"),
        (
            dict(drive="wheels", sprocket=Wheel(12, P, 6, tooth_phase=0.5), idler=Wheel(12, P, 6, tooth_phase=0.25)),
            "tooth_phase",
        ),
    ],
)
def test_bad_machines_are_refused(kwargs, match):
    with pytest.raises(DynamicsError, match=match):
        MachineOnWheels(ChainModel(20, 2.0, 1e8), **kwargs)


def _steady_machines():
    chain = ChainModel(16, 2.03, 9.3e7)
    return [
        MachineOnWheels(
            chain,
            sprocket=Wheel(12, P, 3, inertia_kg_m2=0.3),
            idler=Wheel(12, P, 2, inertia_kg_m2=0.1),
            tensioner=Tensioner(2e5, 8.0, 200.0),
            polygonal=False,
        ),
        MachineOnWheels(chain, sprocket=Wheel(12, P, 3), drive_torsional_stiffness_N_m_per_rad=np.inf, polygonal=False),
    ]


@pytest.mark.parametrize("machine", _steady_machines(), ids=["compliant-drive-idler-carriage", "held-sprocket"])
def test_the_relabelled_steady_state_repeats_after_one_index(machine):
    """x0 = T(P(x0)): propagated over one index by the exact solver and relabelled by one link, the
    state comes back to itself (rounding); marching 40 indexes from rest reaches it too (the slowest
    mode loses a factor of about 200 per index)."""
    from dynamics.solvers.machine_steady import _end_state, cycle_grid, periodic_state

    cam = _cam()
    steady = periodic_state(machine, cam, 360)
    x0 = np.concatenate([steady.q_m[0], steady.v_m_s[0]])
    t, s, a = cycle_grid(cam, 360)
    assert np.max(np.abs(x0)) > 0
    np.testing.assert_allclose(_end_state(machine, x0, t, s, a, True), x0, rtol=0, atol=1e-12 * np.abs(x0).max())
    x = np.zeros_like(x0)
    for _ in range(40):
        x = _end_state(machine, x, t, s, a, True)
    np.testing.assert_allclose(x, x0, rtol=0, atol=1e-12 * np.abs(x0).max())


@pytest.mark.slow
def test_the_polygonal_relabelled_steady_state_repeats_after_one_index():
    """The same with the polygonal feed (integrator and nonlinear transfer): to the shooting's
    tolerance, 1e-7 of the state's scale."""
    from dynamics.solvers.machine_steady import _end_state, cycle_grid, periodic_state

    chain = ChainModel(16, 2.03, 2e7)
    machine = MachineOnWheels(chain, sprocket=Wheel(12, P, 3, inertia_kg_m2=0.3), idler=Wheel(12, P, 2))
    cam = _cam()
    steady = periodic_state(machine, cam, 360)
    x0 = np.concatenate([steady.q_m[0], steady.v_m_s[0]])
    t, s, a = cycle_grid(cam, 360)
    x1 = _end_state(machine, x0, t, s, a, True)
    n = x0.size // 2
    assert np.max(np.abs(x1[:n] - x0[:n])) <= 1e-7 * np.abs(x0[:n]).max()
    assert np.max(np.abs(x1[n:] - x0[n:])) <= 1e-7 * np.abs(x0[n:]).max()


def test_the_issues_residual_vibration_figure_on_the_default_scene():
    """Issue #22, from an independent eigen- and time-domain model: on the default scene (modified
    sine, 180 rpm, zeta 0.13) holding the six seated links to the cam moves the tight-side residual
    vibration (link 64) from 4.17 mm to 3.42 mm and the peak acceleration by +8 %. Same links seated
    every cycle (the frame of that model); the issue's 4.17 is this model's 4.164 (its k or sampling
    differed slightly), hence 0.01 mm."""
    from dynamics.solvers.machine_steady import labelled_periodic_state, link_residual_and_peak

    chain = ChainModel(85, M_AL, K_AL)
    cam = _cam()
    out = []
    for machine in (
        MachineOnWheels(chain, drive="link"),
        MachineOnWheels(chain, sprocket=Wheel(12, P, 6), drive_torsional_stiffness_N_m_per_rad=np.inf, polygonal=False),
    ):
        r = labelled_periodic_state(machine, cam, 360)
        out.append(link_residual_and_peak(machine, r, cam.dwell_mask(r.t_s), 63))
    (today, peak_today), (seated, peak_seated) = out
    assert today * 1e3 == pytest.approx(4.17, abs=0.01)
    assert seated * 1e3 == pytest.approx(3.42, abs=0.005)
    assert peak_seated / peak_today - 1 == pytest.approx(0.08, abs=0.005)


@pytest.mark.parametrize("held", [False, True])
def test_the_polygonal_forces_derive_from_the_span_energy(held):
    """The machine's elastic force with the polygonal feed is -grad V of the spans' energy
    V = sum (P e + k e^2 / 2) - 2 P u_carriage + ground springs, the wheel-end stretches carrying the
    feed's departure d(a): the model is a Lagrangian system (checked by central differences)."""
    chain = ChainModel(14, 2.03, 9.3e7, preload_N=2224.0)
    machine = MachineOnWheels(
        chain,
        sprocket=Wheel(12, P, 3, inertia_kg_m2=0.3),
        idler=Wheel(12, P, 2),
        tensioner=Tensioner(2e5, 8.0),
        polygonal=True,
        drive_torsional_stiffness_N_m_per_rad=np.inf if held else 3e6,
    )
    topo = machine.topology
    b = topo.incidence().toarray()
    angles = np.array([0.21, 0.37])  # the wheels' nominal angles since the dwell (rad)

    def energy(q):
        e = b @ q
        for ends, angle in zip(machine.wheel_ends, angles):
            u = 0.0 if ends.dof is None else q[ends.dof]
            d = ends.wheel.feed_departure_m(angle + u / ends.wheel.feed_radius_m)
            e[ends.behind_span] += d
            e[ends.ahead_span] -= d
        ground = sum(0.5 * kg * q[dof] ** 2 for dof, kg in topo.ground)
        return (
            float(np.sum(chain.preload_N * e + 0.5 * chain.stiffness_N_per_m * e**2))
            + ground
            - 2 * chain.preload_N * q[-1]
        )

    rng = np.random.default_rng(3)
    q = 1e-4 * rng.standard_normal(topo.n_dof)
    h = 1e-7
    grad = np.array([(energy(q + h * e) - energy(q - h * e)) / (2 * h) for e in np.eye(topo.n_dof)])
    force = -(machine.stiffness_matrix() @ q) + machine.polygon_force(angles, q)
    np.testing.assert_allclose(force, -grad, rtol=0, atol=1e-9 * np.abs(grad).max())  # difference rounding
    assert np.max(np.abs(machine.polygon_force(angles, q))) > 1e-2 * np.abs(grad).max()  # and the feed counts
    assert machine.stored_energy_J(q, np.zeros_like(q), 0.0, angles) == pytest.approx(energy(q), rel=1e-12)


@pytest.mark.slow
def test_energy_balance_of_the_polygonal_machine_over_an_index():
    """Work of the cam = dissipation + change of kinetic and elastic energy over one index cycle (issue
    #22 asks 1e-6; measured 3e-13 of the cam's work, asserted 1e-9). Absolute frame: kinetic 1/2 sum M (q' + z')^2 (the carriage
    without z'), elastic V(q, t) as in the gradient test, with the feed's departure moving with the
    cam; the cam's power is -z' 1^T (dV/dq + C q') + dV/dt (dV/dt by central differences in t), the
    damping's q'^T C q'; integrals by Simpson's rule on 20 000 intervals (error ~1e-9 here)."""
    from scipy.integrate import simpson

    chain = ChainModel(14, 2.03, 2e7, preload_N=2224.0)
    machine = MachineOnWheels(
        chain,
        sprocket=Wheel(12, P, 3, inertia_kg_m2=0.3),
        idler=Wheel(12, P, 2),
        tensioner=Tensioner(2e5, 8.0, 150.0),
        drive_torsional_stiffness_N_m_per_rad=2e6,
    )
    cam = _cam()
    topo = machine.topology
    b = topo.incidence().toarray()
    radii = np.array([e.wheel.feed_radius_m for e in machine.wheel_ends])
    moves = np.array([1.0 if carried else 0.0 for carried in topo.links])
    k_mat, c_mat = machine.stiffness_matrix(), machine.damping_matrix()
    masses = np.diag(machine.mass_matrix())

    def lift(t):
        return float(cam.svaj(np.array([t]))[0][0])

    def energy(q, t):
        e = b @ q
        for ends, r in zip(machine.wheel_ends, radii):
            u = 0.0 if ends.dof is None else q[ends.dof]
            d = ends.wheel.feed_departure_m(lift(t) / r + u / r)
            e[ends.behind_span] += d
            e[ends.ahead_span] -= d
        ground = sum(0.5 * kg * q[dof] ** 2 for dof, kg in topo.ground)
        return (
            float(np.sum(chain.preload_N * e + 0.5 * chain.stiffness_N_per_m * e**2))
            + ground
            - 2 * chain.preload_N * q[-1]
        )

    t = np.linspace(0.0, cam.cycle_s, 20001)
    n = topo.n_dof
    run = integrate_cycle(
        machine, lambda s: float(cam.svaj(np.array([s]))[2][0]), lift, t, np.zeros(n), np.zeros(n), rtol=1e-12
    )
    zd = cam.svaj(t)[1]
    total, power, loss = np.empty(t.size), np.empty(t.size), np.empty(t.size)
    h = 1e-7
    for i, (ti, q, v) in enumerate(zip(t, run.q_m, run.v_m_s)):
        dv_dq = k_mat @ q - machine.polygon_force(lift(ti) / radii, q)
        dv_dt = (energy(q, ti + h) - energy(q, ti - h)) / (2 * h)
        total[i] = 0.5 * np.sum(masses * (v + moves * zd[i]) ** 2) + energy(q, ti)
        power[i] = -zd[i] * moves @ (dv_dq + c_mat @ v) + dv_dt
        loss[i] = v @ c_mat @ v
    work, dissipated = simpson(power, x=t), simpson(loss, x=t)
    assert dissipated > 1e-3 * simpson(np.abs(power), x=t)  # the damping takes a real share
    assert total[-1] - total[0] == pytest.approx(work - dissipated, abs=1e-9 * simpson(np.abs(power), x=t))


def test_stations_are_places_on_the_machine():
    """85 links, six on each wheel: sprocket links 0-5, slack strand 6-41 (36), idler 42-47, tight
    strand 48-84 (37); each station is the middle link of its stretch (0-based)."""
    chain = ChainModel(85, 2.03, 9.3e7)
    machine = MachineOnWheels(chain, sprocket=Wheel(12, P, 6), idler=Wheel(12, P, 6))
    assert machine.stations() == {"drive-end": 2, "tight-side": 66, "idler-end": 44, "slack-side": 23}
    assert machine.groups[0] == tuple(range(6)) and machine.groups[machine.idler_place] == tuple(range(42, 48))
    # without an idler wheel the idler end is today's idler span's link (43, 1-based)
    assert MachineOnWheels(chain, sprocket=Wheel(12, P, 6)).stations()["idler-end"] == 42
    assert MachineOnWheels(chain, drive="link").stations() == {
        "drive-end": 0,
        "tight-side": 63,
        "idler-end": 42,
        "slack-side": 20,
    }
