"""Both stages run to a tolerance on the reported metrics (the --tolerance option)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

from settings import RunConfig
from stages.chain import run_dynamics, stiffness_error_allowed
from stages.fea import FeaInProgress, start_fea, store_levels, stored_levels
from stages.geometry import resolve_run_part
from stages.progress import Progress, timed


def run_to_tolerance(cfg: RunConfig, progress: Progress, timing: dict, part=None):
    """Half the tolerance goes to the time step, half to the FEA stiffness. How much a k error moves
    the metrics is measured (not assumed) after a first FEA pass; if it moves them by more than its
    half, the k error that keeps them within 0.8 of it is measured too (stages.chain.
    stiffness_error_allowed: the effect is not linear in the k error) and the FEA is refined once
    more to it.
    Where the FEA cannot refine that far within --max-fea-dofs, the run goes on at the best k
    estimate its levels reached and says why the tolerance is not met.
    `part`: the run's geometry.Part (None: resolved here, once for both passes).
    The solved levels are shared by both passes and kept in the FEA cache for later runs
    (stages.fea.stored_levels): no level is solved twice, in a run or across runs (but the finest
    level of the pass whose k is kept, solved again for its fields where an earlier run solved it).
    Returns the FEA, the chains, the scenarios and why the tolerance is not met (None: met)."""
    part = resolve_run_part(cfg) if part is None else part
    fea_of_part = partial(_start_pass, part=part)
    budget = cfg.tolerance / 2
    # the refinement pass extends the first pass's levels (and earlier runs') instead of re-solving them
    levels = stored_levels(cfg, part)
    keep_levels = _NewLevelsKeeper(cfg, part, levels, len(levels))
    # the first pass's stress study waits until it is known that no second pass replaces it
    first, short = _fea_pass(fea_of_part, cfg, progress, timing, budget, levels, keep_levels)
    fea = first.stiffness
    chains, scenarios = timed(timing, "dynamics", progress, run_dynamics, cfg, fea, progress)
    from_k = max(sc.rel_error_estimate["stiffness"] for sc in scenarios.values())
    if from_k > budget and short is None:
        worst_k_error = max(r.stiffness_rel_error_estimate for r in fea.values())
        over = [(name, sc) for (name, _), sc in scenarios.items() if sc.rel_error_estimate["stiffness"] > budget]
        stiffness_tolerance = timed(
            timing,
            "dynamics",
            progress,
            lambda: min(stiffness_error_allowed(cfg, fea[name], sc, 0.8 * budget) for name, sc in over),
        )
        progress(
            f"a {100 * worst_k_error:.2g} % error in k moves the metrics by {100 * from_k:.2g} %, a "
            f"{100 * stiffness_tolerance:.2g} % error by at most {100 * 0.8 * budget:.2g} % (measured): "
            f"refining the FEA to {100 * stiffness_tolerance:.2g} %"
        )
        refined, short = _fea_pass(fea_of_part, cfg, progress, timing, stiffness_tolerance, levels, keep_levels, first)
        if refined is not first:
            done = timed(timing, "fea", progress, refined.result)
            chains, scenarios = timed(timing, "dynamics", progress, run_dynamics, cfg, done, progress)
            return done, chains, scenarios, tolerance_shortfall(cfg.tolerance, scenarios, short)
    done = timed(timing, "fea", progress, first.result)
    return done, chains, scenarios, tolerance_shortfall(cfg.tolerance, scenarios, short)


def _start_pass(cfg: RunConfig, progress: Progress, stiffness_tolerance: float, levels: dict, part) -> FeaInProgress:
    """One FEA pass in this process, its stiffness solved now and its stress study at `result()`."""
    return start_fea(cfg, progress, stiffness_tolerance, levels, part=part, stress_later=True)


@dataclass
class _NewLevelsKeeper:
    """Called after each pass: stores `levels` in the FEA cache where they grew since they were last
    stored (`stored` of them), not again after a pass that added none."""

    cfg: RunConfig
    part: object
    levels: dict
    stored: int

    def __call__(self) -> None:
        if len(self.levels) > self.stored:
            store_levels(self.cfg, self.part, self.levels)
            self.stored = len(self.levels)


def _fea_pass(
    fea_of_part,
    cfg: RunConfig,
    progress: Progress,
    timing: dict,
    stiffness_tolerance: float,
    levels,
    keep_levels,
    last=None,
):
    """The FEA to `stiffness_tolerance` (a `FeaInProgress`, its stiffness solved), or, where its next
    level would pass --max-fea-dofs (or a size the geometry refuses), at the best k estimate its
    solved levels give (no level solved again; `last`, the previous pass's FEA, where the levels stop
    no finer than it did): (the FEA, why k is short of the tolerance or None). `keep_levels()` stores
    the levels solved so far once the pass's levels are done, reached or not."""
    from fem.adaptive import ToleranceNotReached
    from fem.errors import FemError

    def solved(tolerance: float) -> FeaInProgress:
        run = fea_of_part(cfg, progress, tolerance, levels)
        try:
            run.stiffness  # noqa: B018 (the levels solved now: a ToleranceNotReached is raised here)
        finally:
            keep_levels()
        return run

    try:
        return timed(timing, "fea", progress, solved, stiffness_tolerance), None
    except ToleranceNotReached as exc:
        limit = f"--max-fea-dofs {cfg.max_fea_dofs}" if exc.over_dofs else "the finest mesh the geometry takes"
        if exc.best_rel_error is None:
            raise FemError(
                f"--tolerance {cfg.tolerance:g}: the FEA reached {limit} before it could estimate its k error; "
                "expected a larger --max-fea-dofs"
            ) from None
        short = (
            f"the FEA's k error stops at {100 * exc.best_rel_error:.2g} % (asked for {100 * stiffness_tolerance:.2g} %) "
            f"at {limit}" + ("; a larger --max-fea-dofs refines further" if exc.over_dofs else "")
        )
        if last is not None and exc.best_rel_error >= max(
            r.stiffness_rel_error_estimate for r in last.stiffness.values()
        ):
            progress(f"{short}: going on at the last pass's k")
            return last, short
        progress(f"{short}: going on at that k")
        # the best estimate's own tolerance: met by the levels already solved
        return timed(timing, "fea", progress, solved, exc.best_rel_error * (1 + 1e-9)), short


def tolerance_shortfall(tolerance: float, scenarios: dict, fea_short: str | None) -> str | None:
    """Why the metrics' estimated error is above `tolerance` (None: it is within it)."""
    worst = max(sc.rel_error_estimate["total"] for sc in scenarios.values())
    if worst <= tolerance:
        return None
    parts = max(scenarios.values(), key=lambda sc: sc.rel_error_estimate["total"]).rel_error_estimate
    because = fea_short or "the time step's and k's estimates add up to more"
    return (
        f"tolerance {100 * tolerance:.2g} % not met: estimated error {100 * worst:.2g} % "
        f"(time step {100 * parts['time_step']:.2g} %, k {100 * parts['stiffness']:.2g} %); {because}"
    )
