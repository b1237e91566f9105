"""Real-world-shaped parts (geometry/sample_parts.py), each exported to STEP by the test and re-imported:
which pin bores are chosen, the pitch, the volume against the CAD volume, assemblies, refusals,
and k against a finer-mesh reference within the estimated discretisation error."""

from __future__ import annotations

import math

import gmsh
import numpy as np
import pytest

import geometry.load
from fem import stiffness_study
from fem.materials import get_material
from fem.study import levels_for_finest
from geometry import GeometryError, load_link
from geometry.assembly import LinkSource, inspect_part
from geometry.pin_pair import BoreChoice
from geometry.sample_parts import MM, write_part
from geometry.session import gmsh_model
from geometry.step_io import write_model_step

NAMES = ("nest_holes", "counterbored", "chain_plate", "long_link", "assembly", "ambiguous", "half_bore")


@pytest.fixture(scope="module")
def parts(tmp_path_factory):
    """name -> (path, spec, CAD volume of each solid in m^3), built once for the module."""
    d = tmp_path_factory.mktemp("parts")
    return {name: (d / f"{name}.step", *write_part(name, d / f"{name}.step")) for name in NAMES}


def _axis_xy(bore):
    return bore.center_m[:2]


@pytest.mark.parametrize("name", ["nest_holes", "counterbored", "chain_plate", "long_link", "assembly"])
def test_the_pin_bores_are_chosen_and_the_body_volume_is_the_cads(parts, name):
    path, spec, volumes = parts[name]
    summary = inspect_part(path)
    np.testing.assert_allclose(_axis_xy(summary.pins.fixed.bore), spec.fixed_axis_point_m[:2], atol=1e-9)
    np.testing.assert_allclose(_axis_xy(summary.pins.loaded.bore), spec.loaded_axis_point_m[:2], atol=1e-9)
    assert summary.pins.fixed.bore.radius_m == pytest.approx(spec.bore_radius_m, rel=1e-9)
    assert summary.pins.pitch_m == pytest.approx(spec.pitch_m, rel=1e-9)
    assert summary.n_solids == spec.n_solids and summary.body_index == spec.body_index + 1
    # STEP keeps 15+ digits: the re-imported body is the drawn one to rounding.
    assert summary.body_volume_m3 == pytest.approx(volumes[spec.body_index], rel=1e-9)


def test_nest_screw_holes_and_the_grease_hole_are_ignored_with_reasons(parts):
    reasons = [
        (round(h.hole.bore.radius_m / MM, 3), h.reason) for h in inspect_part(parts["nest_holes"][0]).pins.ignored
    ]
    assert sorted(reasons) == sorted(
        [(1.5, "not parallel to the pins")]
        + [(1.65, "smaller than the pin bores")] * 2
        + [(2.1, "smaller than the pin bores")] * 4
    )


def test_the_printed_choice_names_the_pair_the_rule_and_each_ignored_hole(parts):
    lines = inspect_part(parts["nest_holes"][0]).lines()
    assert lines[0] == (
        "pin bores       fixed at (0.00, 0.00, 8.00) mm, loaded at (101.60, 0.00, 8.00) mm, radius 6.350 mm, "
        "pitch 101.600 mm (equal parallel bores at the part's ends, the largest such, farthest apart; the ends of "
        "its length: along (1,0,0), 139.6 mm)"
    )
    assert "  ignored hole  r 2.100 mm at (32.80, -9.00, 8.00) mm: smaller than the pin bores" in lines
    assert len(lines) == 8


def test_lightening_holes_larger_than_the_pins_but_between_them_are_not_pins(parts):
    ignored = inspect_part(parts["long_link"][0]).pins.ignored
    assert [(round(h.hole.bore.radius_m / MM, 3), h.reason) for h in ignored] == [
        (15.0, "larger than the pin bores, between them (pins sit at the part's ends)")
    ] * 2


def test_a_through_hole_meeting_a_coaxial_counterbore_is_still_a_bore(parts):
    pins = inspect_part(parts["counterbored"][0]).pins
    # The fixed bore is the 10 mm through hole below its 16 mm counterbore: 10 mm of it remain.
    assert pins.fixed.bore.length_m == pytest.approx(10 * MM, rel=1e-9)
    # The loaded bore is chamfered 1 mm at both ends of the 14 mm thickness.
    assert pins.loaded.bore.length_m == pytest.approx(12 * MM, rel=1e-9)
    reliefs = [h for h in pins.ignored if h.reason.startswith("coaxial relief")]
    assert sorted(round(h.hole.bore.radius_m / MM, 3) for h in reliefs) == [5.5, 5.5, 8.0]


def test_assembly_hardware_is_measured_and_not_meshed(parts):
    path, spec, volumes = parts["assembly"]
    summary = inspect_part(path)
    assert [s.index for s in summary.hardware] == [2, 3, 4, 5]
    np.testing.assert_allclose([s.volume_m3 for s in summary.hardware], volumes[1:], rtol=1e-9)
    # Bushings sit in the body's bores; the pins sit in the bushings, clear of the body.
    assert [s.touches_body for s in summary.hardware] == [True, True, False, False]
    link = load_link(path, mesh_size_m=8 * MM)
    assert link.cad_volume_m3 == pytest.approx(volumes[0], rel=1e-9)
    assert _mesh_volume(link) == pytest.approx(volumes[0], rel=0.02)  # straight tets on the curved bores


def _mesh_volume(link) -> float:
    p = link.points_m[:, link.tets]
    return float(
        np.abs(np.einsum("ij,ij->j", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0], axis=0))).sum()
        / 6
    )


def test_two_solids_with_equally_good_pairs_need_body(tmp_path):
    # A roller-chain inner link: two identical plates (boxes with two 4 mm holes), 8 mm apart.
    def inner_link():
        occ = gmsh.model.occ
        for z in (0.0, 8 * MM):
            plate = occ.addBox(-6 * MM, -5 * MM, z, 24.7 * MM, 10 * MM, 1.5 * MM)
            occ.cut([(3, plate)], [(3, occ.addCylinder(x, 0, z - MM, 0, 0, 4 * MM, 2 * MM)) for x in (0, 12.7 * MM)])

    path = tmp_path / "inner_link.step"
    with gmsh_model("inner-link"):
        inner_link()
        gmsh.model.occ.synchronize()
        write_model_step(path)
    with pytest.raises(GeometryError, match=r"solids 1, 2 each hold an equally good pair .*--body N"):
        inspect_part(path)
    summary = inspect_part(LinkSource(path, body=2))
    assert summary.body_index == 2 and summary.pins.pitch_m == pytest.approx(12.7 * MM, rel=1e-9)
    assert [s.touches_body for s in summary.hardware] == [False]
    with pytest.raises(GeometryError, match=r"--body 3: .* holds 2 solid\(s\)"):
        inspect_part(LinkSource(path, body=3))


def test_two_equal_candidate_pairs_are_refused_with_the_list_and_the_option(parts):
    with pytest.raises(GeometryError) as info:
        inspect_part(parts["ambiguous"][0])
    message = str(info.value)
    assert "2 equally good pin-bore pairs" in message and "--bores" in message and "\n" not in message
    assert "0,-10,6:70,10,6" in message  # pasteable into --bores


def test_bores_option_resolves_the_ambiguity_fixed_bore_first(parts):
    source = LinkSource(parts["ambiguous"][0], BoreChoice((70 * MM, 10 * MM, 0.0), (0.0, -10 * MM, 0.0)))
    pins = inspect_part(source).pins
    np.testing.assert_allclose(_axis_xy(pins.fixed.bore), [0.07, 0.01], atol=1e-9)
    np.testing.assert_allclose(_axis_xy(pins.loaded.bore), [0.0, -0.01], atol=1e-9)
    assert pins.pitch_m == pytest.approx(math.hypot(70, 20) * MM, rel=1e-9)
    assert all(h.reason == "not named by --bores" for h in pins.ignored)


def test_pitch_and_radius_options_choose_among_candidates(parts):
    # The nest part's four 4.2 mm tapped holes: their 36 x 18 mm rectangle's long side is 36 mm.
    source = LinkSource(parts["nest_holes"][0], BoreChoice(pitch_m=36 * MM, radius_m=2.1 * MM))
    with pytest.raises(GeometryError, match="2 equally good pin-bore pairs .*pitch 36.000 mm"):
        inspect_part(source)
    source = LinkSource(parts["nest_holes"][0], BoreChoice(pitch_m=101.6 * MM))
    assert inspect_part(source).pins.pitch_m == pytest.approx(101.6 * MM, rel=1e-9)
    with pytest.raises(GeometryError, match=r"no pair .* matching --pitch 50 .*--bores"):
        inspect_part(LinkSource(parts["nest_holes"][0], BoreChoice(pitch_m=50 * MM)))


def test_an_open_half_bore_is_refused_naming_the_cap_and_the_option(parts):
    with pytest.raises(GeometryError, match=r"open \(about 180 deg, a half bore\).*cap.*--bores") as info:
        inspect_part(parts["half_bore"][0])
    assert "\n" not in str(info.value)
    with pytest.raises(GeometryError, match=r"--bores: the point 80,0,0 mm is on an open bore"):
        inspect_part(LinkSource(parts["half_bore"][0], BoreChoice((0.0, 0.0, 0.0), (80 * MM, 0.0, 0.0))))


def test_equal_holes_away_from_the_ends_are_not_taken_for_pins_unless_asked(tmp_path):
    # A 160 x 60 mm bracket with two equal 10 mm holes 40 mm apart in its middle: no link.
    def bracket():
        occ = gmsh.model.occ
        plate = occ.addBox(-60 * MM, -30 * MM, 0, 160 * MM, 60 * MM, 10 * MM)
        occ.cut([(3, plate)], [(3, occ.addCylinder(x, 0, -MM, 0, 0, 12 * MM, 5 * MM)) for x in (0, 40 * MM)])

    path = tmp_path / "bracket.step"
    with gmsh_model("bracket"):
        bracket()
        gmsh.model.occ.synchronize()
        write_model_step(path)
    with pytest.raises(GeometryError, match="no pair of equal parallel full-round bores at the part's ends.*--pitch"):
        inspect_part(path)
    assert inspect_part(LinkSource(path, BoreChoice(pitch_m=40 * MM))).pins.pitch_m == pytest.approx(40 * MM, rel=1e-9)


def test_a_part_that_cannot_be_a_link_is_refused_before_meshing(parts, monkeypatch):
    def no_meshing(*args, **kwargs):
        raise AssertionError("meshed a part that should have been refused")

    monkeypatch.setattr(geometry.load, "mesh_volumes", no_meshing)
    for name in ("ambiguous", "half_bore"):
        with pytest.raises(GeometryError):
            load_link(parts[name][0])


# k against a reference: the estimate's own levels vs three finer levels; the two must agree within
# the sum of their error estimates. Mesh sizes are scaled to each part by hand until relative
# default sizes land (issue #13); then these should use the defaults.
K_CASES = {
    "chain_plate": (1.2 * MM, 0.7 * MM),
    "counterbored": (4.5 * MM, 3.0 * MM),
    "long_link": (7 * MM, 5 * MM),  # 10 mm walls beside the lightening holes
    "assembly": (6 * MM, 4 * MM),
    "nest_holes": (2.6 * MM, 2.2 * MM),  # coarser levels fail in HXT on the 3 mm grease hole (see README)
}


@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=() if n == "chain_plate" else pytest.mark.slow) for n in K_CASES],
)
def test_k_agrees_with_a_finer_reference_within_the_estimate(parts, name):
    coarse, fine = K_CASES[name]
    material = get_material("al6061-t6")
    estimate = stiffness_study(parts[name][0], material, mesh_sizes_m=levels_for_finest(coarse), order=2)
    reference = stiffness_study(parts[name][0], material, mesh_sizes_m=levels_for_finest(fine), order=2)
    k, k_ref = estimate.stiffness_N_per_m, reference.stiffness_N_per_m
    allowed = estimate.stiffness_rel_error_estimate + reference.stiffness_rel_error_estimate
    assert abs(k - k_ref) / k_ref <= allowed, (k, k_ref, allowed)
    assert estimate.finest.pitch_m == pytest.approx(parts[name][1].pitch_m, rel=1e-9)
