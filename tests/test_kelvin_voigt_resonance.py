"""The Kelvin-Voigt law's low-mode resonance on the wheels (docs/physics.md, "Damping laws"): the lowest
mode's record in the run's summary (dynamics.scene.LowestMode), and the resonance itself in the
exact linear machine, the law in full contact (Rayleigh (0, beta))."""

import math
from dataclasses import replace

import numpy as np
import pytest

from dynamics.cams import CamProgram
from dynamics.machine_scene import machine_model, simulate_machine
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import kelvin_voigt_beta_s
from dynamics.scene import lowest_mode
from dynamics.solvers.machine_steady import periodic_state
from geometry.dimensions import LinkDimensions
from settings import RunConfig
from stages.chain import chain_scene

PITCH_M = LinkDimensions().pitch_m  # the default link's, which the wheels are sized on
K_AL, M_AL = 9.325e7, 2.03  # the default aluminium link's FEA k (N/m) and lumped mass (kg)


def test_the_lowest_mode_against_the_cams_harmonics():
    # exactly on the third harmonic of a 1/12 s cycle: the amplification is 1 / (2 zeta)
    on = lowest_mode(36.0, 0.01, 1 / 12)
    assert (on.harmonic, on.detuning) == (3, pytest.approx(0.0, abs=1e-15))
    assert on.amplification == pytest.approx(50.0, rel=1e-12)
    assert on.decay_per_cycle == pytest.approx(math.exp(-0.01 * 2 * math.pi * 3), rel=1e-12)
    # undamped, 3 % above the harmonic: 1 / (1 - r^2), r = 36 / 37.08
    off = lowest_mode(37.08, 0.0, 1 / 12)
    assert off.detuning == pytest.approx(0.03, rel=1e-12)
    assert off.amplification == pytest.approx(1 / (1 - (36 / 37.08) ** 2), rel=1e-12)
    assert off.decay_per_cycle == 1.0
    # below the cycle rate the nearest harmonic is the first
    assert lowest_mode(4.0, 0.1, 1 / 12).harmonic == 1


def _machine_scene(span_damping: str, clearance_m: float, **cfg):
    return chain_scene(RunConfig(span_damping=span_damping, pin_clearance_m=clearance_m, **cfg), PITCH_M)


@pytest.mark.parametrize(
    "span_damping, clearance_m, law_that_ran",
    [("kelvin-voigt", 1e-3, "kelvin-voigt"), ("global", 1e-3, "global"), ("kelvin-voigt", 0.0, "global")],
)
def test_the_machines_summary_gives_its_lowest_mode_under_the_law_that_ran(span_damping, clearance_m, law_that_ran):
    """The lowest mode of the machine that ran, damped as the law that ran damps it: beta omega / 2
    under the Kelvin-Voigt law, the modal zeta under the global law; at free play 0 the linear machine
    (global law) runs whatever law was asked for."""
    chain = ChainModel(16, M_AL, K_AL, damping_ratio=0.13, friction_coefficient=0.0)
    model = machine_model(_machine_scene(span_damping, clearance_m), chain)
    cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=180.0)
    t = np.arange(9) / 4 / (6 * 180.0)
    _, summary = simulate_machine(model, cam, t, steady_state=False)
    mode = summary.lowest_mode
    f1 = model.machine.lowest_natural_frequencies_Hz(1)[0]
    zeta = 0.5 * kelvin_voigt_beta_s(chain, None) * 2 * np.pi * f1 if law_that_ran == "kelvin-voigt" else 0.13
    assert mode.frequency_Hz == pytest.approx(f1, rel=1e-12)
    assert mode.damping_ratio == pytest.approx(zeta, rel=1e-12)
    assert mode == lowest_mode(f1, mode.damping_ratio, cam.cycle_s)


def test_the_kelvin_voigt_machine_resonates_where_its_lowest_mode_meets_an_index_harmonic():
    """The default aluminium machine (85 links, polygon-free) in full contact, its exact relabelled
    periodic state (machine_steady): with the Kelvin-Voigt law (Rayleigh (0, beta) in full contact,
    zeta_1 = 0.0032) at the speed that puts the index's third harmonic on f_1 its motion is 14x the
    global law's (zeta 0.13): on mode 1 alone the ratio would be 0.13 / 0.0032 = 41, the other modes
    dilute it; 20 % slower (150 rpm, off resonance) the two laws' motions are within 22 %."""
    chain = ChainModel(85, M_AL, K_AL, damping_ratio=0.13, friction_coefficient=0.0)
    layout = _machine_scene("kelvin-voigt", 0.0, polygonal_action=False).layout
    kv = layout.machine(replace(chain, rayleigh_coefficients=(0.0, kelvin_voigt_beta_s(chain, None))), None)
    glob = layout.machine(chain, None)
    f1 = kv.lowest_natural_frequencies_Hz(1)[0]
    on_rpm = 15 * f1 / 3  # the index rate is rpm / 15 (four indexes per cam turn)

    def ratio(rpm):
        cam = CamProgram.indexing("modified-sine", pitch_m=PITCH_M, rpm=rpm)
        kv_q, glob_q = (np.max(np.abs(periodic_state(m, cam, 360).q_m)) for m in (kv, glob))
        return kv_q / glob_q

    assert ratio(on_rpm) > 10.0
    assert ratio(150.0) < 1.3


def test_summary_json_gives_the_lowest_mode():
    import json

    from dynamics.scene import ChainModelKind, ContactSummary, Validity
    from reporting.outputs import _contact_summary

    mode = lowest_mode(37.1, 0.0032, 1 / 12)
    contact = ContactSummary(
        ChainModelKind.CLEARANCE, "asked for", Validity.VALID, 1e-4, True, 0.1, 2.0, 900.0, 5e3, -10.0, 20.0, -10.0,
        lowest_mode=mode,
    )  # fmt: skip
    summary = json.loads(json.dumps(_contact_summary(contact), allow_nan=False))
    assert summary["lowest_mode"] == {**vars(mode)}
    assert json.loads(json.dumps(_contact_summary(replace(contact, lowest_mode=None))))["lowest_mode"] is None
