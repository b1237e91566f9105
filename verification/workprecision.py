"""Work-precision measurement for the dynamics solvers: what each answer costs and how far it is off.

The test problem is the default chain, linear (friction 0) so that the reference is exact: N links of
mass m joined by springs k (plus the drive spring), the default modal damping ratio
(dynamics.options.DEFAULT_DAMPING_RATIO), written relative to the cam
(dynamics.models.chain), driven from rest by a continuous-indexing cam (default modified sine, 180 rpm,
45 deg index + 45 deg dwell, pitch 112.5 mm) over `cycles` index cycles, force and outputs sampled
every cam degree (first-order hold in between, as every solver sees it).

Error: max over links and output times of |y - y_ref| (m), y the links' displacement relative to the
cam (the same as the absolute displacement error, since z is given). The reference is the exact
first-order-hold solution computed with every interval split in 4 (different step matrices, so
different rounding; the test suite checks it against modal superposition with all modes). It is the
exact solution of the problem every method is handed, so the error is the method's own. How far that
problem is from the analytic cam (the sampling of z'' at one degree) is measured separately by
`force_sampling_error` and drawn as a line on the chart.

Wall time: one call of dynamics.solvers.solve, cold: the exact method's matrix-exponential cache is
cleared first, so its one-off set-up is counted (one scenario, nothing amortised).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dynamics.cams.program import CamProgram
from dynamics.errors import DynamicsError, SolverDivergedError, SolverFailedError
from dynamics.models.chain import ChainModel
from dynamics.models.system import SampledForce, SecondOrderSystem
from dynamics.options import DEFAULT_DAMPING_RATIO
from dynamics.solvers import METHODS, solve
from dynamics.solvers import cache as solver_cache
from dynamics.solvers._common import max_frequency

IVP_METHODS = ("rk45", "dop853", "radau", "bdf", "lsoda")
FIXED_STEP_METHODS = ("newmark", "hht", "central-difference")
ALL_METHODS = ("exact", "modal", *FIXED_STEP_METHODS, *IVP_METHODS, "report-rk45")
# atol = ATOL_PER_RTOL * rtol for the adaptive methods: MATLAB's default pair (1e-3, 1e-6) scaled
ATOL_PER_RTOL = 1e-3
REFERENCE_SUBSTEPS = 4


@dataclass(frozen=True)
class LinearChainProblem:
    """A linear chain-under-cam problem handed to dynamics.solvers.solve (relative coordinates)."""

    model: ChainModel
    law_id: str
    rpm: float
    system: SecondOrderSystem
    force: SampledForce
    t_eval_s: np.ndarray
    x0: np.ndarray
    v0: np.ndarray

    @property
    def output_step_s(self) -> float:
        return float(self.t_eval_s[1] - self.t_eval_s[0])

    @property
    def omega_max_rad_s(self) -> float:
        return max_frequency(self.system)


def chain_problem(
    n_links: int = 85,
    *,
    stiffness_N_per_m: float = 9e7,
    link_mass_kg: float = 2.0,
    law_id: str = "modified-sine",
    rpm: float = 180.0,
    cycles: float = 2.0,
    samples_per_degree: int = 1,
    damping_ratio: float = DEFAULT_DAMPING_RATIO,
) -> LinearChainProblem:
    """The default chain (friction 0) started from rest under an indexing cam; see the module doc."""
    if not (np.isfinite(cycles) and cycles > 0):
        raise DynamicsError(f"cycles: got {cycles!r}; expected a positive number of index cycles")
    if not (isinstance(samples_per_degree, (int, np.integer)) and samples_per_degree >= 1):
        raise DynamicsError(f"samples_per_degree: got {samples_per_degree!r}; expected an integer >= 1")
    model = ChainModel(n_links, link_mass_kg, stiffness_N_per_m, damping_ratio=damping_ratio)
    cam = CamProgram.indexing(law_id, rpm=rpm)
    n_steps = max(int(round(cycles * 90 * samples_per_degree)), 1)
    t = cycles * cam.cycle_s * np.arange(n_steps + 1) / n_steps
    _, zdot, zddot, _ = cam.svaj(t)
    force = SampledForce(t, model.base_excitation_force(zddot))
    x0 = np.zeros(n_links)
    v0 = -zdot[0] * np.ones(n_links)  # every link moves with the cam: relative velocity -z'
    return LinearChainProblem(model, law_id, float(rpm), model.system(), force, t, x0, v0)


def reference_response(problem: LinearChainProblem) -> np.ndarray:
    """Displacements (relative to the cam) at the output times, exact to rounding (see module doc)."""
    return solve(
        problem.system,
        problem.force,
        problem.t_eval_s,
        method="exact",
        x0=problem.x0,
        v0=problem.v0,
        substeps=REFERENCE_SUBSTEPS,
    ).x


def force_sampling_error(problem: LinearChainProblem, refinement: int = 16) -> float:
    """Max |y| difference (m) at the output times between the problem as sampled and the same chain
    under the cam sampled `refinement` times finer: the error every method inherits from handing
    the solver z'' at the output samples only."""
    cam = CamProgram.indexing(problem.law_id, rpm=problem.rpm)
    t = problem.t_eval_s
    fine = np.linspace(t[0], t[-1], refinement * (t.size - 1) + 1)
    force = SampledForce(fine, problem.model.base_excitation_force(cam.svaj(fine)[2]))
    y_fine = solve(problem.system, force, fine, method="exact", x0=problem.x0, v0=problem.v0).x[::refinement]
    return float(np.max(np.abs(y_fine - reference_response(problem))))


@dataclass(frozen=True)
class Measurement:
    method: str
    parameter_name: str  # "dt_s", "rtol", "n_modes" or "" (exact)
    parameter: float
    wall_s: float
    error_m: float  # nan unless status is "ok"
    status: str  # "ok", "diverged" (SolverDivergedError) or "failed" (SolverFailedError)
    message: str = ""


def settings(method: str, problem: LinearChainProblem, quick: bool = False) -> tuple[str, list[float]]:
    """The parameter each method is swept over, and its values (coarse to fine)."""
    h = problem.output_step_s
    n = problem.model.n_links
    if method == "exact":
        return "", [np.nan]
    if method == "modal":
        counts = [1, 3, 10, n] if quick else sorted({r for r in (1, 2, 3, 5, 10, 20, 40, 80, 160, 320) if r < n} | {n})
        return "n_modes", [float(r) for r in counts]
    if method in ("newmark", "hht"):
        return "dt_s", [h / 2**j for j in range(0, 4 if quick else 7)]
    if method == "central-difference":
        limit = 2.0 / problem.omega_max_rad_s
        return "dt_s", [0.95 * limit / 2**j for j in range(0, 3 if quick else 5)]
    if method in IVP_METHODS:
        return "rtol", [10.0**-e for e in ((3, 5, 7) if quick else range(3, 11))]
    if method == "report-rk45":
        return "rtol", [10.0**-e for e in ((3, 5) if quick else range(3, 9))]
    raise DynamicsError(f"method: got {method!r}; expected one of {', '.join(ALL_METHODS)}")


def options_for(method: str, parameter_name: str, value: float) -> dict:
    if parameter_name == "n_modes":
        return {"n_modes": int(value)}
    if parameter_name == "dt_s":
        return {"dt": float(value)}
    if parameter_name == "rtol":
        return {"rtol": float(value), "atol": ATOL_PER_RTOL * float(value)}
    return {}


def timed_solve(problem: LinearChainProblem, method: str, **options) -> tuple[np.ndarray, float]:
    """(relative displacements, wall time in s) of one cold solve (exact's cache cleared first)."""
    solver_cache.clear()  # count the one-off matrix exponential: one scenario, not amortised
    start = time.perf_counter()
    resp = solve(
        problem.system, problem.force, problem.t_eval_s, method=method, x0=problem.x0, v0=problem.v0, **options
    )
    return resp.x, time.perf_counter() - start


def measure(
    problem: LinearChainProblem,
    method: str,
    reference_x: np.ndarray,
    parameter_name: str = "",
    parameter: float = np.nan,
    repeats: int = 1,
) -> Measurement:
    """Error against `reference_x` and best-of-`repeats` wall time of one method at one setting."""
    opts = options_for(method, parameter_name, parameter)
    best = np.inf
    try:
        for _ in range(max(1, repeats)):
            x, wall = timed_solve(problem, method, **opts)
            best = min(best, wall)
    except SolverDivergedError as exc:
        return Measurement(method, parameter_name, parameter, np.nan, np.nan, "diverged", str(exc))
    except SolverFailedError as exc:
        return Measurement(method, parameter_name, parameter, np.nan, np.nan, "failed", str(exc))
    return Measurement(method, parameter_name, parameter, best, float(np.max(np.abs(x - reference_x))), "ok")


def work_precision(
    problem: LinearChainProblem, methods=ALL_METHODS, *, quick: bool = False, repeats: int = 1
) -> list[Measurement]:
    """Every method over its settings (`settings`) on one problem."""
    for method in methods:
        if method not in METHODS:
            raise DynamicsError(f"method: got {method!r}; expected one of {', '.join(METHODS)}")
    ref = reference_response(problem)
    out = []
    for method in methods:
        name, values = settings(method, problem, quick)
        out.extend(measure(problem, method, ref, name, v, repeats) for v in values)
    return out


def observed_order(parameters, errors) -> float:
    """Least-squares slope of log(error) against log(parameter): the observed convergence order."""
    p = np.asarray(parameters, dtype=float)
    e = np.asarray(errors, dtype=float)
    if p.size < 2 or p.shape != e.shape or np.any(p <= 0) or np.any(e <= 0):
        raise DynamicsError("parameters, errors: expected two or more positive pairs of equal length")
    return float(np.polyfit(np.log(p), np.log(e), 1)[0])
