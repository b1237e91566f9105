"""Pin-bore detection across the ways CAD exporters write the same bores, and the manual override."""

import dataclasses
import math

import gmsh
import numpy as np
import pytest

from geometry import (
    DEFAULT_LINK,
    EXAMPLE_STEP,
    BoreOverride,
    GeometryError,
    LinkFeatures,
    load_link,
    write_step,
)
from geometry.bores import fit_cylinder
from geometry.parametric import add_link
from geometry.session import gmsh_model
from geometry.step_io import write_model_step

COARSE = 0.01
R = DEFAULT_LINK.bore_radius_m


def _check_default_bores(link, length):
    assert link.pitch_m == pytest.approx(DEFAULT_LINK.pitch_m, rel=1e-9)
    for bore, x in ((link.fixed_bore, -DEFAULT_LINK.pitch_m / 2), (link.loaded_bore, DEFAULT_LINK.pitch_m / 2)):
        # B-spline bores are fitted to exact rational circles: the fit is good to rounding (1e-12 m).
        assert bore.radius_m == pytest.approx(R, rel=1e-9)
        assert bore.length_m == pytest.approx(length, rel=1e-9)
        np.testing.assert_allclose(bore.center_m, [x, 0, DEFAULT_LINK.body_height_m / 2], atol=1e-9)
        np.testing.assert_allclose(bore.axis, [0, 0, 1], atol=1e-12)


@pytest.mark.parametrize(
    "features",
    [
        LinkFeatures(split_bores=True),
        LinkFeatures(bspline_bores=True),
        LinkFeatures(bore_edge_break_m=0.001),
        LinkFeatures(split_bores=True, bore_edge_break_m=0.0015),
    ],
    ids=["half-cylinders", "b-spline", "chamfer+fillet", "half-cylinders+chamfer+fillet"],
)
def test_same_bores_whatever_the_faces(tmp_path, features):
    path = write_step(DEFAULT_LINK, tmp_path / "link.step", features=features)
    link = load_link(path, mesh_size_m=COARSE)
    # A chamfer and a fillet of size b at the two ends shorten the cylindrical part by 2 b.
    _check_default_bores(link, DEFAULT_LINK.body_height_m - 2 * features.bore_edge_break_m)


def test_shipped_example_step():
    assert EXAMPLE_STEP.is_file() and EXAMPLE_STEP.stat().st_size < 1_000_000
    _check_default_bores(load_link(EXAMPLE_STEP, mesh_size_m=COARSE), DEFAULT_LINK.body_height_m - 0.002)


def test_concave_fillets_and_coaxial_lug_ends_are_not_bores(tmp_path):
    # The recess's four vertical inner corners become concave quarter cylinders; the lug ends are
    # convex half cylinders on the bores' axes. Neither may count as a bore. (Built on the
    # sharp-cornered variant: the default link has its own fillets since #13.)
    sharp = dataclasses.replace(
        DEFAULT_LINK, lug_fillet_radius_m=0.0, pocket_corner_radius_m=0.0, pocket_floor_radius_m=0.0
    )
    with gmsh_model("filleted"):
        volume = add_link(sharp)
        h = DEFAULT_LINK.body_height_m
        recess_edges = gmsh.model.getEntitiesInBoundingBox(
            -0.05, -0.039, DEFAULT_LINK.web_thickness_m - 1e-6, 0.05, 0.039, h + 1e-6, dim=1
        )
        corners = [c for _, c in recess_edges if _z_extent(c) > 1e-3]
        assert len(corners) == 4
        gmsh.model.occ.fillet([volume], corners, [0.004])
        gmsh.model.occ.synchronize()
        types = [gmsh.model.getType(2, s) for _, s in gmsh.model.getEntities(2)]
        assert types.count("Cylinder") >= 6  # two bores, four concave corner fillets, ...
        path = write_model_step(tmp_path / "filleted.step")
    _check_default_bores(load_link(path, mesh_size_m=COARSE), DEFAULT_LINK.body_height_m)


def _z_extent(curve):
    _, _, zmin, _, _, zmax = gmsh.model.getBoundingBox(1, curve)
    return zmax - zmin


def test_fixed_bore_is_the_lower_one_along_the_pitch_line(tmp_path):
    # The link turned by +-90 degrees (pitch along y): the bore built first ends up at -y, then +y.
    for angle, fixed_y in ((math.pi / 2, -1), (-math.pi / 2, -1)):
        with gmsh_model("turned"):
            volume = add_link(DEFAULT_LINK)
            gmsh.model.occ.rotate([(3, volume)], 0, 0, 0, 0, 0, 1, angle)
            gmsh.model.occ.synchronize()
            path = write_model_step(tmp_path / "turned.step")
        link = load_link(path, mesh_size_m=COARSE)
        assert np.sign(link.fixed_bore.center_m[1]) == fixed_y
        np.testing.assert_allclose(link.load_direction, [0, 1, 0], atol=1e-9)


def test_override_gives_the_detected_bores():
    detected = load_link(mesh_size_m=COARSE)
    half = DEFAULT_LINK.pitch_m / 2
    manual = load_link(
        mesh_size_m=COARSE,
        bores=BoreOverride((-half, 0.0, 0.0), (half, 0.0, 0.0), (0.0, 0.0, -1.0), R),
    )
    for a, b in ((detected.fixed_bore, manual.fixed_bore), (detected.loaded_bore, manual.loaded_bore)):
        np.testing.assert_allclose(a.center_m, b.center_m, atol=1e-12)
        np.testing.assert_allclose(a.axis, b.axis, atol=1e-12)
        assert (a.radius_m, a.length_m) == pytest.approx((b.radius_m, b.length_m), rel=1e-12)


def test_override_swaps_fixed_and_loaded_on_request():
    half = DEFAULT_LINK.pitch_m / 2
    link = load_link(mesh_size_m=COARSE, bores=BoreOverride((half, 0.0, 0.0), (-half, 0.0, 0.0), (0.0, 0.0, 1.0), R))
    assert link.fixed_bore.center_m[0] == pytest.approx(half)
    np.testing.assert_allclose(link.load_direction, [-1, 0, 0], atol=1e-12)


def test_override_that_misses_the_bore_is_an_error():
    half = DEFAULT_LINK.pitch_m / 2
    with pytest.raises(GeometryError, match="default: no face lies on the fixed bore"):
        load_link(mesh_size_m=COARSE, bores=BoreOverride((-half, 0.0, 0.0), (half, 0.0, 0.0), (0.0, 0.0, 1.0), 0.9 * R))


@pytest.mark.parametrize(
    "args, match",
    [
        (((0, 0, 0), (0.1, 0, 0), (0, 0, 0), 0.01), "expected a non-zero direction"),
        (((0, 0, 0), (0.1, 0, 0), (0, 0, 1), -0.01), "radius_m=-0.01"),
        (((0, 0, 0), (0.01, 0, 0), (0, 0, 1), 0.01), "more than two radii apart"),
        (((0, 0), (0.1, 0, 0), (0, 0, 1), 0.01), "3-vectors"),
    ],
)
def test_bad_override(args, match):
    with pytest.raises(GeometryError, match=match):
        BoreOverride(*args)


def test_fit_cylinder_recovers_an_oblique_cylinder_and_rejects_a_sphere():
    rng = np.random.default_rng(1)
    axis = np.array([1.0, 2.0, 2.0]) / 3
    u = np.cross(axis, [1, 0, 0])
    u /= np.linalg.norm(u)
    w = np.cross(axis, u)
    phi, t = rng.uniform(0, 2 * np.pi, 200), rng.uniform(-0.02, 0.02, 200)
    radial = np.outer(np.cos(phi), u) + np.outer(np.sin(phi), w)
    centre = np.array([0.1, -0.2, 0.05])
    cylinder = fit_cylinder(centre + 0.007 * radial + np.outer(t, axis), radial)
    assert cylinder.radius_m == pytest.approx(0.007, rel=1e-10)
    assert abs(cylinder.axis @ axis) == pytest.approx(1, abs=1e-12)
    assert cylinder.distance_to_axis(centre[None])[0] < 1e-10
    normals = rng.normal(size=(200, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    assert fit_cylinder(centre + 0.007 * normals, normals) is None
    flat = np.tile([0.0, 0.0, 1.0], (50, 1))
    assert fit_cylinder(rng.uniform(size=(50, 3)) * [1, 1, 0], flat) is None
