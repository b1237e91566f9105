import numpy as np
import pytest

from dynamics.cams import CamProgram, TabulatedCam, mqp2012_program, read_svaj_table, write_svaj_table
from dynamics.errors import DynamicsError

DEG_S = 1.0 / (6 * 180.0)


def test_written_table_has_the_reports_layout(tmp_path):
    path = write_svaj_table(mqp2012_program("modified-sine"), tmp_path / "ms.txt")
    lines = path.read_text().splitlines()
    rows = np.loadtxt(path, skiprows=6)  # what dlmread(file, '', 6, 0) sees
    assert rows.shape == (181, 5)
    assert len(lines) == 6 + 181
    assert np.allclose(rows[:, 0], np.arange(181.0))
    assert rows[45, 1] == pytest.approx(112.5) and rows[180, 1] == pytest.approx(225.0)  # mm


def test_quintic_hermite_reproduces_a_quintic_law_exactly(tmp_path):
    # 3-4-5 is a quintic in time inside each rise, and each 1-deg interval lies inside one segment:
    # the Hermite quintic through s, v, a at the rows is that polynomial. The file keeps 15
    # significant digits; print rounding is amplified by 1/h in v and 1/h^2 in a, so 1e-10 of
    # each quantity's scale (0.225 m, 6 m/s, 3e3 m/s^2) bounds what is left.
    p = mqp2012_program("poly-345")
    cam = read_svaj_table(write_svaj_table(p, tmp_path / "p.txt"), rpm=180.0)
    t = np.linspace(0.0, 179.9 * DEG_S, 2001)
    for got, want, scale in zip(cam.svaj(t), p.svaj(t), (0.225, 6.0, 3e3)):
        assert np.max(np.abs(got - want)) < 1e-10 * scale


def test_hermite_interpolation_of_a_non_polynomial_law_converges_at_sixth_order(tmp_path):
    p = CamProgram.indexing("cycloidal")
    errors = []
    for step in (1.0, 0.5):
        cam = read_svaj_table(write_svaj_table(p, tmp_path / "c.txt", step_deg=step), rpm=180.0, periodic=True)
        t = np.linspace(0.0, 2 * p.period_s, 3001)
        errors.append(np.max(np.abs(cam.svaj(t)[0] - p.svaj(t)[0])))
    # Quintic Hermite: displacement error O(h^6), halving the step divides it by ~64 (the file's
    # 15 significant digits keep print rounding ~1e-16 m, far below both errors).
    assert errors[0] / errors[1] == pytest.approx(64.0, rel=0.1)


def test_periodic_table_continues_the_indexing(tmp_path):
    p = CamProgram.indexing("modified-sine")
    cam = read_svaj_table(write_svaj_table(p, tmp_path / "i.txt"), rpm=180.0, periodic=True)
    assert cam.period_s == pytest.approx(p.period_s)
    assert cam.advance_m == pytest.approx(p.advance_m, rel=1e-12)
    t = np.array([0.3, 1.7])
    assert np.allclose(cam.svaj(t)[0], p.svaj(t)[0], rtol=0, atol=1e-8)  # 1e-8 m: 1-deg Hermite error
    assert np.allclose(cam.dwell_intervals_s, p.dwell_intervals_s, rtol=1e-12)


def test_linear_interpolation_and_dwells(tmp_path):
    p = mqp2012_program("cycloidal")
    cam = read_svaj_table(write_svaj_table(p, tmp_path / "c.txt"), interpolation="linear", header_lines=6)
    s, v, a, j = cam.svaj(np.array([0.5 * DEG_S]))
    s0, v0, a0, j0 = p.svaj(np.array([0.0, DEG_S]))
    assert s[0] == pytest.approx(s0.mean()) and v[0] == pytest.approx(v0.mean()) and j[0] == pytest.approx(j0.mean())
    assert cam.dwell_mask(np.array([10.0, 50.0, 100.0, 150.0, 300.0]) * DEG_S).tolist() == [
        False,
        True,
        False,
        True,
        True,
    ]
    assert cam.dwell_intervals_s[-1][1] == np.inf
    s_late, v_late, _, _ = cam.svaj(np.array([1.0]))  # past the end of a one-shot table: at rest
    assert s_late[0] == pytest.approx(0.225) and v_late[0] == 0.0


def test_at_rpm_rescales_time_derivatives(tmp_path):
    cam = read_svaj_table(write_svaj_table(mqp2012_program("poly-4567"), tmp_path / "p.txt"))
    slow = cam.at_rpm(90.0)
    s1, v1, a1, _ = cam.svaj(np.array([10 * DEG_S]))
    s2, v2, a2, _ = slow.svaj(np.array([20 * DEG_S]))
    assert s2 == pytest.approx(s1) and v2 == pytest.approx(v1 / 2) and a2 == pytest.approx(a1 / 4)


def test_metres_and_four_columns(tmp_path):
    path = tmp_path / "m.txt"
    path.write_text("angle s v a\n0 0 0 0\n90 0.1 0 0\n")
    cam = read_svaj_table(path, units="m", rpm=60.0)
    assert cam.duration_s == pytest.approx(0.25)
    assert cam.svaj(np.array([0.25]))[0][0] == pytest.approx(0.1)


@pytest.mark.parametrize(
    "text, match",
    [
        ("h\n0 0 0 0 0\n1 0 0 x 0\n", r"line 3: .* not numeric"),
        ("h\n0 0 0 0 0\n1 0 0 0\n", r"line 3: got 4 columns; expected 5"),
        ("h\n0 0 0\n1 0 0\n", r"line 2: got 3 columns"),
        ("h\n0 0 0 0 0\n1 0 0 0 0\n1 0 0 0 0\n", r"line 4: angle 1.0 does not increase"),
        ("h\n0 0 0 0 0\n", r"found 1 data rows"),
        ("just a header\n", r"found 0 data rows"),
    ],
)
def test_bad_tables_name_the_line(tmp_path, text, match):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(DynamicsError, match=match):
        read_svaj_table(path)


def test_bad_arguments(tmp_path):
    with pytest.raises(DynamicsError, match="cannot read"):
        read_svaj_table(tmp_path / "missing.txt")
    good = write_svaj_table(mqp2012_program("cycloidal"), tmp_path / "g.txt")
    with pytest.raises(DynamicsError, match="units"):
        read_svaj_table(good, units="inch")
    with pytest.raises(DynamicsError, match="interpolation"):
        read_svaj_table(good, interpolation="cubic")
    with pytest.raises(DynamicsError, match="rpm"):
        read_svaj_table(good, rpm=-1.0)
    with pytest.raises(DynamicsError, match="periodic table"):
        TabulatedCam([0, 1], [0, 1], [0, 1], [0, 0], rpm=1.0, periodic=True)
    with pytest.raises(DynamicsError, match="step_deg"):
        write_svaj_table(mqp2012_program("cycloidal"), tmp_path / "x.txt", step_deg=0.0)
    with pytest.raises(DynamicsError, match="stop_deg"):
        write_svaj_table(mqp2012_program("cycloidal"), tmp_path / "x.txt", step_deg=7.0)


def test_programs_and_tables_refuse_the_same_times_alike(tmp_path):
    """One check (dynamics.cams.cycle) for both kinds of cam: non-finite times always, times before
    t = 0 only for one-shot motions, the bad time printed as a plain number."""
    program = mqp2012_program("cycloidal")
    table = read_svaj_table(write_svaj_table(program, tmp_path / "c.txt"))
    for cam, kind in ((program, "cam program"), (table, "table")):
        with pytest.raises(DynamicsError, match="non-finite times"):
            cam.svaj(np.array([0.0, np.nan]))
        with pytest.raises(DynamicsError, match=rf"got -0\.001 s; a one-shot {kind} starts at t = 0"):
            cam.svaj(np.array([-1e-3, 0.0]))
    periodic = CamProgram.indexing("modified-sine")
    early = periodic.svaj(np.array([-0.25 * periodic.period_s]))[0]
    late = periodic.svaj(np.array([0.75 * periodic.period_s]))[0]
    assert early[0] == pytest.approx(late[0] - periodic.advance_m, abs=1e-12)
