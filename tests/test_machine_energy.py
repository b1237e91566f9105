"""Energy balance of the machine on its wheels across seat changes (issue #22; verification.machine_energy).

Over several index cycles, each followed by the transfer at the dwell: work of the drive = damping's
dissipation + seating losses (impacts' kinetic losses minus the seat snaps' elastic gains) + change
of stored energy. The drive's work and the dissipation are extra states of the DOP853 integration
at rtol 1e-12; measured against rtol 1e-9..1e-11 on these machines their error is 2e-9 of the
work (3e-10 without the polygonal feed), and the window's imbalance is 1e-9..1e-11 of the work.
The issue asks 1e-6 of the work; the seating terms are only 1e-4 of it, so the balance also bounds
the imbalance by 1e-3 of the seating terms, which is what makes it a check of the transfer: before
the transfer put the link leaving an idler wheel on a carriage at its seat (it ignored the
carriage's lengthening of the span ahead), that machine's window was out by 3e-6 J, 0.6 % of its
seating terms (1e-7 of its work, inside the issue's 1e-6).
"""

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import Tensioner
from dynamics.models.machine import MachineOnWheels
from dynamics.models.wheels import Wheel
from dynamics.solvers.machine_steady import transfer
from verification.machine_energy import drive_power_W, drive_spring_power_W, energy_window, seating_energy

P = 0.1125
CAM = CamProgram.indexing("modified-sine", pitch_m=P, rpm=180.0)
CHAIN = ChainModel(16, 2.03, 2e7, preload_N=2224.0, damping_ratio=0.13)


def _machine(drive: str, polygonal: bool, carriage: bool = False) -> MachineOnWheels:
    held = drive == "held"
    return MachineOnWheels(
        CHAIN,
        sprocket=Wheel(12, P, 3, inertia_kg_m2=0.0 if held else 0.3),
        idler=Wheel(12, P, 2, inertia_kg_m2=0.1),
        tensioner=Tensioner(2e5, 8.0, 150.0) if carriage else None,
        drive_torsional_stiffness_N_m_per_rad=np.inf if held else 2e6,
        polygonal=polygonal,
    )


MACHINES = {
    "held-polygonal": ("held", True, False),
    "held-linear": ("held", False, False),
    "compliant-polygonal": ("compliant", True, False),
    "compliant-linear": ("compliant", False, False),
    "compliant-polygonal-carriage": ("compliant", True, True),
    "compliant-linear-carriage": ("compliant", False, True),
}


def _random_state(machine, seed):
    rng = np.random.default_rng(seed)
    n = machine.topology.n_dof
    return 3e-5 * rng.standard_normal(n), 3e-2 * rng.standard_normal(n)


@pytest.mark.parametrize("name", MACHINES)
def test_the_transfer_changes_the_stored_energy_by_the_seating_losses(name):
    """No integrator: at a state of the index's end, stored energy after the transfer minus before =
    -impacts + snaps, each computed from that state alone (the relabelling conserves the rest)."""
    machine = _machine(*MACHINES[name])
    tooth = np.array([e.wheel.tooth_angle_rad for e in machine.wheel_ends])
    for seed in range(3):
        q, v = _random_state(machine, seed)
        impacts, snaps = seating_energy(machine, q, v)
        q_new, v_new, _, reported = transfer(machine, q, v)
        np.testing.assert_allclose(reported, impacts, rtol=1e-12)
        change = machine.stored_energy_J(q_new, v_new, 0.0, np.zeros(tooth.size)) - machine.stored_energy_J(
            q, v, 0.0, tooth
        )
        size = sum(impacts) + sum(np.abs(snaps))
        assert min(impacts) > 0 and size > 1e-4  # both effects are there, of the order of 1e-3 J
        assert change == pytest.approx(sum(snaps) - sum(impacts), abs=1e-10 * size)


@pytest.mark.parametrize("polygonal", [False, True])
def test_the_drives_power_is_its_springs_force_on_the_cam_times_the_cams_speed(polygonal):
    """Compliant drive: the prescribed motion's power -z' 1^T (dV/dq + C q') + dV/dt equals
    -z' (k_g u + 1^T C q'), the torsional spring's (and the dampers') force on the cam's side."""
    machine = _machine("compliant", polygonal, carriage=True)
    for seed in range(3):
        q, v = _random_state(machine, seed)
        angles = np.array([0.13, 0.29])
        general = drive_power_W(machine, q, v, angles, 1.7)
        assert general == pytest.approx(drive_spring_power_W(machine, q, v, 1.7), rel=1e-9)


def _check_window(window):
    seating = sum(sum(s.impact_J) + sum(np.abs(s.snap_J)) for s in window.transfers)
    assert window.dissipated_J > 0.5 * window.work_J  # damping takes most of the work from rest
    assert seating > 1e-5 * window.work_J  # the seating terms are visible at the balance's tolerance
    assert abs(window.imbalance_J) <= 1e-6 * window.work_J
    assert abs(window.imbalance_J) <= 1e-3 * seating


def test_energy_balance_across_seat_changes_linear_compliant_drive():
    _check_window(energy_window(_machine("compliant", False), CAM, 2))


@pytest.mark.slow
@pytest.mark.parametrize(
    "name", ["held-polygonal", "held-linear", "compliant-polygonal", "compliant-polygonal-carriage"]
)
def test_energy_balance_across_seat_changes(name):
    _check_window(energy_window(_machine(*MACHINES[name]), CAM, 3))
