"""The compiled kernels' specialisations the fast suite calls, compiled into numba's on-disk cache
before the test workers start (tests/conftest.py, `pytest_sessionstart` of the xdist controller).

On a clean checkout numba's cache is empty: without this, the first test of each worker to call a
kernel compiles it (about 1 min of CPU per specialisation of the big step kernels), both workers often
the same one at once, and each pipeline or study run in a child process compiles it again until one
of them has written the cache. Here each family compiles once, the families in parallel processes,
before any test runs (about 60-90 CPU s each on an empty cache). Each family steps a tiny model a few steps through the solvers' own entry
points, so it compiles what they call with the types they pass; the answers are thrown away. A
family that compiles nothing new (a warm cache) only loads its kernels (about 1-2 s with the imports).
"""

from __future__ import annotations

import numpy as np

_STEPS = 4


def ring() -> None:
    """The ring's own kernel (dynamics.solvers.clearance_verlet, double), global and Kelvin-Voigt laws
    (one specialisation: the law is a run-time flag), with the energy's terms; and its numpy path
    (`compiled=False`), which calls the step's helpers as compiled functions of their own."""
    from dynamics.models.chain import ChainModel
    from dynamics.models.clearance import ClearanceChain
    from dynamics.solvers import clearance_verlet as cv

    chain = ChainModel(8, 2.03, 9.331e7, friction_coefficient=0.35)
    nodes = np.zeros(_STEPS + 1)
    rest = np.zeros(chain.n_links)
    for law, predictor in (("global", "ab2"), ("kelvin-voigt", "euler")):
        model = ClearanceChain(chain, 94e-6, span_damping=law)
        step_s = 0.5 * cv.stable_step_s(model, 1.0, predictor)
        for compiled in (True, False):
            cv.integrate(
                model, nodes, nodes, step_s, rest, rest, predictor=predictor, track_energy=True, compiled=compiled
            )


def machine() -> None:
    """The machine's step kernel, one specialisation for every machine (machine_verlet.kernel_damping):
    the chain on its wheels (C in single precision) with its stations' peaks, the pipeline's own
    warm-up (dynamics.warm_up, which every default run and study point calls), then the single-link
    drive (the ring on the topology kernel: C in double), which loads what the first compiled."""
    from dynamics.models.chain import ChainModel
    from dynamics.models.clearance_machine import ClearanceMachine
    from dynamics.models.layout import LINK_DRIVE
    from dynamics.solvers import machine_verlet as mv
    from dynamics.warm_up import load_machine_kernels

    load_machine_kernels()
    model = ClearanceMachine.of(ChainModel(8, 2.03, 9.331e7, friction_coefficient=0.35), LINK_DRIVE, None, 94e-6)
    nodes = np.zeros(_STEPS + 1)
    rest = np.zeros(model.n_state)
    mv.integrate(model, nodes, nodes, nodes, 0.5 * mv.stable_step_s(model, 1.0, "ab2"), rest, rest, predictor="ab2")


FAMILIES = {"machine": machine, "ring": ring}
