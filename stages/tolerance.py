"""Both stages run to a tolerance on the reported metrics (the --tolerance option)."""

from __future__ import annotations

from functools import partial

from settings import RunConfig
from stages.chain import run_dynamics
from stages.fea import run_fea
from stages.geometry import resolve_run_part
from stages.progress import Progress, timed


def run_to_tolerance(cfg: RunConfig, progress: Progress, timing: dict, part=None):
    """Half the tolerance goes to the time step, half to the FEA stiffness. How much a k error moves
    the metrics is measured (not assumed) after a first FEA pass; if it moves them by more than its
    half, the FEA is refined once more to the k accuracy that the measured sensitivity asks for.
    `part`: the run's geometry.Part (None: resolved here, once for both passes)."""
    fea_of_part = partial(run_fea, part=resolve_run_part(cfg) if part is None else part)
    budget = cfg.tolerance / 2
    stiffness_tolerance = budget
    levels: dict = {}  # the refinement pass extends the first pass's levels instead of re-solving them
    fea = timed(timing, "fea", progress, fea_of_part, cfg, progress, stiffness_tolerance, levels)
    chains, scenarios = timed(timing, "dynamics", progress, run_dynamics, cfg, fea, progress)
    from_k = max(sc.rel_error_estimate["stiffness"] for sc in scenarios.values())
    if from_k > budget:
        worst_k_error = max(r.stiffness_rel_error_estimate for r in fea.values())
        stiffness_tolerance = 0.8 * worst_k_error * budget / from_k
        progress(
            f"a {100 * worst_k_error:.2g} % error in k moves the metrics by {100 * from_k:.2g} %: "
            f"refining the FEA to {100 * stiffness_tolerance:.2g} %"
        )
        fea = timed(timing, "fea", progress, fea_of_part, cfg, progress, stiffness_tolerance, levels)
        chains, scenarios = timed(timing, "dynamics", progress, run_dynamics, cfg, fea, progress)
    return fea, chains, scenarios
