"""The mqp2012 preset's stage: the 2012 report's MATLAB model per material, with each cam's link metrics."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from settings import RunConfig
from stages.progress import Progress

if TYPE_CHECKING:
    from dynamics.models.mqp2012 import ReplicaResult
    from dynamics.response.metrics import LinkMetrics


@dataclass(frozen=True)
class ReplicaRun:
    """One material's replica and the metrics of its links per cam law (SI)."""

    replica: ReplicaResult
    metrics: dict[str, LinkMetrics]  # cam law -> its link metrics


def run_replicas(cfg: RunConfig, progress: Progress) -> dict[str, ReplicaRun]:
    from dynamics.models.mqp2012 import run_mqp2012
    from dynamics.response.metrics import link_metrics

    runs = {}
    for material in cfg.materials:
        progress(f"mqp2012 replica {material}: RK45 restarted every degree, N = {cfg.links}")
        r = run_mqp2012(material, n_links=cfg.links, rpm=cfg.rpm, friction=cfg.friction, cams=cfg.cams)
        if not r.stable:
            progress(
                f"warning: the script's model is unstable for N = {cfg.links} ({material}): its damping "
                "matrix feeds energy in below N = 24, so its numbers grow without bound (as the script's did)"
            )
        runs[material] = ReplicaRun(
            r,
            {
                cam: link_metrics(c.x_m, c.v_m_s, c.a_m_s2, c.z_m, c.zdot_m_s, c.zddot_m_s2, c.dwell_mask)
                for cam, c in r.cams.items()
            },
        )
    return runs
