"""dynamics.response.sweep: the modal periodic solution against simulate(), the sweep, critical speeds, input checks."""

import warnings

import numpy as np
import pytest
from scipy.linalg import eigh

from dynamics.cams.program import CamProgram
from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.response.metrics import station_links
from dynamics.response.sweep import (
    cam_cycle_samples,
    chain_modes,
    critical_speeds_rpm,
    modal_periodic_response,
    parse_rpm_range,
    rpm_sweep,
    stiffness_matrix_sparse,
)
from dynamics.solvers.simulate import SlackChainWarning, simulate
from reporting.plots import plot_rpm_sweep

LAWS = ("modified-sine", "cycloidal")


def simulate_cycle(model, law, rpm, n, links):
    """simulate() (exact, periodic steady state) on the sweep's grid: n samples of one index cycle."""
    program = CamProgram.indexing(law, rpm=rpm)
    t = program.cycle_s * np.arange(n + 1) / n
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SlackChainWarning)
        r = simulate(model, program, t, links=links)
    return (r.x_m - r.z_m[:, None])[:-1], r.a_m_s2[:-1], program.dwell_mask(t[:-1])


@pytest.mark.parametrize("stiffness", [1e5, 9e7, 1e10])
def test_modal_periodic_response_matches_simulate(stiffness):
    # Same first-order-hold discretisation and the same periodic condition, solved two ways (modal DFT
    # vs matrix exponential + monodromy LU): only rounding separates them; measured 1e-12..2e-11.
    model = ChainModel(30, 2.0, stiffness)
    modes = chain_modes(model)
    n = 180
    for rpm in (60.0, 300.0):
        t, zdd, _ = cam_cycle_samples("modified-sine", n, pitch_m=0.1125, index_deg=45, dwell_deg=45, rpm=rpm)
        y, a = modal_periodic_response(modes, zdd, t[1] - t[0], [0, 22])
        y_ref, a_ref, _ = simulate_cycle(model, "modified-sine", rpm, n, [0, 22])
        assert np.max(np.abs(y - y_ref)) <= 1e-8 * np.max(np.abs(y_ref))
        assert np.max(np.abs(a - a_ref)) <= 1e-8 * np.max(np.abs(a_ref))


def test_rpm_sweep_agrees_with_simulate_at_a_few_speeds():
    # Same discretisation as simulate() on the same grid (see above): agreement to rounding, 1e-8.
    model = ChainModel(40, 2.03, 92696969.7)
    speeds = [45.0, 180.0, 240.0]
    n = 180
    result = rpm_sweep(model, LAWS, speeds, samples_per_cycle=n)
    link = station_links(40)["tight-side"]
    assert result.station_link == link
    for i, law in enumerate(LAWS):
        for j, rpm in enumerate(speeds):
            y, a, dwell = simulate_cycle(model, law, rpm, n, [link - 1])
            residual = np.max(np.abs(y[dwell]))
            peak = np.max(np.abs(a))
            assert result.residual_vibration_m[i, j] == pytest.approx(residual, rel=1e-8)
            assert result.peak_acceleration_m_s2[i, j] == pytest.approx(peak, rel=1e-8)


def test_modal_truncation_converges_in_relative_coordinates():
    # Relative coordinates: the cut modes carry little of the effective mass, so the station response
    # error falls as modes are added and vanishes (to rounding) with all of them.
    model = ChainModel(40, 2.0, 9e7)
    full = rpm_sweep(model, "modified-sine", [180.0], samples_per_cycle=180)
    errs = []
    for r in (1, 3, 10, 40):
        part = rpm_sweep(model, "modified-sine", [180.0], samples_per_cycle=180, n_modes=r)
        errs.append(abs(part.residual_vibration_m[0, 0] - full.residual_vibration_m[0, 0]))
    scale = full.residual_vibration_m[0, 0]
    assert errs[0] > errs[2] and errs[1] > errs[2]
    assert errs[2] < 0.05 * scale  # 10 of 40 modes: ~97 % of the effective mass (field notes)
    assert errs[3] < 1e-10 * scale


def test_sparse_mode_set_matches_dense_eigensolve():
    # Above 400 links (and up to N/10 modes) a truncated set comes from sparse shift-invert Lanczos;
    # eigenvalues agree with a dense solve to near rounding (ARPACK's default tol is machine precision).
    # Participations of the symmetric modes are zero, so they get an absolute floor of the largest one.
    model = ChainModel(600, 2.0, 9e7)
    sparse = chain_modes(model, n_modes=6)
    lam, vec = eigh(model.stiffness_matrix() / 2.0, subset_by_index=[0, 5])
    np.testing.assert_allclose(sparse.omega_rad_s, np.sqrt(lam), rtol=1e-9)
    gamma = 2.0 * vec.sum(axis=0) / np.sqrt(2.0)
    np.testing.assert_allclose(np.abs(sparse.participation), np.abs(gamma), rtol=1e-6, atol=1e-9 * np.abs(gamma).max())


def test_sparse_stiffness_equals_chain_model():
    model = ChainModel(7, 1.5, 3e7, drive_stiffness_N_per_m=5e7)
    np.testing.assert_array_equal(stiffness_matrix_sparse(model).toarray(), model.stiffness_matrix())


def test_critical_speeds_formula():
    # 40 Hz mode, 4 index cycles per revolution: harmonic k meets it at 60 * 40 / (4 k) rpm.
    crit = critical_speeds_rpm([40.0], 4.0, (0.0, 1000.0), max_harmonic=3)
    assert [c.rpm for c in crit] == pytest.approx([200.0, 300.0, 600.0])
    assert [c.harmonic for c in crit] == [3, 2, 1]
    assert critical_speeds_rpm([40.0], 4.0, (250.0, 650.0), max_harmonic=3)[0].rpm == pytest.approx(300.0)


def test_sweep_marks_the_excited_modes():
    model = ChainModel(85, 2.0, 9e7)
    result = rpm_sweep(model, "modified-sine", np.linspace(30, 300, 50), samples_per_cycle=90)
    modes = {c.mode for c in result.critical_speeds}
    # symmetric modes (2, 4, ...) have zero participation in the uniform base excitation: not marked
    assert 1 in modes and all(m % 2 == 1 for m in modes)
    for c in result.critical_speeds:
        assert c.rpm == pytest.approx(60 * result.natural_frequencies_Hz[c.mode - 1] / (c.harmonic * 4.0))


@pytest.mark.parametrize("text", ["300:30:1", "a:b:c", "30:300:0", "0:10:1", "30:300", "30:nan:1"])
def test_parse_rpm_range_rejects_bad_ranges(text):
    with pytest.raises(DynamicsError, match="rpm range"):
        parse_rpm_range(text)


def test_parse_rpm_range_inclusive():
    np.testing.assert_allclose(parse_rpm_range("30:300:0.5")[[0, -1]], [30.0, 300.0])
    assert parse_rpm_range("30:300:0.5").size == 541


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"rpms": []}, "rpms"),
        ({"rpms": [-10.0]}, "rpms"),
        ({"rpms": [np.nan]}, "rpms"),
        ({"cam_ids": ()}, "cam_ids"),
        ({"cam_ids": ("no-such-law",)}, "law_id"),
        ({"station": "middle"}, "station"),
        ({"station": 99}, "station"),
        ({"samples_per_cycle": 4}, "samples_per_cycle"),
        ({"n_modes": 0}, "n_modes"),
    ],
)
def test_rpm_sweep_input_validation(kwargs, match):
    args = {"cam_ids": ("modified-sine",), "rpms": [180.0]} | kwargs
    with pytest.raises(DynamicsError, match=match):
        rpm_sweep(ChainModel(20, 2.0, 9e7), args.pop("cam_ids"), args.pop("rpms"), **args)


def test_modal_periodic_response_checks_links_and_step():
    modes = chain_modes(ChainModel(10, 2.0, 9e7))
    with pytest.raises(DynamicsError, match="links"):
        modal_periodic_response(modes, np.zeros(16), 1e-3, [10])
    with pytest.raises(DynamicsError, match="step_s"):
        modal_periodic_response(modes, np.zeros(16), -1e-3, [0])


def test_rpm_sweep_refuses_friction():
    with pytest.raises(DynamicsError, match="friction"):
        rpm_sweep(ChainModel(20, 2.0, 9e7, friction_coefficient=0.3), "modified-sine", [180.0])


def test_rpm_sweep_refuses_undamped_chain():
    # an undamped mode has no periodic steady state at resonance
    with pytest.raises(DynamicsError, match="damping"):
        rpm_sweep(ChainModel(20, 2.0, 9e7, damping_ratio=0.0), "modified-sine", [180.0])


def test_plot_rpm_sweep_writes_png(tmp_path):
    result = rpm_sweep(ChainModel(20, 2.0, 9e7), LAWS, np.linspace(60, 240, 20), samples_per_cycle=90)
    path = tmp_path / "sweep.png"
    plot_rpm_sweep(result, path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
