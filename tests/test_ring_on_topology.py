"""The single-link drive (the ring: the cam drives link 1 through k_d) as one more description of the
chain topology (issue #22, Architecture): `ClearanceMachine.of(chain, LINK_DRIVE, ...)`, stepped by the
machine's compiled step (dynamics.solvers.machine_verlet), against today's ring (ClearanceChain and its
own kernel dynamics.solvers.clearance_verlet), and the linear machine on that layout against the linear
chain (ChainModel, dynamics.solvers.simulate).

Where the arithmetic is the same the two agree to 1e-12 (the matrices bit for bit, the trajectories
through hundreds of impacts to rounding: the kernels sum the global law's C w in different orders,
the ring in its mirror blocks), the impact measurements included: both take an impact's closing
speed, force spike window and Kelvin-Voigt dissipation at the crossing interpolated within the step.
"""

import dataclasses

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.errors import DynamicsError
from dynamics.models import clearance_machine
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain, Tensioner
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import LINK_DRIVE
from dynamics.models.machine import MachineOnWheels, modal_damping_matrix
from dynamics.options import DEFAULT_PIN_CLEARANCE_M
from dynamics.scene import simulate_chain
from dynamics.solvers import clearance_verlet as cv
from dynamics.solvers import machine_verlet as mv
from dynamics.solvers import ring_on_topology
from dynamics.solvers.machine_steady import periodic_state
from dynamics.solvers.simulate import SlackChainWarning, simulate

PITCH_M, K, M, N = 0.1125, 9.331e7, 2.03, 85
CLEARANCE_M = DEFAULT_PIN_CLEARANCE_M
TENSIONER = Tensioner(1e5, 5.0, 100.0)


def _cam():
    return CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180)


def _both(law, tensioner, friction, clearance=CLEARANCE_M):
    chain = ChainModel(N, M, K, friction_coefficient=friction)
    ring = ClearanceChain(chain, clearance, span_damping=law, tensioner=tensioner)
    return ring, ClearanceMachine.of(chain, LINK_DRIVE, tensioner, clearance, law)


def _start():
    """A disturbed state (the same for every case): hundreds of impacts within the first index cycle."""
    rng = np.random.default_rng(1)
    return 1e-4 * rng.standard_normal(N), 1e-2 * rng.standard_normal(N)


def _one_cycle(ring, machine, steps_factor=1, out_every=10, track_energy=False):
    """Both kernels over one index cycle from `_start` at the ring's default step (predictor and
    safety), divided by `steps_factor`."""
    cam = _cam()
    predictor = cv.default_predictor(ring)
    n = int(cam.cycle_s / cv.stable_step_s(ring, cv.default_safety(ring, predictor), predictor)) + 1
    n = steps_factor * (n + out_every - n % out_every)
    h = cam.cycle_s / n
    zr, zd, zdd = mv.cycle_nodes(cam, h, n)
    y0, w0 = _start()
    old = cv.integrate(ring, zd, zdd, h, y0, w0, out_every=out_every, predictor=predictor, track_energy=track_energy)
    extra = [0.0] if ring.tensioner is not None else []
    new = mv.integrate(
        machine,
        zr,
        zd,
        zdd,
        h,
        np.r_[y0, extra],
        np.r_[w0, extra],
        out_every=out_every,
        predictor=predictor,
        track_energy=track_energy,
    )
    return old, new


def _apart(new, old) -> float:
    return float(np.max(np.abs(np.asarray(new) - old)) / np.max(np.abs(old)))


@pytest.mark.parametrize("tensioner", [None, TENSIONER])
def test_the_link_drive_derives_the_rings_matrices_bit_for_bit(tensioner):
    """The ring's topology (ring_topology, with the carriage inside span round(N/2) - 1) gives the
    clearance chain's full-contact K and M, its damping matrix C (the carriage's c_t beside it) and
    its highest full-contact frequency, which sets the step, exactly; and the Kelvin-Voigt factor."""
    ring, machine = _both("global", tensioner, 0.35)
    k, m = ring.full_contact_stiffness()
    assert np.array_equal(machine.machine.stiffness_matrix(), k)
    assert np.array_equal(machine.machine.mass_matrix(), m)
    assert np.array_equal(machine.damping_matrix[:N, :N], ring.damping_matrix)
    if tensioner is not None:
        assert machine.damping_matrix[N, N] == tensioner.damping_N_s_per_m
        assert not np.any(machine.damping_matrix[N, :N]) and not np.any(machine.damping_matrix[:N, N])
    assert machine.max_frequency_rad_s == ring.max_frequency_rad_s()
    assert machine.beta_s == ring.beta_s
    omega = ring.max_frequency_rad_s()
    assert mv.stable_step_s(machine, 0.31, "ab2") == cv.stable_step_s(ring, 0.31, "ab2")
    assert machine.damping_ratio_at(omega) == ring.damping_ratio_at(omega)


def test_the_linear_machine_on_the_link_drive_is_the_linear_chain():
    """MachineOnWheels(drive='link') is ChainModel: the same M, C, K (bit for bit) and natural
    frequencies; its exact periodic state (dynamics.solvers.machine_steady, labelled: the link drive
    has no seats to change) equals dynamics.solvers.simulate's exact steady state on the same samples,
    positions and velocities to 1e-12; the accelerations to 5e-11 of their peak (measured 6e-12): the
    two solvers rebuild them in different arithmetic (the machine's from -(K y + C y') / m - z'', the
    exact solver's from its propagated state, 3e-9 m/s^2 from that formula on its own state), and
    -(K y + C y') cancels terms 1e2 times larger than the accelerations' peak."""
    chain = ChainModel(N, M, K)
    machine = MachineOnWheels(chain, drive="link", polygonal=False)
    k, m = machine.stiffness_matrix(), machine.mass_matrix()
    assert np.array_equal(k, chain.stiffness_matrix())
    assert np.array_equal(m, chain.mass_matrix())
    # the machine's damping built on the topology's K and M (as with a tensioner or on wheels)
    assert np.array_equal(modal_damping_matrix(k, m, chain.damping_ratio), chain.damping_matrix())
    np.testing.assert_allclose(machine.natural_frequencies_Hz(), chain.natural_frequencies_Hz(), rtol=1e-12)
    cam = _cam()
    state = periodic_state(machine, cam, 360, relabel=False)
    with pytest.warns(SlackChainWarning):  # the linear chain pushes on this scene: its own warning
        lin = simulate(chain, cam, state.t_s, steady_state=True)
    y = lin.x_m - lin.z_m[:, None]
    w = lin.v_m_s - lin.zdot_m_s[:, None]
    a = lin.a_m_s2 - lin.zddot_m_s2[:, None]
    assert _apart(state.q_m, y) < 1e-12
    assert _apart(state.v_m_s, w) < 1e-12
    assert _apart(state.a_m_s2, a) < 5e-11


@pytest.mark.parametrize("law", ["global", "kelvin-voigt"])
@pytest.mark.parametrize("tensioner", [None, TENSIONER])
@pytest.mark.parametrize("friction", [0.0, 0.35])
def test_the_ring_on_the_topology_kernel_is_todays_ring(law, tensioner, friction):
    """One index cycle through hundreds of impacts at the ring's default step and predictor: every
    output sample's positions, velocities, accelerations (and the carriage's), the span tensions, the
    energy terms (cam work, damping and friction dissipation) to 1e-12; the impact count and the
    free-play fraction exactly; the peak and minimum tension and the force spike to 1e-12."""
    ring, machine = _both(law, tensioner, friction)
    old, new = _one_cycle(ring, machine, track_energy=True)
    assert _apart(new.q[:, :N], old.y) < 1e-12
    assert _apart(new.v[:, :N], old.w) < 1e-12
    assert _apart(new.a[:, :N], old.a) < 1e-12
    if tensioner is not None:
        assert _apart(new.q[:, N], old.u) < 1e-12
        assert _apart(new.v[:, N], old.ud) < 1e-12
    assert _apart(new.tension_N, ring.tension_N(old.y, old.u)) < 1e-12
    assert old.impacts > 300 and new.impacts == old.impacts
    assert new.free_play_fraction == old.free_play_fraction
    for name in ("peak_tension_N", "min_tension_N", "impact_force_spike_N"):
        assert getattr(new, name) == pytest.approx(getattr(old, name), rel=1e-12), name
    for name in ("cam_work_J", "dissipated_damping_J", "dissipated_friction_J"):
        assert getattr(new, name) == pytest.approx(getattr(old, name), rel=1e-12, abs=1e-12), name


def test_free_play_zero_on_both_kernels_is_the_same_linear_step():
    """Clearance 0 (the span law is linear): both kernels take the same steps, to 1e-12."""
    ring, machine = _both("global", None, 0.0, clearance=0.0)
    old, new = _one_cycle(ring, machine)
    assert old.impacts == new.impacts == 0
    assert _apart(new.q, old.y) < 1e-12
    assert _apart(new.v, old.w) < 1e-12


@pytest.mark.parametrize("law", ["global", "kelvin-voigt"])
@pytest.mark.parametrize("tensioner", [None, TENSIONER])
def test_the_impact_measurements_are_the_rings(law, tensioner):
    """Both kernels take each impact's closing speed at the crossing interpolated within the step
    (extrapolated from the free-play side with the span's acceleration at the step's start), its
    force spike over one impact duration counted from the crossing and the Kelvin-Voigt contact's
    dissipation from and to the crossings: through hundreds of impacts the paired closing speeds, the
    approach energy, the largest closing speed, the force spike and the contacts' dissipation to
    1e-12, at the default step and at a quarter of it; and the largest force over each whole contact
    begun by an impact (at least the spike, which is its first impact duration's)."""
    ring, machine = _both(law, tensioner, 0.35)
    for factor in (1, 4):
        old, new = _one_cycle(ring, machine, steps_factor=factor)
        assert old.impacts > 300 and new.impacts == old.impacts
        assert new.impact_speeds_m_s.size == old.impact_speeds_m_s.size == min(old.impacts, cv.SPEED_CAPACITY)
        assert _apart(new.impact_speeds_m_s, old.impact_speeds_m_s) < 1e-12
        for name in (
            "impact_force_spike_N",
            "impact_kinetic_energy_J",
            "impact_max_speed_m_s",
            "peak_force_in_impact_contact_N",
        ):
            assert getattr(new, name) == pytest.approx(getattr(old, name), rel=1e-12), name
        assert new.peak_force_in_impact_contact_N >= new.impact_force_spike_N > 0.0
        assert new.impact_dissipated_J == pytest.approx(old.impact_dissipated_J, rel=1e-12, abs=1e-15)
        if law == "kelvin-voigt":
            assert old.impact_dissipated_J > 0.0


@pytest.mark.parametrize("tensioner", [None, TENSIONER])
@pytest.mark.parametrize("n_links", [N, 24])
def test_the_rings_mirror_product_on_the_machine_kernel_is_c_times_w(tensioner, n_links):
    """The ring's machine (ring_on_topology.RingMachine) takes the global law's C w in the two blocks
    of the loop's mirror symmetry, stacked in its packed C (machine_verlet.mirror_packed), and the
    machine's step multiplies them by the ring's own product (clearance_verlet._mirror_product, the
    blocks as row slices, odd and even N): C w of the whole C (the links' block; the carriage's c_t
    becomes its own dashpot, bit for bit) to 1e-13 of its size."""
    chain = ChainModel(n_links, M, K)
    machine = ring_on_topology.RingMachine.of(chain, LINK_DRIVE, tensioner, CLEARANCE_M)
    arr, c = machine.arrays, machine.damping_matrix
    assert arr.par.shape[0] == mv.N_PAR + 2
    if tensioner is not None:
        assert arr.dof_float[n_links, 3] == tensioner.damping_N_s_per_m
    w = np.random.default_rng(2).standard_normal(n_links)
    rs = int(arr.par[mv.N_PAR])
    assert int(arr.par[mv.N_PAR + 1]) == n_links
    cols, rows = np.zeros((2, arr.cmat.shape[1])), np.zeros(arr.cmat.shape[0])
    out = np.zeros(n_links)
    cv._mirror_product(arr.cmat[:rs], arr.cmat[rs:], n_links, w, *cols, rows[:rs], rows[rs:], out)
    cw = c[:n_links, :n_links] @ w
    assert _apart(out, cw) < 1e-13


@pytest.mark.parametrize("law", ["global", "kelvin-voigt"])
@pytest.mark.parametrize("tensioner", [None, TENSIONER])
def test_ring_on_topology_gives_the_rings_run(law, tensioner):
    """ring_on_topology.integrate (the ring's machine, the global law's mirror product) against the
    ring's own kernel over one index cycle through hundreds of impacts: every field of the Run, the
    largest force over the contacts begun by impacts included, to 1e-12."""
    ring, _ = _both(law, tensioner, 0.35)
    cam = _cam()
    predictor = cv.default_predictor(ring)
    n = 10 * (int(cam.cycle_s / cv.stable_step_s(ring, cv.default_safety(ring, predictor), predictor)) // 10 + 1)
    h = cam.cycle_s / n
    _, zd, zdd = mv.cycle_nodes(cam, h, n)
    y0, w0 = _start()
    runs = [
        kernel(ring, zd, zdd, h, y0, w0, out_every=10, predictor=predictor, track_energy=True)
        for kernel in (cv.integrate, ring_on_topology.integrate)
    ]
    old, new = runs
    assert old.impacts > 300 and new.impacts == old.impacts and new.n_steps == old.n_steps
    assert new.free_play_fraction == old.free_play_fraction
    for name in ("y", "w", "a", "u", "ud", "impact_speeds_m_s"):
        theirs, ours = getattr(old, name), getattr(new, name)
        assert (_apart(ours, theirs) < 1e-12) if np.any(theirs) else not np.any(ours), name
    for f in dataclasses.fields(old):
        if f.name not in ("y", "w", "a", "u", "ud", "impact_speeds_m_s", "impacts", "n_steps"):
            assert getattr(new, f.name) == pytest.approx(getattr(old, f.name), rel=1e-12, abs=1e-15), f.name


@pytest.mark.parametrize("law", ["global", "kelvin-voigt"])
def test_the_rings_scene_on_the_topology_kernel(law):
    """dynamics.scene.simulate_chain with kernel="topology" (dynamics.solvers.ring_on_topology) on the
    default scene's 180-degree window (85 links, friction 0.35, 0.094 mm, periodic steady state): the
    same steady-state search (same cycles), step and model; the response to 1e-12 (accelerations
    2e-12: the search's end state carries the kernels' rounding); impacts, free play and tension
    extremes as the ring's; the impact statistics (closing speeds, approach energy, force spike,
    dissipation: `test_the_impact_measurements_are_the_rings`) to 1e-12."""
    chain = ChainModel(N, M, 9.0092e7, friction_coefficient=0.35)
    model = ClearanceChain(chain, CLEARANCE_M, span_damping=law)
    t = np.arange(721) / 4 / (6 * 180.0)
    ring, ring_contact = simulate_chain(model, _cam(), t)
    ours, contact = simulate_chain(model, _cam(), t, kernel="topology")
    assert _apart(ours.x_m - ours.z_m[:, None], ring.x_m - ring.z_m[:, None]) < 1e-12
    assert _apart(ours.v_m_s, ring.v_m_s) < 1e-12
    assert _apart(ours.a_m_s2, ring.a_m_s2) < 2e-12
    assert _apart(ours.tension_N, ring.tension_N) < 1e-12
    assert contact.steady_state.cycles == ring_contact.steady_state.cycles
    for name in ("model", "reason", "steps_per_output", "impacts_per_cycle", "free_play_time_fraction"):
        assert getattr(contact, name) == getattr(ring_contact, name), name
    for name in ("peak_tension_N", "min_tension_N"):
        assert getattr(contact, name) == pytest.approx(getattr(ring_contact, name), rel=1e-12), name
    assert contact.impacts.closing_speed_max_m_s > 0.0
    for name in (f.name for f in dataclasses.fields(contact.impacts)):
        assert getattr(contact.impacts, name) == pytest.approx(getattr(ring_contact.impacts, name), rel=1e-12), name
    assert contact.impact_force_spike_N == pytest.approx(ring_contact.impact_force_spike_N, rel=1e-12)


def test_above_the_dense_limit_the_topology_kernel_takes_the_machines_o_n_damping(monkeypatch):
    """Above DENSE_LINK_LIMIT links the topology kernel runs the ring with the machine's O(N) damping
    (dynamics.models.machine_damping, each mode's ratio to 1e-5), not the ring's (reduced_damping, to
    1e-4): 401 links, one index cycle from rest through hundreds of impacts, against the dense C on the
    same kernel (the dense-damping reference): the same impacts, positions within 1e-5 of their peak,
    velocities 1e-4, accelerations 1e-3 (measured 2.8e-6, 2.1e-5, 3.2e-4: the acceleration's peak is
    the contacts' high modes, where a 1e-5 ratio error of a mode's damping force shows first), each
    closer than the ring's own kernel with its O(N) form (measured 1.7e-5, 6.5e-5, 1.1e-3). The ring's
    damping_tolerance names the ring's form: refused on the topology kernel, one line."""
    n = 401
    ring = ClearanceChain(ChainModel(n, M, 9.0092e7, friction_coefficient=0.35), CLEARANCE_M)
    cam = _cam()
    predictor = cv.default_predictor(ring)
    steps = 10 * (int(cam.cycle_s / cv.stable_step_s(ring, cv.default_safety(ring, predictor), predictor)) // 10 + 1)
    h = cam.cycle_s / steps
    _, zd, zdd = mv.cycle_nodes(cam, h, steps)
    start = (ring, zd, zdd, h, np.zeros(n), -zd[0] * np.ones(n))
    assert ring_on_topology.machine_of(ring).reduced_damping
    ours = ring_on_topology.integrate(*start, out_every=10, predictor=predictor)
    theirs = cv.integrate(*start, out_every=10, predictor=predictor)
    monkeypatch.setattr(clearance_machine, "DENSE_LINK_LIMIT", 10**9)  # the reference: the dense C
    reference = ring_on_topology.RingMachine.of(ring.chain, LINK_DRIVE, None, CLEARANCE_M)
    assert not reference.reduced_damping
    dense = mv.integrate(reference, np.zeros_like(zd), *start[1:], out_every=10, predictor=predictor)
    assert ours.impacts == dense.impacts > 300
    for name, field, bound in (("y", "q", 1e-5), ("w", "v", 1e-4), ("a", "a", 1e-3)):
        apart = _apart(getattr(ours, name), getattr(dense, field))
        assert apart < bound, name
        assert apart < _apart(getattr(theirs, name), getattr(dense, field)), name
    with pytest.raises(DynamicsError, match="kernel 'topology': damping_tolerance"):
        ring_on_topology.machine_of(ClearanceChain(ChainModel(N, M, K), CLEARANCE_M, damping_tolerance=1e-4))
    with pytest.raises(DynamicsError, match="kernel: expected one of"):
        simulate_chain(ClearanceChain(ChainModel(N, M, K), CLEARANCE_M), _cam(), np.arange(3) * 1e-3, kernel="x")


def test_the_rings_step_control_and_carriage_on_the_topology_kernel():
    """simulate_chain(accuracy=) halves the step until the station metrics settle: on the topology
    kernel the same doublings (same steps per sample, the error estimate to 1e-9 of itself), the same
    steady state, and the links' and the carriage's motion to 1e-12 (24 links, tensioner, friction)."""
    chain = ChainModel(24, M, 9.0092e7, friction_coefficient=0.35)
    model = ClearanceChain(chain, CLEARANCE_M, tensioner=TENSIONER)
    t = np.arange(361) / 2 / (6 * 180.0)
    ring, ring_contact = simulate_chain(model, _cam(), t, accuracy=1e-3)
    ours, contact = simulate_chain(model, _cam(), t, accuracy=1e-3, kernel="topology")
    assert contact.steps_per_output == ring_contact.steps_per_output > 9
    assert contact.step_error_estimate == pytest.approx(ring_contact.step_error_estimate, rel=1e-9)
    assert contact.steady_state.cycles == ring_contact.steady_state.cycles
    assert _apart(ours.x_m - ours.z_m[:, None], ring.x_m - ring.z_m[:, None]) < 1e-12
    assert _apart(ours.diagnostics["carriage_m"], ring.diagnostics["carriage_m"]) < 1e-12
