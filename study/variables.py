"""The table that maps a study's variable names onto the stages' inputs.

A study varies the built-in link (`LinkDimensions` fields, and the rail width the recess leaves
standing), the material, the cam law, and the chain's `RunConfig` fields. One `Variable` line per
name: a new `RunConfig` field (e.g. a pin clearance) becomes a study variable by adding one line
to `VARIABLES`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from geometry.dimensions import LinkDimensions

LINK = "link"  # a LinkDimensions field
RAIL = "rail"  # the side rail width: sets recess_width_m = body_width_m - 2 * value
MATERIAL = "material"
CAM = "cam"
RUN = "run"  # a RunConfig field
STEP = "step"  # the link's STEP file (a path in the study file; its bytes travel with the FEA task)


@dataclass(frozen=True)
class Variable:
    name: str  # the key in the study file and the column in the table (SI, unit suffix)
    target: str  # LINK, RAIL, MATERIAL, CAM, RUN or STEP
    field: str  # the LinkDimensions or RunConfig field it sets
    kind: type  # float, int or str (str: a choice from a list)
    lower: float = 0.0  # numbers only: values above lower (or equal to it when lower_included)
    lower_included: bool = False
    upper: float = float("inf")  # values at most upper

    def accepts(self, value: float) -> bool:
        return (value >= self.lower if self.lower_included else value > self.lower) and value <= self.upper

    def expected(self) -> str:
        low = f"{'>=' if self.lower_included else '>'} {self.lower:g}"
        return low if self.upper == float("inf") else f"{low} and <= {self.upper:g}"


VARIABLES: dict[str, Variable] = {v.name: v for v in [
    *(Variable(f.name, LINK, f.name, float) for f in fields(LinkDimensions)),
    Variable("rail_width_m", RAIL, "recess_width_m", float),
    Variable("material", MATERIAL, "materials", str),
    Variable("cam", CAM, "cams", str),
    Variable("rpm", RUN, "rpm", float),
    Variable("preload_N", RUN, "preload_N", float, lower_included=True),
    Variable("links", RUN, "links", int, lower=2, lower_included=True, upper=10_000),
    Variable("nest_mass_kg", RUN, "nest_mass_kg", float, lower_included=True),
    Variable("hardware_mass_kg", RUN, "hardware_mass_kg", float, lower_included=True),
    Variable("friction", RUN, "friction", float, lower_included=True, upper=1.0),
    Variable("damping", RUN, "damping", float, lower_included=True, upper=0.999),
    Variable("pin_clearance_m", RUN, "pin_clearance_m", float, lower_included=True),
    # the idler tensioner, as pipeline.py's --tensioner-rate/-mass/-damping (the mass is needed with
    # either of the others: dynamics.clearance_sim.tensioner_from)
    Variable("tensioner_rate_N_per_m", RUN, "tensioner_rate_N_per_m", float, lower_included=True),
    Variable("tensioner_mass_kg", RUN, "tensioner_mass_kg", float),
    Variable("tensioner_damping_N_s_per_m", RUN, "tensioner_damping_N_s_per_m", float, lower_included=True),
    # `geometry` in the study file: its column is geometry_file (the table's `geometry` is the FEA group's id)
    Variable("geometry_file", STEP, "geometry", str),
]}

#: The study file's key for the STEP file(s) of the link, and the variable it sets.
GEOMETRY_KEY = "geometry"

#: Variables that change the geometry (one mesh each) and so the FEA.
GEOMETRY_TARGETS = (LINK, RAIL)


def link_dimensions(values: dict) -> LinkDimensions:
    """The link of one design point: the default link with the point's geometry variables set.
    Raises GeometryError (with the violated rule) when the dimensions cannot make a link."""
    dims = {f.name: getattr(LinkDimensions(), f.name) for f in fields(LinkDimensions)}
    for name, value in values.items():
        variable = VARIABLES.get(name)
        if variable is not None and variable.target == LINK:
            dims[variable.field] = float(value)
    for name, value in values.items():
        variable = VARIABLES.get(name)
        if variable is not None and variable.target == RAIL:
            dims[variable.field] = dims["body_width_m"] - 2 * float(value)
    return LinkDimensions(**dims)


def run_fields(values: dict) -> dict:
    """The RunConfig fields one design point sets (material and cam as one-element tuples)."""
    out = {}
    for name, value in values.items():
        variable = VARIABLES.get(name)
        if variable is None or value is None:  # None: a RunConfig default that is "not given" (no tensioner)
            continue
        if variable.target == RUN:
            out[variable.field] = variable.kind(value)
        elif variable.target in (MATERIAL, CAM):
            out[variable.field] = (value,)
    return out
