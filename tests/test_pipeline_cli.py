"""`python pipeline.py` end to end on coarse settings: outputs, JSON keys, cache, bad input."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import matplotlib.image
import pytest
from browser import page_in_browser, screenshot

import pipeline
from geometry import EXAMPLE_STEP
from settings import cam_ids

ROOT = Path(__file__).resolve().parents[1]
# Coarse on purpose: 3 FEA levels ending at 10 mm and a short chain keep one run to seconds.
COARSE = ["--mesh-size", "10", "--drive", "link", "--links", "12", "--samples-per-degree", "2", "-q"]
STATIONS = ("drive-end", "tight-side", "idler-end", "slack-side")
STATION_KEYS = (
    "link",
    "rms_displacement_m",
    "rms_velocity_m_s",
    "rms_acceleration_m_s2",
    "max_abs_acceleration_m_s2",
    "max_deviation_m",
    "residual_vibration_m",
)
PER_LINK_KEYS = ("rms_displacement_m", "rms_velocity_m_s", "rms_acceleration_m_s2", "max_abs_acceleration_m_s2")


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fea-cache")


@pytest.fixture(scope="module")
def default_run(tmp_path_factory, cache_dir) -> Path:
    out = tmp_path_factory.mktemp("results")
    assert pipeline.main([*COARSE, "--out", str(out), "--cache-dir", str(cache_dir)]) == 0
    return out


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def test_summary_has_the_documented_keys_in_si(default_run):
    s = _summary(default_run)
    assert s["geometry"]["source"] == "default"
    assert 0.11 < s["geometry"]["pitch_m"] < 0.115  # the default link's 112.5 mm pitch, in metres
    assert 1e-4 < s["geometry"]["body_volume_m3"] < 2e-4
    assert set(s["cams"]) == set(cam_ids())
    for cam in s["cams"].values():
        assert set(cam) == {"input_rms_displacement_m", "input_rms_velocity_m_s", "input_rms_acceleration_m_s2"}
    assert set(s["materials"]) == {"al6061-t6", "ti-grade2"}
    for m in s["materials"].values():
        for key in ("stiffness_N_per_m", "body_mass_kg", "lumped_mass_kg"):
            assert m[key] > 0
        assert len(m["natural_frequencies_Hz"]) == 10
        assert m["lumped_mass_kg"] > m["body_mass_kg"]
        for cam in m["cams"].values():
            assert set(cam["stations"]) == set(STATIONS)
            for station in cam["stations"].values():
                assert all(k in station for k in STATION_KEYS)
                assert station["settling_band_m"] == 0.0005
                assert station["settling_time_s"] is None or 0 <= station["settling_time_s"] <= 0.042
            for k in PER_LINK_KEYS:
                assert len(cam["per_link"][k]) == 12
            assert cam["peak_tension_N"] >= cam["min_tension_N"]
    assert {"fea", "dynamics", "outputs", "total"} <= set(s["timing_s"])


def test_stations_follow_matlab_rounding(default_run):
    stations = _summary(default_run)["materials"]["al6061-t6"]["cams"]["modified-sine"]["stations"]
    assert {k: v["link"] for k, v in stations.items()} == {
        "drive-end": 1,
        "tight-side": 9,
        "idler-end": 6,
        "slack-side": 3,
    }


def test_titanium_link_is_stiffer_and_heavier(default_run):
    m = _summary(default_run)["materials"]
    assert m["ti-grade2"]["stiffness_N_per_m"] > m["al6061-t6"]["stiffness_N_per_m"]
    assert m["ti-grade2"]["body_mass_kg"] > m["al6061-t6"]["body_mass_kg"]


class _Collector(HTMLParser):
    def __init__(self):
        super().__init__()
        self.images, self.tables = [], 0

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.images.append(dict(attrs)["src"])
        self.tables += tag == "table"


def test_outputs_tables_plots_and_a_self_contained_report(default_run):
    names = {p.name for p in default_run.iterdir()}
    for expected in (
        "summary.json",
        "report.html",
        "rms_table.csv",
        "rms_table.md",
        "max_acceleration_table.csv",
        "ranking.csv",
        "ranking.md",
        "stations.csv",
        "tension.csv",
        "residual_vibration.png",
        "al6061-t6_deformed.png",
        "ti-grade2_deformed.png",
        "al6061-t6_tension.png",
    ):
        assert expected in names
    assert not [n for n in names if n.startswith(".staging")]
    page = _Collector()
    page.feed((default_run / "report.html").read_text())
    assert page.tables >= 5
    assert len(page.images) >= 8
    assert all(src.startswith("data:image/png;base64,") for src in page.images)
    header = (default_run / "rms_table.csv").read_text().splitlines()[0]
    assert "cam input" in header and "al6061-t6 % difference" in header


def test_report_opens_in_a_real_browser_with_every_picture_drawn(default_run, tmp_path):
    seen = page_in_browser(default_run / "report.html")
    assert seen.title == "link-conveyor: chain vibration report"
    for section in ("Run", "Link stiffness and mass", "Which cam law", "Link tension and stress"):
        assert section in seen.sections
    assert seen.tables >= 5 and seen.text_chars > 2000
    embedded = (default_run / "report.html").read_text().count("data:image/png;base64,")
    assert seen.images == embedded >= 8
    assert seen.images_drawn == seen.images  # every embedded PNG decoded to a picture with a size
    pixels = matplotlib.image.imread(screenshot(default_run / "report.html", tmp_path / "report.png"))
    assert pixels.shape[:2] == (2000, 1300) and pixels[..., :3].std() > 0.05  # drawn, not a blank page


def test_second_run_with_another_cam_and_speed_reuses_the_fea(default_run, cache_dir, tmp_path):
    out = tmp_path / "again"
    assert (
        pipeline.main(
            [*COARSE, "--out", str(out), "--cache-dir", str(cache_dir), "--cams", "cycloidal", "--rpm", "120"]
        )
        == 0
    )
    s = _summary(out)
    first = _summary(default_run)
    for name, m in s["materials"].items():
        assert m["fea_from_cache"] is True
        assert m["stiffness_N_per_m"] == first["materials"][name]["stiffness_N_per_m"]
    assert list(s["cams"]) == ["cycloidal"]
    # Slower cam, same lift: the input's RMS velocity scales with speed.
    ratio = s["cams"]["cycloidal"]["input_rms_velocity_m_s"] / first["cams"]["cycloidal"]["input_rms_velocity_m_s"]
    assert ratio == pytest.approx(120 / 180, rel=1e-9)


def test_another_geometry_file_changes_the_results(default_run, cache_dir, tmp_path):
    out = tmp_path / "example"
    assert (
        pipeline.main(
            [
                *COARSE,
                "--no-images",
                "--materials",
                "al6061-t6",
                "--cams",
                "modified-sine",
                "--geometry",
                str(EXAMPLE_STEP),
                "--out",
                str(out),
                "--cache-dir",
                str(cache_dir),
            ]
        )
        == 0
    )
    s, first = _summary(out), _summary(default_run)
    assert s["geometry"]["source"] == str(EXAMPLE_STEP)
    assert s["materials"]["al6061-t6"]["fea_from_cache"] is False
    k_example = s["materials"]["al6061-t6"]["stiffness_N_per_m"]
    assert k_example != first["materials"]["al6061-t6"]["stiffness_N_per_m"]
    a_example = s["materials"]["al6061-t6"]["cams"]["modified-sine"]["stations"]["tight-side"]
    a_default = first["materials"]["al6061-t6"]["cams"]["modified-sine"]["stations"]["tight-side"]
    assert a_example["rms_acceleration_m_s2"] != a_default["rms_acceleration_m_s2"]


def test_preset_mqp2012_runs_for_a_short_chain_and_stays_si(tmp_path):
    out = tmp_path / "replica"
    assert (
        pipeline.main(["--preset", "mqp2012", "--links", "24", "--cams", "modified-sine", "-q", "--out", str(out)]) == 0
    )
    s = _summary(out)
    ms = s["materials"]["al6061-t6"]["cams"]["modified-sine"]
    # Report-scale numbers in SI: ~0.16 m RMS displacement, not ~160 (mm).
    assert 0.1 < ms["table1_rms_displacement_m"] < 0.2
    assert s["materials"]["al6061-t6"]["stiffness_N_per_m"] == 92696969.7
    assert (out / "report_comparison.csv").exists()


def _cli(*args, cwd=ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(ROOT / "pipeline.py"), *args], capture_output=True, text=True, cwd=cwd, timeout=600
    )


@pytest.mark.parametrize(
    "args, named",
    [
        (["--geometry", "no/such/link.step"], "--geometry"),
        (["--materials", "unobtainium"], "--materials"),
        (["--cams", "modified-sine,square-wave"], "--cams"),
        (["--links", "0"], "--links"),
        (["--links", "100000"], "--links"),
        (["--rpm", "-5"], "--rpm"),
        (["--friction", "1.5"], "--friction"),
        (["--damping", "1.0"], "--damping"),
        (["--preload", "-1"], "--preload"),
        (["--nest-mass", "-0.1"], "--nest-mass"),
        (["--mesh-size", "0"], "--mesh-size"),
        (["--solver", "euler"], "--solver"),
        (["--solver", "newmark"], "--solver"),
        (["--preset", "mqp2012", "--links", "5"], "--links"),
        (["--preset", "mqp2012", "--cams", "simple-harmonic"], "--cams"),
        (["--preset", "mqp2012", "--materials", "steel-1018"], "--materials"),
        (["--rpm-sweep", "300:60:1"], "--rpm-sweep"),
        (["--tolerance", "2"], "--tolerance"),
        (["--settling-band", "0"], "--settling-band"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_out_untouched(args, named, existing_out):
    r = _cli(*args, "--out", str(existing_out))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and named in lines[0] and "Traceback" not in r.stderr
    assert (existing_out / "summary.json").read_text() == '{"earlier": true}'
    assert sorted(p.name for p in existing_out.iterdir()) == ["summary.json"]


@pytest.mark.parametrize("size_mm", ["0.00001", "500"])
def test_a_mesh_size_the_part_refuses_names_the_option(size_mm, tmp_path, existing_out):
    # Refused when the part is meshed (too many tetrahedra / larger than the part), not by the parser.
    r = _cli("--mesh-size", size_mm, "--out", str(existing_out), "--cache-dir", str(tmp_path / "c"), "-q")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--mesh-size in mm" in lines[0] and "Traceback" not in r.stderr
    assert sorted(p.name for p in existing_out.iterdir()) == ["summary.json"]


def test_a_geometry_file_that_is_not_step_is_refused(tmp_path, existing_out):
    fake = tmp_path / "link.step"
    fake.write_text("this is not a STEP file\n")
    r = _cli("--geometry", str(fake), "--out", str(existing_out), "--cache-dir", str(tmp_path / "c"), "-q")
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert sorted(p.name for p in existing_out.iterdir()) == ["summary.json"]


def test_unwritable_out_is_refused(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    r = _cli("--out", str(blocker / "results"))
    assert r.returncode == 2
    assert "--out" in r.stderr and "Traceback" not in r.stderr


def test_help_explains_units():
    r = _cli("--help")
    assert r.returncode == 0
    for unit in ("rev/min", "N", "kg", "mm"):
        assert unit in r.stdout


def test_tolerance_picks_the_resolution_and_reports_an_estimate_within_it(cache_dir, tmp_path):
    out = tmp_path / "tol"
    assert (
        pipeline.main(
            [
                "--drive",
                "link",
                "--links",
                "12",
                "--cams",
                "modified-sine",
                "--materials",
                "al6061-t6",
                "--no-images",
                "-q",
                "--tolerance",
                "0.2",
                "--out",
                str(out),
                "--cache-dir",
                str(cache_dir),
            ]
        )
        == 0
    )
    s = _summary(out)
    fidelity = s["fidelity"]
    assert fidelity["tolerance"] == 0.2
    assert fidelity["tolerance_met"] is True and fidelity["tolerance_not_met_because"] is None
    assert fidelity["fea"]["al6061-t6"]["stiffness_rel_error_estimate"] <= 0.1
    assert fidelity["dynamics"]["metrics_rel_error_estimate"] <= 0.2
    estimate = s["materials"]["al6061-t6"]["cams"]["modified-sine"]["rel_error_estimate"]
    assert estimate["total"] == pytest.approx(estimate["time_step"] + estimate["stiffness"])


def test_rpm_sweep_writes_curves_with_critical_speeds(cache_dir, tmp_path):
    out = tmp_path / "sweep"
    assert (
        pipeline.main(
            [
                *COARSE,
                "--no-images",
                "--materials",
                "al6061-t6",
                "--cams",
                "modified-sine,poly-345",
                "--rpm-sweep",
                "60:240:10",
                "--out",
                str(out),
                "--cache-dir",
                str(cache_dir),
            ]
        )
        == 0
    )
    sweep = _summary(out)["rpm_sweep"]["al6061-t6"]
    assert sweep["rpm"][0] == 60 and sweep["rpm"][-1] == 240 and len(sweep["rpm"]) == 19
    assert set(sweep["cams"]) == {"modified-sine", "poly-345"}
    assert all(len(c["residual_vibration_m"]) == 19 for c in sweep["cams"].values())
    assert all(60 <= c["rpm"] <= 240 for c in sweep["critical_speeds"])
    assert (out / "al6061-t6_rpm_sweep.png").exists() and (out / "rpm_sweep.csv").exists()
    csv_rows = list(csv.DictReader((out / "rpm_sweep.csv").open()))
    assert len(csv_rows) == 2 * 19 and {row["seating_model"] for row in csv_rows} == {""}  # the link drive: no seats


def test_a_locking_prone_material_with_p1_is_warned_about_in_one_line(tmp_path):
    rubbery = tmp_path / "materials.toml"
    rubbery.write_text(
        "[nearly-incompressible]\nyoungs_modulus_Pa = 70e9\npoisson_ratio = 0.49\n"
        "density_kg_per_m3 = 2700.0\nyield_strength_Pa = 200e6\n"
    )
    out = tmp_path / "p1"
    # 4.5 mm (P1: cheap): at the 10 mm used before, the elements of the filleted link are thicker
    # than its 2.5 mm rails and a few are slivers, which now warns too, rightly.
    r = _cli(
        "--materials-file",
        str(rubbery),
        "--materials",
        "nearly-incompressible",
        "--order",
        "1",
        "--mesh-size",
        "4.5",
        "--drive",
        "link",
        "--links",
        "12",
        "--cams",
        "modified-sine",
        "--no-images",
        "-q",
        "--out",
        str(out),
        "--cache-dir",
        str(tmp_path / "cache"),
    )
    assert r.returncode == 0, r.stderr
    warning_lines = [line for line in r.stderr.splitlines() if "warning" in line]
    assert len(warning_lines) == 1 and "P1" in warning_lines[0] and "Traceback" not in r.stderr
    assert _summary(out)["materials"]["nearly-incompressible"]["fea_warnings"]


def test_a_one_station_question_keeps_one_link_and_gives_the_same_numbers(default_run, cache_dir, tmp_path):
    out = tmp_path / "station"
    assert (
        pipeline.main(
            [*COARSE, "--no-images", "--station", "idler-end", "--out", str(out), "--cache-dir", str(cache_dir)]
        )
        == 0
    )
    one, full = _summary(out), _summary(default_run)
    assert one["stations"] == {"idler-end": 6} and one["ranking"]["station"] == "idler-end"
    for material, data in one["materials"].items():
        for cam, result in data["cams"].items():
            assert list(result["stations"]) == ["idler-end"]
            assert all(len(values) == 1 for values in result["per_link"].values())
            mine = result["stations"]["idler-end"]
            everyone = full["materials"][material]["cams"][cam]["stations"]["idler-end"]
            for key, value in everyone.items():
                # Same solver, same grid: only the stored columns differ, so the numbers agree to rounding.
                assert mine[key] == (
                    value if value is None or isinstance(value, int) else pytest.approx(value, rel=1e-9)
                )
    assert not list(out.glob("*three_links.png"))


@pytest.mark.slow  # 25-56 s: the linear chain in 400 modes with friction, then the clearance chain's steady state
def test_cli_at_1200_links_runs_the_clearance_chain_to_steady_state_with_every_links_metrics(cache_dir, tmp_path):
    out = tmp_path / "long"
    r = _cli(
        *COARSE,
        "--no-images",
        "--links",
        "1200",
        "--materials",
        "al6061-t6",
        "--cams",
        "modified-sine",
        "--out",
        str(out),
        "--cache-dir",
        str(cache_dir),
    )
    assert r.returncode == 0, r.stderr
    m = _summary(out)["materials"]["al6061-t6"]
    assert len(m["natural_frequencies_Hz"]) == 10 and m["natural_frequencies_Hz"][0] > 0
    assert len(m["cams"]["modified-sine"]["per_link"]["rms_acceleration_m_s2"]) == 1200
    assert m["cams"]["modified-sine"]["stations"]["tight-side"]["link"] == 900
    scenario = m["cams"]["modified-sine"]
    assert scenario["model"] == "clearance" and scenario["clearance_steady_state"]["found"]
