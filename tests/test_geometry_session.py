"""The mirror half kept from a part's measurement (Part.measure_keeping_half) meshes exactly as the
half built afresh, is taken once, and leaves gmsh as it found it."""

import os
import subprocess
import sys
from pathlib import Path

import gmsh
import numpy as np

from geometry import session
from geometry.load import mesh_part
from geometry.part import resolve_part

SIZE_M = 8e-3  # coarse: the comparison needs any mesh, not a fine one
MESH_FIELDS = ("points_m", "tets", "tets10", "fixed_bore_facets", "loaded_bore_facets", "mirror_facets")


def _mesh(part):
    return mesh_part(part, mesh_size_m=SIZE_M, order=2, bore_refinement=0.4, mirror=True, wall_reference_m=SIZE_M)


def test_kept_half_meshes_as_a_fresh_half_and_is_taken_once():
    fresh_part = resolve_part(None)
    fresh_part.geometry  # noqa: B018 (measured without keeping anything)
    assert fresh_part.half_model_name not in session._KEPT
    fresh = _mesh(fresh_part)

    part = resolve_part(None)
    initialised_before = gmsh.isInitialized()
    part.measure_keeping_half()
    assert part.mirror_plane is not None
    assert part.half_model_name in session._KEPT
    kept = _mesh(part)
    assert part.half_model_name not in session._KEPT
    assert gmsh.isInitialized() == initialised_before  # the kept model's removal finalised what it initialised
    again = _mesh(part)  # nothing kept any more: the CAD built afresh

    for name in MESH_FIELDS:
        assert np.array_equal(getattr(kept, name), getattr(fresh, name)), name
        assert np.array_equal(getattr(again, name), getattr(fresh, name)), name


def test_a_kept_model_of_the_same_name_is_replaced_by_a_fresh_one():
    part = resolve_part(None)
    part.measure_keeping_half()
    with session.gmsh_model(part.half_model_name):
        assert gmsh.model.getEntities(3) == []  # the fresh model, not the kept half
    assert part.half_model_name not in session._KEPT
    with session.taken_model(part.half_model_name) as volumes:
        assert volumes is None


def test_gmsh_leaves_python_ignoring_sigpipe():
    """gmsh.initialize sets SIGPIPE to the default at the C level; `gmsh_model` (through
    `initialize_gmsh`) puts Python's SIG_IGN back, so a write to a pipe whose reader is gone raises
    BrokenPipeError instead of ending the process without a word. In a fresh process, whose death
    would otherwise take the test runner with it."""
    probe = (
        "import os\n"
        "from geometry.session import gmsh_model\n"
        "with gmsh_model('probe'):\n"
        "    pass\n"
        "read_end, write_end = os.pipe()\n"
        "os.close(read_end)\n"
        "try:\n"
        "    os.write(write_end, b'x')\n"
        "except BrokenPipeError:\n"
        "    print('BrokenPipeError')\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
    assert (done.returncode, done.stdout) == (0, "BrokenPipeError\n"), (done.returncode, done.stderr)


def test_the_run_s_stiffness_step_hands_the_study_the_kept_half(monkeypatch):
    """`stages.fea`'s stiffness step measures the part for its level sizes before the study: the
    measurement must keep its mirror half then, for the study's finest level (above: meshed in it
    as afresh), or the link's CAD is built a third time for that level."""
    import fem
    from fem.settings import FeaSettings
    from stages.fea import _solve_stiffness

    kept_when_called = []
    monkeypatch.setattr(
        fem,
        "stiffness_studies",
        lambda part, *args, **kwargs: kept_when_called.append(part.half_model_name in session._KEPT) or {},
    )
    part = resolve_part(None)
    try:
        _solve_stiffness(part, FeaSettings(), [], None, lambda line: None, None, 10**6)
        assert kept_when_called == [True]
    finally:
        with session.taken_model(part.half_model_name):  # removed: gmsh as the test found it
            pass


def test_the_planned_sizes_keep_the_half_for_the_finest_level():
    """`fem.study.planned_mesh_sizes` measures the part keeping its mirror half (the one home of that
    step: the study, the run's stiffness step and the benchmark only call it), which the finest
    level (`mesh_planned_level`) then meshes; without mirror symmetry nothing is kept."""
    from fem.settings import FeaSettings
    from fem.study import mesh_planned_level, planned_mesh_sizes

    whole = resolve_part(None)
    planned_mesh_sizes(whole, FeaSettings(mirror_symmetry=False))
    assert whole.half_model_name not in session._KEPT

    part = resolve_part(None)
    settings = FeaSettings.with_finest(SIZE_M)
    try:
        sizes, wall_reference_m = planned_mesh_sizes(part, settings)
        assert part.half_model_name in session._KEPT
        finest = mesh_planned_level(part, settings, sizes, len(sizes) - 1, wall_reference_m)
        assert part.half_model_name not in session._KEPT
        assert finest.mirror_plane is not None
        assert mesh_planned_level(part, settings, sizes, 0, wall_reference_m).mirror_plane is None
    finally:
        with session.taken_model(part.half_model_name):
            pass
