"""One interface, many methods (after scipy.integrate.solve_ivp) for M x'' + C x' + K x = f(t) + g(x, x').

    solve(system, force, t_eval_s, method="exact", x0=None, v0=None, **options) -> Response

`METHODS` maps each method id to a `Method` record: a one-line description, whether it accepts a
nonlinear force, and its options. One module per method; all are unit-agnostic.

Every method returns displacement and velocity at `t_eval_s`; the acceleration is evaluated from the
equation of motion there (force, nonlinear force and state), so all methods report it the same way.
A method's `run(problem)` returns (x, v, a, diagnostics) with a None unless the method has the
equation of motion's acceleration on hand more cheaply (the exact method in modal coordinates).
A solution that becomes non-finite or runs away raises SolverDivergedError naming the method and
its step; an integrator that cannot finish raises SolverFailedError. Numbers are never returned
from a failed run.

Beyond `system.nonlinear_force` g(x, v), the methods that accept a nonlinear force also take the
option `time_dependent_force=g(t, x, v)`, added to it: friction written in coordinates that move
with the cam needs the cam's velocity at time t (see dynamics.solvers.simulate).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.models.system import Response, SampledForce, SecondOrderSystem
from dynamics.options import SOLVER_METHODS
from dynamics.solvers import central_difference, exact, ivp, modal, newmark, report_rk45
from dynamics.solvers._common import accelerations, make_problem, serial_blas


@dataclass(frozen=True)
class Method:
    id: str
    description: str
    handles_nonlinear_force: bool
    options: MappingProxyType
    run: Callable = field(repr=False)


def _method(id_, description, module, run=None, options=None) -> Method:
    """The implementation of the method `id_` declared in dynamics.options (what it can model is
    read there: the settings check a run's method without importing the solvers)."""
    opts = module.OPTIONS if options is None else options
    nonlinear = SOLVER_METHODS[id_].handles_nonlinear_force
    return Method(id_, description, nonlinear, MappingProxyType(dict(opts)), run or module.solve)


def _ivp(name):
    return lambda problem, **opts: ivp.solve(problem, name, **opts)


METHODS: MappingProxyType = MappingProxyType(
    {
        m.id: m
        for m in (
            _method(
                "exact",
                "first-order-hold matrix exponential (Van Loan), exact for the linear model at any "
                "stiffness; nonlinear force by a Heun predictor-corrector splitting",
                exact,
            ),
            _method(
                "modal",
                "modal superposition truncated to n_modes, exact first-order-hold recurrence per mode "
                "(classically damped linear systems)",
                modal,
            ),
            _method(
                "newmark",
                "Newmark average acceleration, fixed step dt (implicit, linear)",
                newmark,
                newmark.solve_newmark,
                newmark.NEWMARK_OPTIONS,
            ),
            _method(
                "hht",
                "HHT-alpha, fixed step dt, alpha in [-1/3, 0] (implicit, linear)",
                newmark,
                newmark.solve_hht,
                newmark.HHT_OPTIONS,
            ),
            _method(
                "central-difference",
                "explicit central difference, fixed step dt; refused above the stability limit 2/omega_max",
                central_difference,
            ),
            *(_method(name, f"scipy solve_ivp {label}", ivp, _ivp(name)) for name, label in ivp.LABELS.items()),
            _method(
                "report-rk45",
                "the 2012 report's scheme: MATLAB ode45 (Dormand-Prince) restarted every output step, "
                "force linear between output samples",
                report_rk45,
            ),
        )
    }
)
if tuple(METHODS) != tuple(SOLVER_METHODS):  # each method declared once, in dynamics.options
    raise ImportError(
        f"dynamics.solvers: METHODS {tuple(METHODS)} differ from dynamics.options {tuple(SOLVER_METHODS)}"
    )


def solve(
    system: SecondOrderSystem,
    force: SampledForce,
    t_eval_s: np.ndarray,
    *,
    method: str = "exact",
    x0=None,
    v0=None,
    **options,
) -> Response:
    """Response of `system` to `force` at `t_eval_s` from the state (x0, v0) (rest by default)."""
    return solve_with_diagnostics(system, force, t_eval_s, method=method, x0=x0, v0=v0, **options)[0]


def solve_with_diagnostics(
    system: SecondOrderSystem,
    force: SampledForce,
    t_eval_s: np.ndarray,
    *,
    method: str = "exact",
    x0=None,
    v0=None,
    **options,
) -> tuple[Response, dict]:
    """As `solve`, plus the method's diagnostics (steps taken, rejected steps, stability limit...)."""
    info = METHODS.get(method)
    if info is None:
        raise DynamicsError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    timed = options.pop("time_dependent_force", None)
    unknown = set(options) - set(info.options)
    if unknown:
        raise DynamicsError(
            f"options for {method}: expected some of {sorted(info.options) or 'none'}, got {sorted(unknown)}"
        )
    if (system.nonlinear_force is not None or timed is not None) and not info.handles_nonlinear_force:
        capable = [m for m, i in METHODS.items() if i.handles_nonlinear_force]
        raise DynamicsError(f"method {method}: cannot take a nonlinear force; use one of {', '.join(capable)}")
    # runaway values are caught and reported; the step loops run on one BLAS thread (serial_blas)
    with np.errstate(over="ignore", invalid="ignore"), serial_blas():
        problem = make_problem(system, force, t_eval_s, x0, v0, timed)
        x, v, a, diagnostics = info.run(problem, **options)
        if a is None:
            a = accelerations(problem, x, v)
    return Response(problem.t_eval_s, x, v, a, method), diagnostics
