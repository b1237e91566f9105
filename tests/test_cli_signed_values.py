"""`--bores` takes negative CAD coordinates after a space (`--bores -0,-10,-3:70,10,20`), in
`pipeline.py` and in `python -m fem`: argparse alone reads such a value as an unknown option and
stops with "expected one argument"."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import pipeline
from geometry.options import signed_values_attached
from geometry.sample_parts import write_part

ROOT = Path(__file__).resolve().parents[1]
# the ambiguous plate's bores run along z through x = 0 and x = 70 mm; a point on the fixed bore's
# axis with every coordinate signed (x = -0) is the value argparse refused
SIGNED_BORES = "-0,-10,-3:70,10,20"


@pytest.fixture(scope="module")
def plate(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("signed-bores") / "ambiguous.step"
    write_part("ambiguous", path)
    return path


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["--bores", "-1,2,3:4,5,6"], ["--bores=-1,2,3:4,5,6"]),
        (["--bores", "-.5,2,3:4,5,6", "-q"], ["--bores=-.5,2,3:4,5,6", "-q"]),
        (["--bores=-1,2,3:4,5,6"], ["--bores=-1,2,3:4,5,6"]),
        (["--bores", "1,2,3:4,5,6"], ["--bores", "1,2,3:4,5,6"]),
        (["--bores", "--pitch", "5"], ["--bores", "--pitch", "5"]),  # a missing value stays argparse's error
        (["--", "--bores", "-1"], ["--", "--bores", "-1"]),
    ],
)
def test_only_a_signed_value_after_bores_is_attached(argv, expected):
    assert signed_values_attached(argv) == expected


def test_pipeline_reads_negative_bore_coordinates_after_a_space(plate):
    cfg = pipeline.parse_cli(["--geometry", str(plate), "--bores", SIGNED_BORES])
    choice = cfg.link_source.bores
    assert choice.fixed_point_m == pytest.approx((0.0, -0.010, -0.003), abs=1e-15)
    assert choice.loaded_point_m == pytest.approx((0.070, 0.010, 0.020), abs=1e-15)


def test_pipeline_refuses_a_bad_signed_value_naming_bores(plate, tmp_path, capsys):
    out = tmp_path / "out"
    assert pipeline.main(["--geometry", str(plate), "--bores", "-1,2,3", "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--bores '-1,2,3': expected" in err, err


def test_fem_reads_negative_bore_coordinates_after_a_space(plate):
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "fem",
            str(plate),
            "--json",
            "--mesh-size",
            "8",
            "--order",
            "1",
            "--bores",
            SIGNED_BORES,
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    # the given points as the tool prints them back (mm; -0 reads 0)
    assert json.loads(r.stdout)["part"]["pin_bores"]["rule"] == "given by --bores 0,-10,-3:70,10,20"
