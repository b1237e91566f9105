"""The table that maps a study's variable names onto the stages' inputs.

A study varies the built-in link (`LinkDimensions` fields, and the rail width the recess leaves
standing), the material, the cam law, and the chain's `RunConfig` fields. One `Variable` line per
name: a new `RunConfig` field (e.g. a pin clearance) becomes a study variable by adding one line
to `VARIABLES`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from geometry.dimensions import LinkDimensions
from settings import LIMITS, Bounds

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
    bounds: Bounds = Bounds()  # numbers only: the allowed values (a length: > 0)

    def accepts(self, value: float) -> bool:
        return self.bounds.accepts(value)

    def expected(self) -> str:
        return self.bounds.expected()


def _run(name: str, kind: type) -> Variable:
    """A RunConfig field as a variable, with the values RunConfig allows (settings.LIMITS)."""
    return Variable(name, RUN, name, kind, LIMITS[name].bounds)


VARIABLES: dict[str, Variable] = {
    v.name: v
    for v in [
        *(Variable(f.name, LINK, f.name, float) for f in fields(LinkDimensions)),
        Variable("rail_width_m", RAIL, "recess_width_m", float),
        Variable("material", MATERIAL, "materials", str),
        Variable("cam", CAM, "cams", str),
        _run("rpm", float),
        _run("preload_N", float),
        _run("links", int),
        _run("nest_mass_kg", float),
        _run("hardware_mass_kg", float),
        _run("friction", float),
        _run("damping", float),
        _run("pin_clearance_m", float),
        # the idler tensioner, as pipeline.py's --tensioner-rate/-mass/-damping (the mass is needed with
        # either of the others: dynamics.models.tensioner.tensioner_from)
        _run("tensioner_rate_N_per_m", float),
        _run("tensioner_mass_kg", float),
        _run("tensioner_damping_N_s_per_m", float),
        # the machine on its wheels (issue #22; they act when the run's drive is the wheels)
        _run("sprocket_teeth", int),
        _run("sprocket_wrap_links", int),
        _run("drive_stiffness_N_m_per_rad", float),
        _run("sprocket_inertia_kg_m2", float),
        _run("idler_teeth", int),
        _run("idler_wrap_links", int),
        _run("idler_inertia_kg_m2", float),
        _run("tooth_phase", float),  # the seats change inside the index: the tooth model where rigid seating fails
        _run("tooth_stiffness_N_per_m", float),  # not set: rigid seating where it holds, else the default k_t
        # `geometry` in the study file: its column is geometry_file (the table's `geometry` is the FEA group's id)
        Variable("geometry_file", STEP, "geometry", str),
    ]
}

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
