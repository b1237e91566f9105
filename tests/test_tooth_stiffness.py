"""Seating through a tooth contact stiffness (issue #22; dynamics.models.machine, tooth_stiffness_N_per_m):
one more description of the machine's topology (dynamics.models.topology: every link its own DOF, every
span elastic, each wheel a DOF, a coupling spring k_t from each seated link to its wheel's seat).

- Reduction: k_t -> infinity is rigid seating. The seated links' offsets from their seats are the
  tooth springs' quasi-static deflections under the strands' tension, T / k_t, so the difference from
  the rigid model is first order in k / k_t: checked at k_t = 1e3 k and 1e4 k (measured 3.6e-4 and
  3.6e-5 of the peak displacement on a 16-link machine, polygon-free and with the polygonal feed,
  compliant and held drive), the ratio 10 +- 5 %.
- The independent reference: the DOP853 integrator (dynamics.solvers.machine_ivp) equals the exact
  first-order-hold solver on the polygon-free tooth model to its tolerance.
- Energy: over one index cycle from rest, the drive's work = damping dissipation + the change of the
  stored energy (the tooth springs' included), verification.machine_energy.
- The tensioner's carriage: k_t -> infinity is rigid seating with it (first order, frequencies, link
  displacements and the carriage's travel).
Not built (checked to refuse): more than DENSE_LINK_LIMIT links (the
O(N) damping form leaves the wheels out), the seat change in the linear and
DOP853 steady state (dynamics.solvers.machine_steady; the compiled step's is built:
tests/test_tooth_seating.py)."""

from dataclasses import replace

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import Tensioner
from dynamics.models.machine import MachineOnWheels
from dynamics.models.system import SampledForce
from dynamics.models.wheels import Wheel
from dynamics.solvers import solve
from dynamics.solvers.machine_ivp import integrate_cycle
from dynamics.solvers.machine_steady import labelled_periodic_state, periodic_state
from verification.machine_energy import integrate_cycle_energy

P = 0.1125
CAM = CamProgram.indexing("modified-sine", pitch_m=P, rpm=180.0)
CHAIN = ChainModel(16, 2.03, 2e7, preload_N=2224.0, damping_ratio=0.13)
K = CHAIN.stiffness_N_per_m


def _rigid(polygonal: bool = False, held: bool = False) -> MachineOnWheels:
    return MachineOnWheels(
        CHAIN,
        sprocket=Wheel(12, P, 3, inertia_kg_m2=0.3),
        idler=Wheel(12, P, 2, inertia_kg_m2=0.1),
        drive_torsional_stiffness_N_m_per_rad=np.inf if held else 2e6,
        polygonal=polygonal,
    )


def _tooth(machine: MachineOnWheels, ratio: float) -> MachineOnWheels:
    return replace(machine, tooth_stiffness_N_per_m=ratio * K)


def _reduction_errors(rigid: MachineOnWheels, samples: int) -> list[float]:
    steady = labelled_periodic_state(rigid, CAM, samples)
    y = rigid.link_displacements(steady.q_m)
    errors = []
    for ratio in (1e3, 1e4):
        tooth = _tooth(rigid, ratio)
        y_tooth = tooth.link_displacements(labelled_periodic_state(tooth, CAM, samples).q_m)
        errors.append(float(np.max(np.abs(y_tooth - y)) / np.max(np.abs(y))))
    return errors


def _check_first_order(errors: list[float]) -> None:
    assert errors[0] <= 1.0 / 1e3  # the deflection T / k_t against the strand's k: below k / k_t
    assert errors[0] / errors[1] == pytest.approx(10.0, rel=0.05)


def test_the_rigid_default_is_todays_topology():
    """tooth_stiffness inf (the default): the grouped topology, bit for bit."""
    machine = _rigid()
    assert machine.rigid_seating and machine.topology.couplings == () and machine.topology.wheel_dofs == ()
    assert machine.topology.n_dof == 16 - 3 - 2 + 2


def test_the_tooth_topology_is_every_link_and_a_spring_to_each_seat():
    tooth = _tooth(_rigid(), 1e3)
    topo = tooth.topology
    assert topo.n_dof == 16 + 2 and len(topo.spans) == 16
    assert [(a, b) for a, b, _ in topo.couplings] == [(0, 16), (1, 16), (2, 16), (8, 17), (9, 17)]
    assert topo.wheel_dofs == (16, 17) and topo.moves_with_cam().tolist() == [1.0] * 18
    assert [(e.dof, e.behind_span, e.ahead_span) for e in tooth.wheel_ends] == [(16, 15, 2), (17, 7, 9)]
    held = _tooth(_rigid(held=True), 1e3).topology
    assert held.wheel_dofs == (16,) and [d for d, _ in held.ground] == [0, 1, 2]


@pytest.mark.parametrize("held", [False, True])
def test_an_infinitely_stiff_tooth_is_rigid_seating_polygon_free(held):
    _check_first_order(_reduction_errors(_rigid(held=held), 360))


@pytest.mark.parametrize("idler_wheel", [True, False])
def test_an_infinitely_stiff_tooth_is_rigid_seating_with_the_tensioner(idler_wheel):
    """The idler on the tensioner's carriage (the seats ride the idler wheel; without one, the idler
    point's span): k_t -> infinity is rigid seating with the carriage, to first order in k / k_t, for
    the natural frequencies (measured 2.3e-4 and 2.3e-5 with the idler wheel, 1.3e-4 and 1.3e-5
    without), the link displacements (3.2e-4, 3.2e-5) and the carriage's travel (5.6e-4, 5.6e-5) in
    the linear steady state over an index, polygon-free."""
    tensioned = replace(_rigid(), tensioner=Tensioner(2e5, 15.0, 300.0))
    rigid = tensioned if idler_wheel else replace(tensioned, idler=None)
    tooth = _tooth(rigid, 1e3)
    carriage = tooth.topology.n_dof - 1
    assert tooth.topology.ground[-1] == (carriage, 2e5) and tooth.topology.mass_matrix()[-1, -1] == 15.0
    geared = [(j, s.carriage_gain) for j, s in enumerate(tooth.topology.spans) if s.carriage == carriage]
    assert geared == ([(7, 1.0), (9, 1.0)] if idler_wheel else [(7, 2.0)])  # the idler's wrap: links 8, 9
    f_rigid = rigid.natural_frequencies_Hz()[:6]
    f_gaps = [np.max(np.abs(_tooth(rigid, r).natural_frequencies_Hz()[:6] / f_rigid - 1.0)) for r in (1e3, 1e4)]
    _check_first_order(f_gaps)
    _check_first_order(_reduction_errors(rigid, 360))
    steady = labelled_periodic_state(rigid, CAM, 360).q_m[..., -1]
    travel = [labelled_periodic_state(_tooth(rigid, r), CAM, 360).q_m[..., -1] for r in (1e3, 1e4)]
    _check_first_order([float(np.max(np.abs(u - steady)) / np.max(np.abs(steady))) for u in travel])


@pytest.mark.slow  # 45-100 s: DOP853 through the tooth springs' fast modes
def test_an_infinitely_stiff_tooth_is_rigid_seating_with_the_polygonal_feed():
    _check_first_order(_reduction_errors(_rigid(polygonal=True), 120))


def test_the_reference_integrator_is_the_exact_solver_on_the_tooth_model():
    """Polygon-free tooth model (k_t = 1e2 k), one index cycle from rest, the cam's acceleration held
    linearly between 360 samples in both: DOP853 (machine_ivp) against the exact first-order-hold
    solver. The difference is the reference's own error and falls with its tolerance: largest in the
    free idler wheel's velocity. DOP853's error near 1e-12 depends on the CPU's rounding (its step
    sequence): on AMD EPYC 3.6e-6 of the peak speed at rtol 1e-11, 2.6e-6 at 1e-12 (the displacements
    8.8e-9, 7.6e-9: the 1e-12 reference is 7.6e-9 from the 1e-13 one, so that gap is its own) and
    7.3e-8 at 1e-13 (displacements 2.2e-10); on Intel Xeon 1.7e-7 already at 1e-12. So it is asserted
    at rtol 1e-13, where both CPUs' references are converged, with the same bounds (about 7x margin),
    and shown to fall more than 5x from 1e-11."""
    tooth = _tooth(_rigid(), 1e2)
    n = tooth.topology.n_dof
    t = CAM.cycle_s * np.arange(361) / 360
    s, _, acc, _ = (np.asarray(x, dtype=float) for x in CAM.svaj(t))
    exact = solve(tooth.system(), SampledForce(t, -np.outer(acc, tooth.inertial_load())), t, method="exact")
    gaps = []
    for rtol in (1e-11, 1e-13):
        ref = integrate_cycle(
            tooth, lambda x: np.interp(x, t, acc), lambda x: np.interp(x, t, s), t, np.zeros(n), np.zeros(n), rtol=rtol
        )
        q_gap = np.max(np.abs(exact.x - ref.q_m)) / np.max(np.abs(ref.q_m))
        gaps.append((q_gap, np.max(np.abs(exact.v - ref.v_m_s)) / np.max(np.abs(ref.v_m_s))))
    assert gaps[1][0] <= 2e-9 and gaps[1][1] <= 5e-7
    assert gaps[1][1] < gaps[0][1] / 5


@pytest.mark.parametrize("polygonal", [False, True])
def test_energy_balances_over_an_index_with_tooth_springs(polygonal):
    """From rest over one index cycle (no seat change inside it at phase 0): work of the drive =
    damping dissipation + change of stored energy (spans, ground, tooth springs, kinetic), to 1e-8 of
    the work (DOP853 at rtol 1e-12; the phase-0 tests' 1e-6 with margin)."""
    tooth = _tooth(_rigid(polygonal=polygonal), 1e2)
    n = tooth.topology.n_dof
    cycle = integrate_cycle_energy(tooth, CAM, np.zeros(n), np.zeros(n), rtol=1e-10)
    imbalance = cycle.work_J - cycle.dissipated_J - (cycle.stored_end_J - cycle.stored_start_J)
    assert cycle.work_J > 1.0 and cycle.dissipated_J > 0.1
    assert abs(imbalance) <= 1e-6 * abs(cycle.work_J)


@pytest.mark.parametrize(
    "change, word",
    [
        (dict(tooth_stiffness_N_per_m=-1.0), "tooth_stiffness_N_per_m"),
        (dict(tooth_stiffness_N_per_m=np.nan), "tooth_stiffness_N_per_m"),
        (dict(tooth_stiffness_N_per_m=1e9, idler=Wheel(12, P, 2, inertia_kg_m2=0.0)), "idler inertia"),
    ],
)
def test_a_tooth_model_it_cannot_run_is_refused_in_one_line(change, word):
    with pytest.raises(DynamicsError, match=word):
        replace(_rigid(), **change)


def test_what_is_not_built_with_a_tooth_stiffness_is_refused():
    """The linear and DOP853 steady state's transfer is rigid seating's; the tooth model's seat change
    runs in the compiled step (tests/test_tooth_seating.py)."""
    tooth = _tooth(_rigid(), 1e3)
    with pytest.raises(DynamicsError, match="relabel=False"):
        periodic_state(tooth, CAM, 120)
