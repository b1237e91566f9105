"""The chain's named options and the constants read outside the dynamics, declared without their
implementations: the settings check a run's choices against these names before the FEA's process
starts, and importing the models and solvers that implement them (numba, SciPy) took 0.8 s of that
start (`python -X importtime pipeline.py`); a study's client describes its columns with them.

Each name lives here once; the implementations import it from here and refuse an id not declared
here (dynamics.solvers builds `METHODS` from `SOLVER_METHODS`; tests/test_startup.py checks that
the two agree).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

MODEL_CHOICES = ("auto", "linear", "clearance")  # dynamics.scene: which chain model a scene simulates
DRIVES = ("link", "wheels")  # dynamics.models.machine: the report's single-point drive, or the wheels
SPAN_DAMPING_LAWS = ("global", "kelvin-voigt")  # dynamics.models.clearance: the span damping law

# ISO 286-2 close running fit H8/f7 at the default link's 19.05 mm (3/4 in) pin/bushing bore (the
# 18-30 mm size range): H8 = +0/+33 um, f7 = -20/-41 um, diametral clearance 20-74 um, mean 47 um
# per joint. A span has two pin joints: 2 x 47 um of axial free play.
DEFAULT_PIN_CLEARANCE_M = 94e-6

# The chain's defaults, read by dynamics.models.chain.ChainModel and by settings.RunConfig (each
# written once here): the sponsor's modal damping ratio of every chain mode, and the idler
# tensioner's static tension, uniform around the loop (also the load at which
# dynamics.models.wheels takes the default tooth contact stiffness)
DEFAULT_DAMPING_RATIO = 0.13
DEFAULT_PRELOAD_N = 2224.0

# Above this many links the pipeline solves in the lowest modes (dynamics.models.reduction, where the
# figures are) and the clearance chains take the O(N) damping (dynamics.models.machine_damping)
DENSE_LINK_LIMIT = 400

# The linear span law T = P + k e holds while a span stays in its link's elastic range. No structural
# metal stays elastic beyond about 1 % strain (sigma_y / E: 0.4 % for 6061-T6, 0.3 % for titanium grade
# 2, 0.7 % for 7075-T6, 1 % for maraging steel), and a link's stress concentrations only lower that
# limit: a span deformed from its unloaded length by more than this fraction of the pitch has yielded
# whatever the link, so the linear model's numbers there describe no chain (docs/physics.md;
# dynamics.scene.linear_model_validity applies it, study.records describes it)
LINEAR_ELASTIC_STRAIN_LIMIT = 0.01


@dataclass(frozen=True)
class SolverMethod:
    """A solver method's id and what it can model (its implementation: dynamics.solvers.METHODS)."""

    id: str
    handles_nonlinear_force: bool


SOLVER_METHODS: MappingProxyType = MappingProxyType(
    {
        m.id: m
        for m in (
            SolverMethod("exact", True),
            SolverMethod("modal", False),
            SolverMethod("newmark", False),
            SolverMethod("hht", False),
            SolverMethod("central-difference", True),
            SolverMethod("rk45", True),
            SolverMethod("dop853", True),
            SolverMethod("radau", True),
            SolverMethod("bdf", True),
            SolverMethod("lsoda", True),
            SolverMethod("report-rk45", True),
        )
    }
)


def parse_rayleigh(text: str) -> tuple[float, float]:
    """'ALPHA:BETA' -> (alpha 1/s, beta s), both finite and >= 0; ValueError otherwise."""
    parts = str(text).split(":")
    try:
        alpha, beta = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"expected ALPHA:BETA (C = alpha M + beta K, alpha in 1/s, beta in s), got {text!r}") from None
    if not all(math.isfinite(c) and c >= 0 for c in (alpha, beta)):
        raise ValueError(f"expected finite ALPHA:BETA >= 0, got {text!r}")
    return alpha, beta
