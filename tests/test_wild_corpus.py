"""The wild corpus: eleven public STEP files made by others (../shared/wild/, its README), one test
per part, each a `python -m fem FILE --material al6061-t6 --json` run in a child process as a new
user would start it: the outcome (k, or a one-line refusal naming the feature and the option),
no traceback, and the child's peak memory (getrusage of the child, measured by a wrapper process)
within the default memory budget (fem.budget.DEFAULT_MAX_MEMORY_GB).

Reference stiffnesses, and how they were obtained (al6061-t6, E = 68.9 GPa, nu = 0.33):
- arm_bar_400mm_inventor.stp: 1.50462e8 N/m, this code at --mesh-size 3.5 (levels 4.67 / 3.5 mm,
  369k unknowns on the finest, estimate +-0.054 %), after the small-hole size fields made it mesh.
- robot_arm_link_pockets_inventor.stp: 1.99184e7 N/m, the converged reference quoted in issue 23
  (fine meshes, extrapolated).
- gripper_connector_2holes_inventor.stp: 3.74275e7 N/m, this code at --mesh-size 0.25 (half the
  default; levels 0.333 / 0.25 mm, estimate +-0.053 %, the default run's +-0.31 %).
- gripper_connector_3holes_inventor.stp: 2.32139e7 N/m, this code at --mesh-size 0.325 (half the
  default; levels 0.433 / 0.325 mm, estimate +-0.19 %, the default run's +-0.81 %).
- quadruped_upper_leg_onshape.step --bores=-103.32,2.2,-25:4.95,-15.05,-3.55: 3.65541e7 N/m, three
  levels of this code's meshes (curved P2, bore refinement 0.7): the default run's 2.011 / 1.508 mm
  (193,707 / 368,547 unknowns, k 3.68296e7 / 3.66995e7) and a third at 1.131 mm (757,803 unknowns,
  k 3.66252e7, solved with --solver amg: 6.0 GB, 24 min on a loaded 2-core machine); their observed
  rate in h = DOFs^(-1/3) is 2.98 and Richardson's extrapolation of the finest pair at that rate gives
  the reference (inside the finest pair's own bracket, 3.6351e7-3.6593e7). One level meshed and solved by
      geometry.mesh_part(part, mesh_size_m=0.001131, order=2, bore_refinement=0.7)
      fem.analyse_link(link, fem.get_material("al6061-t6"), solver="amg")
- arm_bar_slots_inventor.stp --bores 30,30,-30:20,370,-30: 4.0213e7 N/m, four levels of this code's
  meshes, each meshed and solved alone as above (curved P2, bore refinement 0.7, PARDISO):
      mesh size mm   unknowns   k N/m
      7.62667        73,566     4.04436e7
      5.72           136,878    4.03788e7
      4.29           277,965    4.03434e7
      3.2175         578,154    4.03144e7   (7.2 GB peak, 155 s)
  Their differences shrink by 0.55 and then 0.82: the observed rate in h = DOFs^(-1/3) falls from
  3.3 (levels 1-3, not yet asymptotic) to 0.98 (levels 2-4), near the h^1.09 of a sharp re-entrant
  edge (the part has sharp concave corners). Richardson's extrapolation of the finest pair at rates 0.98 to
  1.09 gives 4.0207e7 to 4.0219e7; the reference is their middle (+-0.015 %). Not shown by a fifth
  level (about 1.2M unknowns, over the memory this machine could spare).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from benchmarks.wild_corpus import ABSENT, WILD
from fem.budget import DEFAULT_MAX_MEMORY_GB, ESTIMATE_LOW_RATIO
from fem.cli import build_parser
from fem.settings import DEFAULT_BORE_REFINEMENT
from geometry.mesh_estimate import estimated_dofs
from geometry.options import link_source
from geometry.part import resolve_part

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(WILD is None, reason=ABSENT)

# The wrapper runs the command and reports its children's peak resident memory (KB on Linux).
_WRAPPER = (
    "import resource, subprocess, sys; rc = subprocess.call(sys.argv[1:]); "
    "print('peak_rss_kb', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); sys.exit(rc)"
)
BUDGET_BYTES = DEFAULT_MAX_MEMORY_GB * 1e9
# The unknowns estimated before meshing (geometry.mesh_estimate) against the real ones of every
# level that runs: the budget trusts the estimate's low end (ESTIMATE_LOW_RATIO); 0.85-1.04 measured.
ESTIMATE_HIGH_RATIO = 1.25
REFUSAL_SECONDS = 60  # a refusal is decided before any meshing (a few seconds on a quiet machine)


@dataclass(frozen=True)
class Run:
    returncode: int
    stdout: str
    error_lines: list[str]  # stderr without the wrapper's line
    peak_bytes: float
    seconds: float

    @property
    def result(self) -> dict:
        return json.loads(self.stdout)


def assert_unknowns_as_estimated(run: Run, name: str, *options: str) -> None:
    """Every level's real unknowns within the band of the estimate made before meshing."""
    path = str(WILD / name)
    features = resolve_part(link_source(path, build_parser().parse_args([path, *options]))).geometry.mesh_features
    levels = run.result["levels"]
    for i, level in enumerate(levels):
        half = i == len(levels) - 1 and run.result["mirror_plane"] is not None  # the finest on a mirror half
        size = level["mesh_size_m"]
        estimate = estimated_dofs(features, size, DEFAULT_BORE_REFINEMENT * size, 2, half)
        assert ESTIMATE_LOW_RATIO <= level["dofs"] / estimate <= ESTIMATE_HIGH_RATIO, (size, level["dofs"], estimate)


def run_fem(name: str, *args: str, timeout: float = 1800) -> Run:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    start = time.perf_counter()
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            _WRAPPER,
            sys.executable,
            "-m",
            "fem",
            str(WILD / name),
            "--material",
            "al6061-t6",
            "--json",
            *args,
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
        cwd=ROOT,
    )
    seconds = time.perf_counter() - start
    lines = done.stderr.strip().splitlines()
    peak = [line for line in lines if line.startswith("peak_rss_kb ")]
    return Run(
        done.returncode,
        done.stdout,
        [line for line in lines if not line.startswith("peak_rss_kb ")],
        float(peak[-1].split()[1]) * 1024,
        seconds,
    )


def assert_refused(run: Run, *phrases: str) -> str:
    assert run.returncode == 2, run.error_lines
    assert not any("Traceback" in line for line in run.error_lines)
    errors = [line for line in run.error_lines if line.startswith("python -m fem: error: ")]
    assert len(errors) == 1, run.error_lines
    for phrase in phrases:
        assert phrase in errors[0], errors[0]
    assert run.peak_bytes < BUDGET_BYTES
    assert run.seconds < REFUSAL_SECONDS
    return errors[0]


def assert_k_within_estimate(run: Run, reference_N_per_m: float) -> dict:
    assert run.returncode == 0, run.error_lines
    assert not any("Traceback" in line for line in run.error_lines)
    r = run.result
    error = abs(r["stiffness_N_per_m"] / reference_N_per_m - 1)
    assert error <= r["stiffness_rel_error_estimate"], (r["stiffness_N_per_m"], r["stiffness_rel_error_estimate"])
    assert run.peak_bytes < BUDGET_BYTES
    return r


# --- refused, in one line naming the feature and the option ------------------------------------------


def test_conrod_is_refused_naming_its_open_r35_big_end():
    assert_refused(run_fem("conrod_fusion360.step"), "r 35 mm bore at 0,0,0 mm is open", "half bore", "--bores")


def test_odri_lower_leg_is_refused_naming_its_open_knee_seat_not_the_screw_holes_across_it():
    message = assert_refused(run_fem("odri_lower_leg_solidworks.step"), "r 11.5 mm bore", "293 deg", "--bores")
    assert "r 1.550 at 6,8,0" in message  # the M3 holes are listed as full holes, not taken for pins


def test_so101_under_arm_is_refused_naming_its_largest_open_bore():
    assert_refused(run_fem("so101_under_arm_fusion360.step"), "r 8 mm bore at -10.8499,-32,0 mm is open", "--bores")


def test_arm_bar_with_slots_is_refused_as_not_an_equal_bore_link():
    assert_refused(run_fem("arm_bar_slots_inventor.stp"), "r 11.000 at 30,30,-30, r 2.500 at 20,370,-30", "--bores")


def test_grip_link_of_four_identical_solids_is_refused_asking_for_the_body():
    assert_refused(run_fem("grip_link_4x_inventor.stp"), "solids 1, 2, 3, 4", "--body N")


def test_quadruped_lower_leg_with_one_bore_is_refused():
    assert_refused(run_fem("quadruped_lower_leg_onshape.step"), "r 4.750 at -102.804,2.3,-25", "--bores")


def test_quadruped_upper_leg_is_refused_listing_its_holes():
    assert_refused(run_fem("quadruped_upper_leg_onshape.step"), "r 2.900 at 4.95,-15.05,-3.55", "--bores")


# --- computed, k within its estimate of a converged reference, within the budget --------------------

# N/m, al6061-t6; how each was obtained: the module docstring.
REFERENCE_K = {
    "arm_bar_400mm_inventor.stp": 1.50462e8,
    "robot_arm_link_pockets_inventor.stp": 1.99184e7,
    "gripper_connector_2holes_inventor.stp": 3.74275e7,
    "gripper_connector_3holes_inventor.stp": 2.32139e7,
    "quadruped_upper_leg_onshape.step": 3.65541e7,
    "arm_bar_slots_inventor.stp": 4.0213e7,
}


def test_gripper_connector_with_two_holes_gives_k_within_its_estimate():
    run = run_fem("gripper_connector_2holes_inventor.stp")
    r = assert_k_within_estimate(run, REFERENCE_K["gripper_connector_2holes_inventor.stp"])
    assert_unknowns_as_estimated(run, "gripper_connector_2holes_inventor.stp")
    assert r["pitch_m"] == pytest.approx(0.0125, rel=1e-9)


def test_gripper_connector_with_three_holes_takes_the_end_pair_and_gives_k_within_its_estimate():
    run = run_fem("gripper_connector_3holes_inventor.stp")
    r = assert_k_within_estimate(run, REFERENCE_K["gripper_connector_3holes_inventor.stp"])
    assert_unknowns_as_estimated(run, "gripper_connector_3holes_inventor.stp")
    assert r["pitch_m"] == pytest.approx(0.020, rel=1e-9)  # the holes at -10 and +10 mm, not the middle one


@pytest.mark.slow
def test_arm_bar_400mm_gives_k_at_the_default_settings_within_the_budget():
    # Its four r 1.05 mm screw holes used to set a 2.1 mm size everywhere (305k tets, no answer in
    # 300 s, a PyPardisoError traceback); now they are refined locally.
    run = run_fem("arm_bar_400mm_inventor.stp")
    r = assert_k_within_estimate(run, REFERENCE_K["arm_bar_400mm_inventor.stp"])
    assert_unknowns_as_estimated(run, "arm_bar_400mm_inventor.stp")
    assert r["pitch_m"] == pytest.approx(0.340, rel=1e-9)


@pytest.mark.slow
def test_robot_arm_link_gives_k_at_the_default_settings_within_its_estimate():
    # It used to stop with "inverted curved cells remain after straightening" at the default size,
    # and at 3 mm give k 6.4 % low, outside its estimate: straightening had cut its 2 mm rounds off.
    run = run_fem("robot_arm_link_pockets_inventor.stp")
    r = assert_k_within_estimate(run, REFERENCE_K["robot_arm_link_pockets_inventor.stp"])
    assert_unknowns_as_estimated(run, "robot_arm_link_pockets_inventor.stp")
    assert r["pitch_m"] == pytest.approx(0.200, rel=1e-9)


def test_a_mesh_size_over_the_memory_budget_is_refused_before_solving_naming_the_options():
    run = run_fem("gripper_connector_2holes_inventor.stp", "--mesh-size", "0.3", "--max-memory", "0.6")
    assert_refused(run, "--mesh-size 0.3", "over the memory budget of 0.6 GB", "--max-memory GB")


def test_a_hopeless_mesh_size_on_the_400mm_arm_bar_is_refused_before_meshing():
    # 1 mm everywhere on the 400 mm bar: millions of unknowns. It is refused from the estimate made
    # before meshing, in the time of a refusal, instead of after minutes of meshing.
    run = run_fem("arm_bar_400mm_inventor.stp", "--mesh-size", "1")
    assert_refused(run, "--mesh-size 1: at least about", "estimated before meshing", "--max-memory GB")


def test_default_sizes_over_a_small_budget_are_coarsened_with_a_one_line_warning():
    run = run_fem("gripper_connector_2holes_inventor.stp", "--max-memory", "0.6")
    assert run.returncode == 0, run.error_lines
    warning = [line for line in run.error_lines if "memory budget" in line]
    assert len(warning) == 1 and "--max-memory 0.6 GB; k computed at" in warning[0], run.error_lines
    assert run.result["mesh_size_m"] > 0.0005  # coarser than the default 0.5 mm


# --- two unequal bores named by --bores: allowed, each meshed for its radius, within the budget --------


def assert_ran_within_budget(run: Run) -> dict:
    assert run.returncode == 0, run.error_lines
    assert not any("Traceback" in line for line in run.error_lines)
    assert run.peak_bytes < BUDGET_BYTES
    return run.result


@pytest.mark.slow
def test_arm_bar_with_slots_runs_on_its_unequal_bores_named_by_hand():
    # It was killed by the kernel at 23.2 GiB: the r 2.5 mm bore set the size of the whole 400 mm bar.
    # Its finest level then fell back to straight cells (scikit-fem's inverse facet map stopped at
    # round-off at its loaded bore, 370 mm from the origin) beside a curved coarse level: k was
    # 4.0314e7 +- 0.17 %, 0.25 % above the reference, outside its estimate.
    bores = "30,30,-30:20,370,-30"
    run = run_fem("arm_bar_slots_inventor.stp", "--bores", bores)
    r = assert_k_within_estimate(run, REFERENCE_K["arm_bar_slots_inventor.stp"])
    assert_unknowns_as_estimated(run, "arm_bar_slots_inventor.stp", "--bores", bores)
    assert r["curved_elements"]
    assert "unequal bores: the fixed one (r 11 mm) is clamped all round" in r["part"]["pin_bores"]["rule"]
    assert r["stiffness_rel_error_estimate"] < 0.01


@pytest.mark.slow
def test_quadruped_upper_leg_runs_on_the_bores_named_by_hand_with_negative_coordinates():
    # It took 13 GiB and 2:52 before failing.
    bores = "--bores=-103.32,2.2,-25:4.95,-15.05,-3.55"
    run = run_fem("quadruped_upper_leg_onshape.step", bores)
    r = assert_k_within_estimate(run, REFERENCE_K["quadruped_upper_leg_onshape.step"])
    assert_unknowns_as_estimated(run, "quadruped_upper_leg_onshape.step", bores)
    assert r["pitch_m"] == pytest.approx(0.1103, rel=0.01)
    assert r["stiffness_rel_error_estimate"] < 0.01
