"""The call the pipeline makes: a chain model, a cam, output times -> the chain's motion and tension.

The chain is solved relative to the cam (see dynamics.models.chain): y = x - z 1 under the force -M 1 z'',
friction (mu > 0) entering as a time-dependent force because it opposes the absolute velocity
z'(t) + y'. Absolute motion is rebuilt at the output times from the cam's exact s, v, a.

The cam is a duck type: `cam.svaj(t_s) -> (s_m, v_m_s, a_m_s2, j_m_s3)`, `cam.period_s` and
`cam.advance_m` (z(t + period) = z(t) + advance; period None for a one-shot program).

steady_state=True returns the periodic steady state of continuous indexing (dynamics.solvers.steady_state):
the state at t_eval_s[0] is the one that repeats after one cam period, over a period grid with the
output step (so the two coincide when the period is a whole number of output steps).
steady_state=False starts from rest at t_eval_s[0]: every link at the cam's position, motionless.

With the default method `exact` and friction, the Heun splitting needs h mu g / v_s <= 1 for the
friction's steep branch; each output interval is split into as many sub-steps as that requires
(one at one-degree steps, 180 rpm, mu 0.35, v_s 5 mm/s). Accuracy is second order in the step, for
the cam's sampling and for friction alike: at one-degree steps the friction's contribution to the
motion (about 3 % of the deflection for a 16-link chain) is right to about 15 % of itself; pass
`substeps=4` for about 1 %.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.friction import CamFrameFriction
from dynamics.models.reduction import ProjectedForce, modal_basis
from dynamics.models.system import Response, SampledForce, SecondOrderSystem
from dynamics.solvers import METHODS, solve_with_diagnostics
from dynamics.solvers._common import serial_blas
from dynamics.solvers.steady_state import periodic_initial_state

DEFAULT_METHOD = "exact"


class SlackChainWarning(UserWarning):
    """Some link tension fell below zero: a real chain would go slack there (the model is linear)."""


@dataclass(frozen=True)
class ChainResponse:
    """Absolute link motion at t_s; columns are the links in `links` (0-based, 0 = driven link 1)."""

    t_s: np.ndarray  # (m,)
    x_m: np.ndarray  # (m, len(links))
    v_m_s: np.ndarray
    a_m_s2: np.ndarray
    z_m: np.ndarray  # (m,) cam input at t_s
    zdot_m_s: np.ndarray
    zddot_m_s2: np.ndarray
    tension_N: np.ndarray  # (m, N): column j is the spring from link j to link j+1 (0-based, closing the loop)
    drive_force_N: np.ndarray  # (m,) drive spring force on link 1
    links: tuple[int, ...]
    min_tension_N: float
    slack: bool  # min_tension_N < 0
    method: str
    diagnostics: dict = field(default_factory=dict)


@lru_cache(maxsize=16)
def _system(model: ChainModel) -> SecondOrderSystem:
    return model.system()


def simulate(
    model: ChainModel,
    cam,
    t_eval_s: np.ndarray,
    *,
    method: str = DEFAULT_METHOD,
    steady_state: bool = True,
    links=None,
    n_modes: int | None = None,
    **options,
) -> ChainResponse:
    """Motion of every link (or of `links`) and every spring tension at t_eval_s (s).

    `n_modes` solves in the chain's lowest n_modes modes (dynamics.models.reduction) instead of all N
    link coordinates: for long chains, whose dense matrices would not fit."""
    with serial_blas():  # small dense matrices: a threaded BLAS only adds hand-off cost (see _common)
        return _simulate(model, cam, t_eval_s, method, steady_state, links, n_modes, options)


def _simulate(model, cam, t_eval_s, method, steady_state, links, n_modes, options) -> ChainResponse:
    t = np.asarray(t_eval_s, dtype=float)
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0.0):
        raise DynamicsError("t_eval_s: expected at least two strictly increasing times")
    info = METHODS.get(method)
    if info is None:
        raise DynamicsError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    friction = model.friction_coefficient > 0.0
    if friction and not info.handles_nonlinear_force:
        capable = [m for m, i in METHODS.items() if i.handles_nonlinear_force]
        raise DynamicsError(
            f"method {method}: cannot model friction (friction_coefficient > 0); use one of {', '.join(capable)}"
        )
    selected = _links(links, model.n_links)
    basis = None if n_modes is None else modal_basis(model, n_modes)
    system = _system(model) if basis is None else basis.system
    s, v, a, _ = (np.asarray(q, dtype=float) for q in cam.svaj(t))

    def excitation(zddot: np.ndarray) -> np.ndarray:
        if basis is None:
            return model.base_excitation_force(zddot)
        return -np.outer(zddot, basis.participation)

    period_grid = _period_grid(cam, t) if steady_state else None
    t_table = t if period_grid is None else np.union1d(t, period_grid)
    zdot_table = np.asarray(cam.svaj(t_table)[1], dtype=float) if period_grid is not None else v
    opts = dict(options)
    if friction:
        friction_force = CamFrameFriction(model.coulomb_force_N, model.friction_velocity_scale_m_s, t_table, zdot_table)
        opts["time_dependent_force"] = friction_force if basis is None else ProjectedForce(friction_force, basis.shapes)
        if method == "exact":
            h = float(np.max(np.diff(t)))
            needed = int(np.ceil(h * model.friction_slope_per_s()))
            opts["substeps"] = max(int(opts.get("substeps", 1)), needed, 1)

    force = SampledForce(t, excitation(a))
    steady_info = None
    if steady_state:
        zdd_p = np.asarray(cam.svaj(period_grid)[2], dtype=float)
        force_p = SampledForce(period_grid, excitation(zdd_p))
        y0, yd0, steady_info = periodic_initial_state(system, force_p, method=method, **opts)
    else:
        y0 = np.zeros(system.n_dof)
        # every link at the cam's speed: y' = -z'(0) 1, whose modal coordinates are -z'(0) shapes^T M 1
        yd0 = -v[0] * (np.ones(model.n_links) if basis is None else basis.participation)
    resp, solver_info = solve_with_diagnostics(system, force, t, method=method, x0=y0, v0=yd0, **opts)
    if basis is not None:
        resp = Response(
            resp.t_s, resp.x @ basis.shapes.T, resp.v @ basis.shapes.T, resp.a @ basis.shapes.T, resp.method
        )

    tension = model.tension_N(resp.x)
    min_tension = float(tension.min())
    if min_tension < 0.0:
        warnings.warn(
            f"chain goes slack: minimum link tension {min_tension:.4g} N (preload {model.preload_N:g} N); "
            "the linear model lets links push",
            SlackChainWarning,
            stacklevel=3,
        )
    cols = list(selected)
    return ChainResponse(
        t_s=t,
        x_m=s[:, None] + resp.x[:, cols],
        v_m_s=v[:, None] + resp.v[:, cols],
        a_m_s2=a[:, None] + resp.a[:, cols],
        z_m=s,
        zdot_m_s=v,
        zddot_m_s2=a,
        tension_N=tension,
        drive_force_N=model.drive_force_N(s + resp.x[:, 0], s),
        links=selected,
        min_tension_N=min_tension,
        slack=min_tension < 0.0,
        method=method,
        diagnostics={
            "solver": solver_info,
            "steady_state": steady_info,
            "substeps": opts.get("substeps"),
            "friction": "regularised Coulomb tanh(v / v_s)" if friction else None,
        },
    )


def _links(links, n: int) -> tuple[int, ...]:
    if links is None:
        return tuple(range(n))
    chosen = tuple(int(i) for i in np.atleast_1d(links))
    if not chosen or any(i < 0 or i >= n for i in chosen):
        raise DynamicsError(f"links: expected 0-based link indices in 0..{n - 1}, got {links!r}")
    return chosen


def _period_grid(cam, t: np.ndarray) -> np.ndarray:
    """One cam period from t[0], in steps of the output step (as close as fits a whole number)."""
    period = getattr(cam, "period_s", None)
    if period is None:
        raise DynamicsError("steady_state: the cam program is not periodic (period_s is None); use steady_state=False")
    if not (np.isfinite(period) and period > 0):
        raise DynamicsError(f"cam.period_s: expected a positive period, got {period!r}")
    h = float(np.median(np.diff(t)))
    n_steps = max(int(round(period / h)), 1)
    return t[0] + period * np.arange(n_steps + 1) / n_steps
