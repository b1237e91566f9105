"""What runs before the FEA's process starts stays light, and each light name agrees with its
implementation (issue #24: the FEA is on the critical path, and the settings' checks used to import
the chain's models and solvers, numba and SciPy, 0.8 s before it could start)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numba", "scipy", "skfem", "matplotlib", "dynamics.solvers", "dynamics.scene", "dynamics.models.clearance")

# parse and check the default command line as pipeline.main does before `run` starts the FEA
PRE_FEA = """
import json, sys
import pipeline
import fem.cache, processes, stages.beside  # noqa: F401, E401  (what start_fea imports before the child starts)
from fem import load_materials
from stages.fea import fea_cache_settings, fea_settings
cfg = pipeline.parse_cli(["--rayleigh", "0:1e-5", "--tensioner-mass", "2", "--span-damping", "global"])
settings = fea_settings(cfg)
fea_cache_settings(cfg, settings, load_materials()["al6061-t6"], None)
print(json.dumps(sorted(sys.modules)))
"""


def _loaded_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    return set(json.loads(out.stdout.splitlines()[-1]))


def _heavy(modules: set[str]) -> list[str]:
    return sorted(m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY))


def test_the_settings_and_their_checks_import_no_solver_numba_scipy_or_matplotlib():
    loaded = _loaded_after(PRE_FEA)
    assert "settings.checks" in loaded and "dynamics.options" in loaded  # the checks did run
    assert _heavy(loaded) == []


def test_the_declared_solver_methods_are_the_implemented_ones():
    from dynamics.options import SOLVER_METHODS
    from dynamics.solvers import METHODS

    assert tuple(SOLVER_METHODS) == tuple(METHODS)
    for method_id, method in METHODS.items():
        assert method.handles_nonlinear_force == SOLVER_METHODS[method_id].handles_nonlinear_force


def test_the_models_check_against_the_declared_names():
    """The implementations read the light module's names (one home), so the settings' names are theirs."""
    import dynamics.models.clearance as clearance
    import dynamics.models.machine as machine
    import dynamics.options as options
    import dynamics.scene as scene
    from settings import registries

    assert scene.MODEL_CHOICES is options.MODEL_CHOICES is registries.chain_models()
    assert machine.DRIVES is options.DRIVES is registries.drives()
    assert clearance.SPAN_DAMPING_LAWS is options.SPAN_DAMPING_LAWS is registries.span_damping_laws()
    assert clearance.Tensioner is scene.Tensioner


def test_a_light_name_refused_where_the_models_refuse_it():
    import pytest

    from dynamics.errors import DynamicsError
    from dynamics.models.tensioner import Tensioner, tensioner_from
    from dynamics.options import parse_rayleigh

    assert tensioner_from(None, None, None) is None
    assert tensioner_from(None, 2.0, None) == Tensioner(0.0, 2.0, 0.0)
    with pytest.raises(ValueError, match="carriage mass"):
        tensioner_from(1e5, None, None)
    for bad in (float("nan"), float("inf"), -1.0):
        with pytest.raises(DynamicsError, match="mass_kg"):
            Tensioner(0.0, bad)
    assert parse_rayleigh("0.5:1e-5") == (0.5, 1e-5)
    for bad in ("1", "a:b", "nan:0", "0:inf", "-1:0"):
        with pytest.raises(ValueError, match="ALPHA:BETA"):
            parse_rayleigh(bad)


def test_the_declared_fea_choices_are_the_implemented_ones():
    import pytest

    from fem.errors import FemError
    from fem.options import ELEMENT_ORDERS, LINEAR_SOLVERS
    from fem.problem import ELEMENTS, element
    from fem.settings import FeaSettings
    from fem.solvers import SOLVERS, resolve
    from settings import registries

    assert tuple(ELEMENTS) == ELEMENT_ORDERS == registries.ELEMENT_ORDERS
    assert tuple(SOLVERS) == LINEAR_SOLVERS
    assert resolve("auto") in LINEAR_SOLVERS
    for bad in (0, 3):
        with pytest.raises(
            FemError, match=f"element order {bad}: expected one of {', '.join(map(str, ELEMENT_ORDERS))} "
        ):
            element(bad)
        with pytest.raises(
            FemError, match=f"element order {bad}: expected one of {', '.join(map(str, ELEMENT_ORDERS))} "
        ):
            FeaSettings(order=bad)
    with pytest.raises(
        FemError, match=f"linear solver 'cholmod': expected one of auto, {', '.join(LINEAR_SOLVERS)}; set it with"
    ):
        FeaSettings(solver="cholmod")


# what `python pipeline.py` imports before it starts the FEA's process (stages.fea.waiting_fea_process)
PRE_WAITING_FEA = """
import json, sys
import pipeline
from stages.fea import waiting_fea_process  # noqa: F401
print(json.dumps(sorted(sys.modules)))
"""


def test_the_fea_process_starts_before_numpy_gmsh_or_the_part_are_imported():
    loaded = _loaded_after(PRE_WAITING_FEA)
    assert [m for m in ("numpy", "gmsh", "geometry") if m in loaded] == []
    assert _heavy(loaded) == []


def test_the_fea_process_imports_modules_that_exist():
    """A waiting FEA process that cannot import one of them fails the run (stages.beside)."""
    import importlib.util

    from stages.fea import FEA_MODULES

    assert [m for m in FEA_MODULES if importlib.util.find_spec(m) is None] == []
