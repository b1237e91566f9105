"""The machine's compiled kernels loaded before the dynamics stage calls them (issue #24).

numba loads a cached kernel at its first call: the cache's index, the object code's unpickling and
LLVM's linking of each specialisation (about 0.15 CPU s for the machine's step, `machine_verlet._run`,
and its peaks' fold, `_step_peaks_into`, on the default run). `load_machine_kernels` makes those first
calls on a small machine whose arguments have the types the chain on its wheels passes (dense global
damping law in single precision, DAMPING_PRODUCT_PRECISIONS; the same types under the Kelvin-Voigt law
and any predictor), imports the modules the stage imports on its first scenario, and finds the BLAS
libraries the step loops limit to one thread (`_common.serial_blas`), so that an orchestration can do
all of it where a core is free (pipeline.py: while it waits for the FEA's stiffness). What it loads
is what the stage would load; the stage's answers do not depend on it.
"""

from __future__ import annotations

# the small machine's wheels: the default sprocket's 12 teeth with six links seated, on a chain long
# enough to have free spans between the two wheels
_TEETH, _WRAP_LINKS, _LINKS = 12, 6, 24
_PITCH_M = 0.1
_STEPS = 4


def load_machine_kernels() -> None:
    """Load the chain-on-wheels kernels (a few steps of a small machine, with station peaks), the
    dynamics stage's lazily imported modules and the BLAS thread limit's library scan."""
    import numpy as np

    import dynamics.cams  # noqa: F401
    import dynamics.machine_scene  # noqa: F401  (machine_steady, machine_shooting, machine_modes, ...)
    import dynamics.response.seating  # noqa: F401
    import dynamics.solvers.machine_ivp  # noqa: F401
    import dynamics.solvers.tooth_transfer  # noqa: F401
    from dynamics.machine_scene import station_dofs
    from dynamics.solvers import machine_verlet as mv
    from dynamics.solvers._common import serial_blas

    serial_blas()  # threadpoolctl's scan of the loaded libraries, once per process
    model = small_machine()
    nodes = np.zeros(_STEPS + 1)
    rest = np.zeros(model.n_state)
    step_s = 0.5 * mv.stable_step_s(model, 1.0, "ab2")
    mv.integrate(model, nodes, nodes, nodes, step_s, rest, rest, predictor="ab2", stations=station_dofs(model))


def small_machine():
    """A small chain on two wheels with free play (the kernels' argument types of every chain on its
    wheels up to DENSE_LINK_LIMIT links)."""
    from dynamics.models.chain import ChainModel
    from dynamics.models.clearance import DEFAULT_PIN_CLEARANCE_M
    from dynamics.models.clearance_machine import ClearanceMachine
    from dynamics.models.layout import MachineLayout
    from dynamics.models.wheels import Wheel

    wheel = Wheel(_TEETH, _PITCH_M, _WRAP_LINKS, 0.1)
    chain = ChainModel(n_links=_LINKS, link_mass_kg=2.0, stiffness_N_per_m=1e8)
    layout = MachineLayout("wheels", wheel, wheel, None, True)
    return ClearanceMachine.of(chain, layout, None, DEFAULT_PIN_CLEARANCE_M)
