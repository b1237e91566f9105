"""The CAD-variants example (examples/cad_variants.toml): it parses, its three STEP files exist and
are three different links (the FEA cache and the study tell them by content), and they are what
examples/cad_variants/write_variants.py writes. No FEA: the files' own geometry is not meshed."""

from __future__ import annotations

import importlib.util
import re

import numpy as np
from study_cluster import ROOT

from geometry import DEFAULT_LINK, resolve_part
from study.sampling import design_points
from study.sensitivity import first_order_indices
from study.spec import load_study
from study.tasks import base_config

EXAMPLE = ROOT / "examples" / "cad_variants.toml"
FILES = [
    "cad_variants/link_web_5mm.step",
    "cad_variants/link_web_6.858mm.step",
    "cad_variants/link_web_9mm.step",
]


def test_example_parses_with_three_variants():
    spec = load_study(EXAMPLE)
    assert list(spec.parts) == FILES
    assert all(spec.parts[f].path == EXAMPLE.parent / f for f in FILES)
    points = design_points(spec, base_config(spec.settings))
    assert len(points) == 3 * 2 * spec.sampling.points  # variants x cam laws x Latin hypercube
    assert {p.inputs["geometry_file"] for p in points} == set(FILES)


def test_variant_files_are_distinct_small_links():
    parts = [resolve_part(EXAMPLE.parent / f) for f in FILES]
    assert len({p.fingerprint for p in parts}) == 3
    assert all(len(p.step_bytes) < 200_000 for p in parts)


def _solid_lines(text: str) -> list[str]:
    """The STEP file's data section without its header (which holds the time of writing), and with
    the product's name cleared of OpenCASCADE's count of the files this process wrote before."""
    data = text[text.index("DATA;") :]
    return re.sub(r"(Open CASCADE STEP translator [\d.]+) \d+", r"\1", data).splitlines()


def test_variants_are_what_the_script_writes(tmp_path):
    script = EXAMPLE.parent / "cad_variants" / "write_variants.py"
    module = importlib.util.module_from_spec(importlib.util.spec_from_file_location("write_variants", script))
    module.__spec__.loader.exec_module(module)
    WEBS_M, write_variants = module.WEBS_M, module.write_variants
    assert list(WEBS_M) == [f.split("/")[1] for f in FILES]
    assert sorted(WEBS_M.values()) == [0.005, DEFAULT_LINK.web_thickness_m, 0.009]
    for written in write_variants(tmp_path):
        shipped = (EXAMPLE.parent / "cad_variants" / written.name).read_text()
        assert _solid_lines(written.read_text()) == _solid_lines(shipped), written.name


def test_metric_set_by_the_list_variables_alone_has_zero_range_indices():
    """A body mass that only the CAD variant sets: its mean over the variants is constant up to
    rounding, so the range variables' indices are 0, not RBD-FAST's 0/0 (NaN)."""
    rng = np.random.default_rng(1)
    X = rng.random((128, 2))
    masses = np.array([0.3424, 0.3727, 0.4076])
    Y = np.tile(np.repeat(masses, 2), (128, 1)) * (1 + 1e-16 * rng.standard_normal((128, 6)))
    labels = {"geometry_file": ["a", "a", "b", "b", "c", "c"], "cam": ["x", "y"] * 3}
    indices = {i.input: i for i in first_order_indices(X, ["rpm", "preload_N"], Y, labels, seed=1)}
    assert indices["rpm"].first_order == 0.0 and indices["preload_N"].first_order == 0.0
    assert abs(indices["geometry_file"].first_order - 1) < 1e-9
