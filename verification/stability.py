"""Stability map: where each method gives a bounded, accurate answer, and where it blows up or fails.

Each case is one method at one setting (time step dt for the fixed-step methods, rtol for the adaptive
ones, none for exact and modal) on the default linear chain (verification.workprecision.chain_problem)
with a given link stiffness and number of links, started from rest for one index cycle at 180 rpm
with one-degree outputs. Outcomes:
- "accurate": finished, max |y - y_ref| <= `accuracy` * max |y_ref| (y relative to the cam);
- "inaccurate": finished and bounded, but off by more than that;
- "diverged": SolverDivergedError (the central-difference refusal above 2 / omega_max, or the
  divergence check on a run that grew without bound);
- "failed": SolverFailedError (an adaptive integrator that could not finish).
The reference is the exact first-order-hold solution (verification.workprecision.reference_response).

Theory drawn on the map: central difference is stable for dt <= 2 / omega_max (omega_max the largest
undamped natural frequency of (K, M), proportional to sqrt(k)); `central_difference_spectral_radius`
gives the amplification of one undamped mode per step, 1 up to omega dt = 2 and above 1 beyond.
Newmark (average acceleration) and HHT are unconditionally stable; their error grows with omega dt of
the excited modes. Explicit RK45/DOP853 stay bounded by shrinking the step to ~3/omega_max, so they
do not fail, they slow down in proportion to sqrt(k).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dynamics.errors import DynamicsError, SolverDivergedError, SolverFailedError
from dynamics.solvers import cache as solver_cache
from dynamics.solvers import solve
from dynamics.solvers._common import max_frequency
from verification.workprecision import IVP_METHODS, LinearChainProblem, chain_problem, options_for, reference_response

OUTCOMES = ("accurate", "inaccurate", "diverged", "failed")
MAP_METHODS = (
    "central-difference",
    "newmark",
    "hht",
    "rk45",
    "dop853",
    "radau",
    "bdf",
    "lsoda",
    "report-rk45",
    "exact",
    "modal",
)
STIFFNESSES_N_PER_M = (1e6, 1e7, 1e8, 1e9, 1e10)


def central_difference_limit_s(system) -> float:
    """Largest stable central-difference step 2 / omega_max (s)."""
    return 2.0 / max_frequency(system)


def central_difference_spectral_radius(omega_dt) -> np.ndarray:
    """Spectral radius of the undamped central-difference step [[2 - (w dt)^2, -1], [1, 0]]:
    1 for w dt <= 2 (neutral), growing beyond (the amplitude multiplies by it every step)."""
    w2 = np.asarray(omega_dt, dtype=float) ** 2
    b = 2.0 - w2  # roots of r^2 - b r + 1 = 0
    disc = np.sqrt(np.clip(b * b - 4.0, 0.0, None))
    return np.where(np.abs(b) <= 2.0, 1.0, (np.abs(b) + disc) / 2.0)


@dataclass(frozen=True)
class StabilityCase:
    method: str
    parameter_name: str  # "dt_s", "rtol" or ""
    parameter: float
    stiffness_N_per_m: float
    n_links: int
    outcome: str  # one of OUTCOMES
    relative_error: float  # nan unless finished
    wall_s: float
    omega_max_rad_s: float
    message: str = ""

    @property
    def central_difference_limit_s(self) -> float:
        return 2.0 / self.omega_max_rad_s


def map_settings(method: str, problem: LinearChainProblem, quick: bool = False) -> tuple[str, list[float]]:
    """The map's axis for a method: steps on one absolute grid for all stiffnesses (so the limit
    line crosses it), rtol for the adaptive methods, nothing for exact and modal."""
    h = problem.output_step_s
    if method in ("central-difference", "newmark", "hht"):
        return "dt_s", [h / 4**j for j in range(0, 4 if quick else 5)]
    if method in IVP_METHODS or method == "report-rk45":
        return "rtol", [10.0**-e for e in ((2, 6) if quick else (2, 4, 6))]
    if method in ("exact", "modal"):
        return "", [np.nan]
    raise DynamicsError(f"method: got {method!r}; expected one of {', '.join(MAP_METHODS)}")


def classify(
    problem: LinearChainProblem,
    method: str,
    parameter_name: str,
    parameter: float,
    reference_x: np.ndarray,
    accuracy: float = 1e-2,
) -> StabilityCase:
    """Run one case and sort it into an outcome (see the module doc)."""
    if not (0.0 < accuracy < 1.0):
        raise DynamicsError(f"accuracy: got {accuracy!r}; expected a relative error in (0, 1)")
    opts = options_for(method, parameter_name, parameter)
    common = (method, parameter_name, parameter, problem.model.stiffness_N_per_m, problem.model.n_links)
    omega_max = max_frequency(problem.system)
    solver_cache.clear()
    start = time.perf_counter()
    try:
        x = solve(
            problem.system, problem.force, problem.t_eval_s, method=method, x0=problem.x0, v0=problem.v0, **opts
        ).x
    except SolverDivergedError as exc:
        return StabilityCase(*common, "diverged", np.nan, time.perf_counter() - start, omega_max, str(exc))
    except SolverFailedError as exc:
        return StabilityCase(*common, "failed", np.nan, time.perf_counter() - start, omega_max, str(exc))
    wall = time.perf_counter() - start
    rel = float(np.max(np.abs(x - reference_x)) / np.max(np.abs(reference_x)))
    return StabilityCase(*common, "accurate" if rel <= accuracy else "inaccurate", rel, wall, omega_max)


def stability_map(
    methods=MAP_METHODS,
    stiffnesses_N_per_m=STIFFNESSES_N_PER_M,
    n_links=(10, 85),
    *,
    quick: bool = False,
    accuracy: float = 1e-2,
    cycles: float = 1.0,
) -> list[StabilityCase]:
    """Every (method, setting, stiffness, N) case on the default chain; see the module doc."""
    cases = []
    for n in n_links:
        for k in stiffnesses_N_per_m:
            problem = chain_problem(int(n), stiffness_N_per_m=float(k), cycles=cycles)
            ref = reference_response(problem)
            for method in methods:
                name, values = map_settings(method, problem, quick)
                cases.extend(classify(problem, method, name, v, ref, accuracy) for v in values)
    return cases
