"""One home for a run's settings: `RunConfig` (every default, SI), `LIMITS` (allowed ranges, with
the option that sets each), `check_run_config` (every check, before any work) and the registries
of named choices (cam laws, materials, stations, chain models, solver methods).

The command line (`pipeline.py`) only maps flags onto RunConfig fields; `python -m study` starts
each design point from `RunConfig()` and bounds its variables with `LIMITS`.
"""

from settings.checks import check_run_config
from settings.registries import DEFAULT_MATERIALS, DEFAULT_STATION, cam_ids, extra_cam_ids, known_cam_ids
from settings.run import LIMITS, MAX_LINKS, Bounds, Limit, RunConfig, SettingsError, m_to_mm, mm_to_m

__all__ = [
    "DEFAULT_MATERIALS",
    "DEFAULT_STATION",
    "LIMITS",
    "MAX_LINKS",
    "Bounds",
    "Limit",
    "RunConfig",
    "SettingsError",
    "cam_ids",
    "check_run_config",
    "extra_cam_ids",
    "known_cam_ids",
    "m_to_mm",
    "mm_to_m",
]
