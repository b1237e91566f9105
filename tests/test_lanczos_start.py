"""Every eigsh call in dynamics starts from `lanczos_start`: the O(N) set-up of a long machine (the
damping's range and nodes, the top and the lowest frequencies) is bit-identical from one process to
the next, whatever eigsh calls the process made before. ARPACK's own random start moves with every
call, so without the fixed start a process that had built another model first gave node weights
about 1e-10 apart."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

# One process's build of the 500-link machine on its wheels; with "other" first a 450-link one's
BUILD = """
import hashlib, json, sys
import numpy as np
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import Tensioner
from dynamics.models.clearance_machine import _top_frequency_sparse
from dynamics.models.layout import MachineLayout
from dynamics.models.machine_damping import of_machine
from dynamics.models.reduced_damping import eigenvalue_bounds
from dynamics.models.wheels import Wheel

wheel = Wheel(12, 0.1125, 6, 0.688)
layout = MachineLayout("wheels", wheel, wheel, None, True)

def build(n):
    chain = ChainModel(n, 2.03, 9.331e7)
    machine = layout.machine(chain, Tensioner(1e5, 5.0, 100.0))
    red = of_machine(machine)
    arrays = [red.weights, red.factors, red.sm, red.scalars, red.border,
              [_top_frequency_sparse(machine)], machine.lowest_natural_frequencies_Hz(10), eigenvalue_bounds(chain)]
    return [np.asarray(a, dtype=float).ravel().tolist() for a in arrays]

if sys.argv[1] == "other":
    build(450)
print(json.dumps(build(500)))
"""


def _build(first: str) -> list[np.ndarray]:
    out = subprocess.run(
        [sys.executable, "-c", BUILD, first], capture_output=True, text=True, check=True, cwd=ROOT, timeout=120
    )
    return [np.array(a) for a in json.loads(out.stdout.strip().splitlines()[-1])]


def test_a_long_machines_setup_is_bit_identical_in_two_processes():
    fresh, after_another = _build("none"), _build("other")
    assert len(fresh) == len(after_another)
    for a, b in zip(fresh, after_another, strict=True):
        np.testing.assert_array_equal(a, b)
