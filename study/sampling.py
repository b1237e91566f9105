"""The design points of a study: ranges sampled (full grid, Latin hypercube or Sobol from
scipy.stats.qmc, seeded), crossed with every combination of the listed values.

The same study file gives the same points in the same order, with the same ids (a hash of every
input and setting), which is what --resume matches on.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import asdict, dataclass, fields

import numpy as np

from geometry.dimensions import LinkDimensions
from geometry.errors import GeometryError
from study.samplers import SAMPLERS, SamplingSize
from study.spec import StudySpec
from study.variables import GEOMETRY_TARGETS, LINK, STEP, VARIABLES, link_dimensions


@dataclass(frozen=True)
class DesignPoint:
    index: int
    point_id: str  # hash of every input and setting
    geometry: str  # hash of the link (dimensions, or STEP contents and part options) and the FEA settings:
    #                one mesh and FEA per value
    inputs: dict  # every variable (varied and held) and every LinkDimensions field (built-in link), SI
    infeasible: str | None  # why the link cannot be built, known before any work

    def task_view(self) -> dict:
        """What a worker needs of the point (small, picklable)."""
        return {"index": self.index, "point_id": self.point_id, "geometry": self.geometry, "inputs": self.inputs}


def range_samples(spec: StudySpec) -> list[dict]:
    """The sampled values of the range variables (one dict per sample, file order of the names)."""
    ranges = spec.ranges
    if not ranges:
        return [{}]
    names = list(ranges)
    lows = np.array([ranges[n].min for n in names])
    highs = np.array([ranges[n].max for n in names])
    s = spec.sampling
    values = SAMPLERS[s.method].values(lows, highs, SamplingSize(s.levels, s.points, s.seed))
    return [_kinds(dict(zip(names, row))) for row in values]


def _kinds(values: dict) -> dict:
    """Plain Python numbers, rounded to whole numbers for integer variables."""
    return {n: (int(round(float(v))) if VARIABLES[n].kind is int else float(v)) for n, v in values.items()}


def design_points(spec: StudySpec, base_config) -> list[DesignPoint]:
    """Every point of the study, in a fixed order: range samples outermost, then the lists."""
    choice_names = list(spec.choices)
    combos = list(itertools.product(*(spec.choices[n].values for n in choice_names)))
    settings = asdict(spec.settings)
    points = []
    for sample in range_samples(spec):
        for combo in combos:
            values = {**held_values(spec, base_config), **sample, **dict(zip(choice_names, combo))}
            points.append(make_point(len(points), values, settings, part_identities(spec)))
    return points


def part_identities(spec: StudySpec) -> dict:
    """What identifies each STEP file's link: its contents and the part options (not its path)."""
    return {name: {"sha256": part.sha256, "options": spec.part_options} for name, part in spec.parts.items()}


def held_values(spec: StudySpec, base_config) -> dict:
    """Every run variable at its fixed value, or pipeline.py's default."""
    out = {}
    for name, variable in VARIABLES.items():
        if variable.target in GEOMETRY_TARGETS or variable.kind is str:
            continue
        value = spec.fixed.get(name, getattr(base_config, variable.field))
        if value is not None:  # None: pipeline.py's "not given" (no tensioner), not a column
            out[name] = value
    for name in ("material", "cam", "geometry_file"):
        if name in spec.fixed:
            out[name] = spec.fixed[name]
    for name, value in spec.fixed.items():
        if VARIABLES[name].target in GEOMETRY_TARGETS:
            out[name] = value
    return out


def make_point(index: int, values: dict, settings: dict, parts: dict | None = None) -> DesignPoint:
    """The point of the given variable values (every variable set), with its ids; `parts`: the
    identity of each STEP file (part_identities) when the link comes from one."""
    fea_settings = {k: settings[k] for k in ("mesh_size_m", "order")}
    if values.get("geometry_file") is not None:
        inputs = {n: v for n, v in values.items() if VARIABLES[n].target not in GEOMETRY_TARGETS}
        geometry = _digest({"part": parts[values["geometry_file"]], "fea": fea_settings})
        point_id = _digest({"inputs": inputs, "part": parts[values["geometry_file"]], "settings": settings})
        return DesignPoint(index, point_id, geometry, inputs, None)
    link_fields = {f.name: getattr(LinkDimensions(), f.name) for f in fields(LinkDimensions)}
    geometry_values = {n: v for n, v in values.items() if VARIABLES[n].target in GEOMETRY_TARGETS}
    try:
        dims = link_dimensions(geometry_values)
        link_fields = asdict(dims)
        infeasible = None
    except GeometryError as e:
        link_fields.update({VARIABLES[n].field: v for n, v in geometry_values.items() if VARIABLES[n].target == LINK})
        infeasible = f"geometry: {e}"
    inputs = {
        **link_fields,
        "rail_width_m": (link_fields["body_width_m"] - link_fields["recess_width_m"]) / 2,
        **{n: v for n, v in values.items() if VARIABLES[n].target not in (*GEOMETRY_TARGETS, STEP)},
    }
    if "rail_width_m" in geometry_values and infeasible is not None:
        inputs["rail_width_m"] = geometry_values["rail_width_m"]
    geometry = _digest({"link": geometry_values, "fea": fea_settings})
    point_id = _digest({"inputs": inputs, "settings": settings})
    return DesignPoint(index, point_id, geometry, inputs, infeasible)


def _digest(payload: dict) -> str:
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=repr).encode()).hexdigest()[:16]
