"""tests/kernel_warm_up.py: its families load (compile, on an empty cache) every specialisation of
the step kernels that the solvers' entry points call on the suite's kinds of model, so that after the
xdist controller has run them (tests/conftest.py) no test compiles a step kernel."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent

# In a fresh process (this one has loaded kernels already): every family, then models of other
# sizes, laws and tensioners than the families' on each path, counting the loaded specialisations
_FAMILIES_THEN_OTHER_MODELS = """
import json
import numpy as np
import kernel_warm_up
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain, Tensioner
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models import machine_damping
from dynamics.models.layout import MachineLayout
from dynamics.models.wheels import Wheel
from dynamics.solvers import clearance_verlet as cv
from dynamics.solvers import machine_verlet as mv
from dynamics.solvers import ring_on_topology

kernels = {"ring": cv._run_compiled, "machine": mv._run, "peaks": mv._step_peaks_into}
counts = lambda: {name: len(kernel.signatures) for name, kernel in kernels.items()}
for family in kernel_warm_up.FAMILIES.values():
    family()
warm = counts()
tensioner = Tensioner(1e5, 5.0, 100.0)
nodes = np.zeros(9)
for law, predictor in (("global", "ab2"), ("kelvin-voigt", "euler")):
    ring = ClearanceChain(ChainModel(30, 2.03, 9e7, friction_coefficient=0.2), 50e-6, span_damping=law, tensioner=tensioner)
    h = 0.5 * cv.stable_step_s(ring, 1.0, predictor)
    cv.integrate(ring, nodes, nodes, h, np.zeros(30), np.zeros(30), predictor=predictor)
    ring_on_topology.integrate(ring, nodes, nodes, h, np.zeros(30), np.zeros(30), predictor=predictor, stations=[0, 5])
wheel = Wheel(17, 0.1, 4, 0.3)
above = machine_damping.SINGLE_PRECISION_FACTORS_ABOVE_LINKS
for links, law, single_factors in ((30, "kelvin-voigt", False), (500, "global", False), (2000, "global", False), (500, "global", True)):
    # the long chains' single-precision damping factors (above SINGLE_PRECISION_FACTORS_ABOVE_LINKS), forced
    machine_damping.SINGLE_PRECISION_FACTORS_ABOVE_LINKS = 0 if single_factors else above
    chain = ChainModel(links, 2.03, 9e7, damping_ratio=0.1, friction_coefficient=0.2)
    model = ClearanceMachine.of(chain, MachineLayout("wheels", wheel, wheel, None, True), tensioner, 50e-6, law)
    if single_factors:
        assert model.reduced_damping and model.arrays.reduced[3].dtype == np.float32
    predictor = cv.default_predictor(model)
    rest = np.zeros(model.n_state)
    h = 0.5 * mv.stable_step_s(model, 1.0, predictor)
    mv.integrate(model, nodes, nodes, nodes, h, rest, rest, predictor=predictor, stations=[0, links // 2])
print(json.dumps({"warm": warm, "after": counts()}))
"""


def test_the_families_load_every_step_kernel_specialisation_the_solvers_call():
    from dynamics.solvers import machine_verlet as mv

    if mv.numba is None:
        pytest.skip("numba not installed: the kernels are plain Python, nothing to compile")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(TESTS.parent), str(TESTS), env.get("PYTHONPATH")]))
    out = subprocess.run(
        [sys.executable, "-c", _FAMILIES_THEN_OTHER_MODELS],
        cwd=TESTS.parent,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    # the machine's step: one specialisation for C in double (the link drive) and in single (on its
    # wheels) and the O(N) damping's factors in either precision (machine_verlet.kernel_damping)
    assert counts["warm"] == {"ring": 1, "machine": 1, "peaks": 1}
    assert counts["after"] == counts["warm"]
