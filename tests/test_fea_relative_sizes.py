"""Default FEA mesh sizes are relative to the part (pitch, bore radius), so one default serves a
12.7 mm-pitch roller-chain plate 1.5 mm thick and a 300 mm link alike; thin walls warn."""

from __future__ import annotations

import dataclasses
import warnings

import gmsh
import pytest

from fem import get_material, stiffness_study
from fem.errors import FemWarning
from fem.quality import thin_wall_warning, thinnest_wall_m
from fem.study import default_mesh_sizes, part_scale
from geometry import DEFAULT_LINK, load_link, write_step
from geometry.session import gmsh_model
from geometry.step_io import write_model_step

ALUMINIUM = get_material("al6061-t6")
LARGE_SCALE = 0.300 / DEFAULT_LINK.pitch_m
ROLLER_PITCH_M, ROLLER_THICKNESS_M, ROLLER_BORE_RADIUS_M, ROLLER_OUTER_RADIUS_M = 0.0127, 0.0015, 0.00255, 0.0059


def roller_chain_plate(path):
    """A roller-chain link plate (ANSI 40 size): two discs of 5.9 mm radius 12.7 mm apart joined by
    their tangent strip, bores of 2.55 mm radius, 1.5 mm thick (OpenCASCADE, written as STEP)."""
    with gmsh_model("roller-plate"):
        occ = gmsh.model.occ
        t, p, r = ROLLER_THICKNESS_M, ROLLER_PITCH_M, ROLLER_OUTER_RADIUS_M
        parts = [(3, occ.addCylinder(x, 0, 0, 0, 0, t, r)) for x in (0.0, p)]
        parts.append((3, occ.addBox(0, -r, 0, p, 2 * r, t)))
        body, _ = occ.fuse(parts[:1], parts[1:])
        bores = [(3, occ.addCylinder(x, 0, -t, 0, 0, 3 * t, ROLLER_BORE_RADIUS_M)) for x in (0.0, p)]
        occ.cut(body, bores)
        occ.synchronize()
        write_model_step(path, unit="mm")
    return path


def scaled_link(path, scale: float):
    dims = dataclasses.replace(
        DEFAULT_LINK, **{f.name: getattr(DEFAULT_LINK, f.name) * scale for f in dataclasses.fields(DEFAULT_LINK)}
    )
    return write_step(dims, path, unit="mm")


@pytest.fixture(scope="module")
def parts(tmp_path_factory):
    d = tmp_path_factory.mktemp("parts")
    return {"plate": roller_chain_plate(d / "plate.step"), "large": scaled_link(d / "large.step", LARGE_SCALE)}


def test_default_link_levels_are_6_and_4_5_mm():
    assert default_mesh_sizes(None) == pytest.approx((0.006, 0.0045), rel=0.01)


def test_sizes_scale_with_the_part(parts):
    pitch, bore, hole = part_scale(parts["large"])
    assert pitch == pytest.approx(0.300, rel=1e-9)
    assert bore == pytest.approx(DEFAULT_LINK.bore_radius_m * LARGE_SCALE, rel=1e-9)
    for big, small in zip(default_mesh_sizes(parts["large"]), default_mesh_sizes(None)):
        assert big == pytest.approx(small * LARGE_SCALE, rel=1e-9)


def test_roller_plate_gets_elements_well_inside_its_thickness(parts):
    assert part_scale(parts["plate"]) == pytest.approx((ROLLER_PITCH_M, ROLLER_BORE_RADIUS_M, float("inf")), rel=1e-9)
    finest = default_mesh_sizes(parts["plate"])[-1]
    assert finest == pytest.approx(ROLLER_PITCH_M / 25, rel=1e-9)  # the pitch governs here
    assert finest < ROLLER_THICKNESS_M / 2.5


def test_thin_wall_is_measured_and_warned_about(parts):
    coarse = load_link(parts["plate"], mesh_size_m=0.004)  # elements much thicker than the plate
    assert thinnest_wall_m(coarse.points_m, coarse.tets, 0.005) == pytest.approx(ROLLER_THICKNESS_M, rel=1e-6)
    message = thin_wall_warning(coarse)
    assert message is not None and "1.5 mm thick" in message and "--mesh-size" in message
    assert "\n" not in message
    assert thin_wall_warning(load_link(parts["plate"], mesh_size_m=0.001)) is None


@pytest.mark.slow
def test_one_default_gives_about_one_percent_on_a_small_plate_and_a_large_link(parts):
    with warnings.catch_warnings():
        warnings.simplefilter("error", FemWarning)  # neither has a wall thinner than its elements
        plate = stiffness_study(parts["plate"], ALUMINIUM)
        large = stiffness_study(parts["large"], ALUMINIUM)
    default = stiffness_study(None, ALUMINIUM)
    for estimate in (plate, large, default):
        assert estimate.stiffness_rel_error_estimate < 0.01
    # Geometrically similar parts with meshes scaled alike: k scales with the length (k ~ E L).
    assert large.stiffness_N_per_m / LARGE_SCALE == pytest.approx(default.stiffness_N_per_m, rel=0.005)


def test_a_small_hole_is_refined_locally_and_an_assembly_is_scaled_by_its_body(tmp_path):
    from geometry.assembly import LinkSource
    from geometry.sample_parts import write_part

    write_part("nest_holes", tmp_path / "nest.step")
    pitch, bore, hole = part_scale(tmp_path / "nest.step")
    assert (pitch, bore, hole) == pytest.approx((0.1016, 0.00635, 0.0015), rel=1e-6)  # the 3 mm grease hole
    # The sizes come from the pitch and the pin bores (0.52 x 6.35 mm); the grease hole gets its own
    # finer elements from a size field (geometry.meshing.small_hole_fields), not the whole part.
    assert default_mesh_sizes(tmp_path / "nest.step") == pytest.approx(
        (0.52 * 0.00635 * 4 / 3, 0.52 * 0.00635), rel=1e-6
    )
    write_part("assembly", tmp_path / "assembly.step")  # body, pins and bushings: the body's pair counts
    assert part_scale(LinkSource(tmp_path / "assembly.step"))[:2] == part_scale(tmp_path / "assembly.step")[:2]
    assert part_scale(tmp_path / "assembly.step")[0] > 0


def test_a_variant_of_the_built_in_link_is_scaled_by_its_own_dimensions():
    from dataclasses import replace

    variant = replace(DEFAULT_LINK, bore_radius_m=0.006)
    assert part_scale(variant) == (variant.pitch_m, 0.006, float("inf"))
