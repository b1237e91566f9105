"""The machine's mode nearest resonance with an index harmonic (dynamics.scene.Resonance): of its lowest
NEAREST_RESONANCE_MODES modes the one its nearest cam harmonic drives hardest, beside lowest_mode."""

import json

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.machine_scene import machine_lowest_mode, machine_model, machine_nearest_resonance, simulate_machine
from dynamics.models.chain import ChainModel
from dynamics.options import DENSE_LINK_LIMIT
from dynamics.scene import harmonic_shares, lowest_mode, nearest_resonance
from dynamics.solvers import cache, machine_modes, machine_shooting
from dynamics.solvers.machine_modes import NEAREST_RESONANCE_MODES, SOLVED_MODES
from geometry.dimensions import LinkDimensions
from settings import RunConfig
from stages.chain import chain_scene

PITCH_M = LinkDimensions().pitch_m
K_AL, M_AL = 9.325e7, 2.03  # the default aluminium link's FEA k (N/m) and lumped mass (kg)
CYCLE_S = 1 / 12


class _TwoHarmonicCam:
    """A cam whose acceleration is 2 cos(w t) + 0.5 sin(3 w t) over a cycle of CYCLE_S: its harmonics'
    shares are 1, 0, 0.25 exactly."""

    cycle_s = CYCLE_S

    def svaj(self, t):
        w = 2 * np.pi / CYCLE_S
        a = 2 * np.cos(w * t) + 0.5 * np.sin(3 * w * t)
        return None, None, a, None


def test_the_harmonic_shares_are_the_cams_acceleration_harmonics():
    # exact for a band-limited acceleration sampled over one cycle (to rounding)
    assert harmonic_shares(_TwoHarmonicCam(), [1, 2, 3]) == pytest.approx([1.0, 0.0, 0.25], abs=1e-13)


def test_the_mode_driven_hardest_is_amplification_times_its_harmonics_share():
    cam = _TwoHarmonicCam()
    f = 1 / CYCLE_S
    lowest = lowest_mode(0.5 * f, 0.13, CYCLE_S)  # below the first harmonic: amplification 1.3
    # mode 3 on the third harmonic nearly undamped: 1 / (2 zeta) x 0.25 = 12.5 against mode 2's 3.8 x 1
    picked = nearest_resonance([0.5 * f, 1.02 * f, 3.0 * f], [0.13, 0.13, 0.01], cam, lowest)
    assert (picked.mode_number, picked.harmonic_share) == (3, pytest.approx(0.25, abs=1e-13))
    assert picked.searched_up_to_Hz == 3.0 * f
    assert picked.mode == lowest_mode(3.0 * f, 0.01, CYCLE_S) and picked.mode.amplification == pytest.approx(50.0)
    # damped as mode 2, mode 3's weaker harmonic loses
    assert nearest_resonance([0.5 * f, 1.02 * f, 3.0 * f], [0.13, 0.13, 0.13], cam, lowest).mode_number == 2
    # on the second harmonic, which the cam does not have, no amplification counts
    assert nearest_resonance([0.5 * f, 2.0 * f], [0.13, 1e-4], cam, lowest).mode_number == 1
    # mode 1 driven hardest: the lowest mode's own object
    on = lowest_mode(f, 0.05, CYCLE_S)
    assert nearest_resonance([f, 3.1 * f], [0.05, 0.05], cam, on).mode is on


def _machine(links: int):
    chain = ChainModel(links, M_AL, K_AL, damping_ratio=0.13, friction_coefficient=0.0)
    return machine_model(chain_scene(RunConfig(), PITCH_M), chain)


def _dense_frequencies_Hz(machine) -> np.ndarray:
    """Every natural frequency of the machine's (K, M) by numpy.linalg.eigh on M^-1/2 K M^-1/2."""
    topo = machine.topology
    r = 1 / np.sqrt(np.asarray(topo.masses_kg, dtype=float))
    lam = np.linalg.eigh(r[:, None] * topo.stiffness_matrix_sparse().toarray() * r[None, :])[0]
    return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)


def test_the_long_machines_modes_are_the_dense_eigensolves():
    """Above DENSE_LINK_LIMIT the modes come from one shift-invert Lanczos solve on the sparse (K, M):
    its 12 lowest frequencies are the dense eigensolve's (the dense solve's rounding, eps x
    lambda_max / lambda_1 = 2e-16 x 8e4, is 1e-11 on f_1; measured 2.3e-12; the tolerance 1e-9 leaves
    100x), and the nearest resonance picked from them is the one picked from the dense frequencies."""
    model = _machine(DENSE_LINK_LIMIT + 50)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180.0)
    dense = _dense_frequencies_Hz(model.machine)[:NEAREST_RESONANCE_MODES]
    sparse = model.machine.lowest_natural_frequencies_Hz(NEAREST_RESONANCE_MODES)
    assert sparse == pytest.approx(dense, rel=1e-9)
    lowest = machine_lowest_mode(model, cam.cycle_s)
    picked = machine_nearest_resonance(model, cam, lowest)
    reference = nearest_resonance(dense, [0.13] * NEAREST_RESONANCE_MODES, cam, lowest)
    assert picked.mode_number == reference.mode_number
    assert picked.mode.frequency_Hz == pytest.approx(reference.mode.frequency_Hz, rel=1e-9)


@pytest.mark.parametrize("links", [85, DENSE_LINK_LIMIT + 50])
def test_one_eigensolve_gives_the_lowest_mode_the_searches_decay_and_the_resonances_modes(links, monkeypatch):
    """Mode 1 of the summary's lowest_mode and of the searches' slowest decay is the first of the
    NEAREST_RESONANCE_MODES the nearest resonance is picked from, to the bit, from one eigensolve per
    machine (the dense one at 85 links, one shift-invert Lanczos solve above DENSE_LINK_LIMIT)."""
    model = _machine(links)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180.0)
    machine = model.machine
    solves = []
    solve = type(machine).lowest_natural_frequencies_Hz

    def counted(self, count):
        solves.append(count)
        return solve(self, count)

    monkeypatch.setattr(type(machine), "lowest_natural_frequencies_Hz", counted)
    cache.clear()
    decay = machine_shooting.slowest_decay_per_cycle(model, cam.cycle_s)
    lowest = machine_lowest_mode(model, cam.cycle_s)
    resonance = machine_nearest_resonance(model, cam, lowest)
    modes = machine_modes.lowest_frequencies_Hz(machine)
    assert solves == [SOLVED_MODES]
    assert lowest.frequency_Hz == modes[0] and resonance.searched_up_to_Hz == modes[-1]
    omega = 2 * np.pi * modes[0]
    assert decay == np.exp(-model.damping_ratio_at(omega) * omega * cam.cycle_s)


def test_on_the_default_machine_the_nearest_resonance_is_mode_1s_lowest_mode():
    """The default run's machine (85 aluminium links, 180 rpm): mode 1 at 37.1 Hz, 3 % above the third
    harmonic, is the one driven hardest of the 12 lowest (the dense frequencies, every other mode's
    amplification x harmonic share below it), and the summary gives it as lowest_mode itself."""
    model = _machine(85)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180.0)
    t = np.arange(361) / 4 / (6 * 180.0)
    _, summary = simulate_machine(model, cam, t)
    assert summary.nearest_resonance.mode is summary.lowest_mode and summary.nearest_resonance.mode_number == 1
    dense = _dense_frequencies_Hz(model.machine)[:NEAREST_RESONANCE_MODES]
    modes = [lowest_mode(f, 0.13, cam.cycle_s) for f in dense]
    driven = [m.amplification * s for m, s in zip(modes, harmonic_shares(cam, [m.harmonic for m in modes]))]
    assert int(np.argmax(driven)) == 0 and modes[0].harmonic == 3


def test_summary_json_gives_the_nearest_resonance():
    from dataclasses import replace

    from dynamics.scene import ChainModelKind, ContactSummary, Resonance, Validity
    from reporting.outputs import _contact_summary

    mode = lowest_mode(37.1, 0.0032, 1 / 12)
    contact = ContactSummary(
        ChainModelKind.CLEARANCE, "asked for", Validity.VALID, 1e-4, True, 0.1, 2.0, 900.0, 5e3, -10.0, 20.0, -10.0,
        nearest_resonance=Resonance(11, 0.28, 40.4, mode),
    )  # fmt: skip
    summary = json.loads(json.dumps(_contact_summary(contact), allow_nan=False))
    expected = {"mode_number": 11, "harmonic_share": 0.28, "searched_up_to_Hz": 40.4, **vars(mode)}
    assert summary["nearest_resonance"] == expected
    assert (
        json.loads(json.dumps(_contact_summary(replace(contact, nearest_resonance=None))))["nearest_resonance"] is None
    )
