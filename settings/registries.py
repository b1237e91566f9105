"""The named choices a run can make, each read from the module that implements it.

A new cam law is one `dynamics.cams.register_law` call: `cam_ids()` (what 'all' means) and
`extra_cam_ids()` (accepted by name only) are derived from the law registry. Materials come from
fem/data/materials.toml (plus a user's --materials-file), solver methods, chain models, drives and
span damping laws from dynamics.options (where the solvers and models that implement them read
them), accelerometer stations from `dynamics.response.metrics.station_links`. The imports are
deferred so that reading the settings does not load numpy, scipy or gmsh, and none of them loads
the chain's models or solvers (numba, SciPy): the FEA's process starts after these checks.
"""

from __future__ import annotations

from fem.options import ELEMENT_ORDERS as ELEMENT_ORDERS  # P1 / P2 tetrahedra, read here by the CLIs

DEFAULT_MATERIALS = ("al6061-t6", "ti-grade2")
DEFAULT_STATION = "tight-side"  # where tables, rankings and plots look unless --station says otherwise
DEFAULT_DRIVE = "wheels"  # how the chain is driven when --drive is not given (RunConfig.machine_drive)
PRESETS = ("mqp2012",)


def cam_ids() -> tuple[str, ...]:
    """The laws 'all' means: every registered law that enters and leaves its dwells without an
    acceleration jump (a law with one, such as simple harmonic, has infinite jerk at the joints)."""
    from dynamics.cams import get_law, law_ids

    return tuple(law_id for law_id in law_ids() if get_law(law_id).zero_end_acceleration)


def extra_cam_ids() -> tuple[str, ...]:
    """Registered laws accepted by name but left out of 'all'."""
    from dynamics.cams import law_ids

    default = cam_ids()
    return tuple(law_id for law_id in law_ids() if law_id not in default)


def known_cam_ids() -> tuple[str, ...]:
    return cam_ids() + extra_cam_ids()


def preset_cam_ids(preset: str) -> tuple[str, ...]:
    """The cam laws a preset replicates (the 2012 report's five for mqp2012)."""
    from dynamics.models.mqp2012 import CAMS

    return {"mqp2012": CAMS}[preset]


def preset_material_ids(preset: str) -> tuple[str, ...]:
    from dynamics.models.mqp2012 import MATERIALS

    return {"mqp2012": tuple(MATERIALS)}[preset]


def material_ids(materials_file=None) -> tuple[str, ...]:
    """The built-in materials and those of a user's TOML file."""
    from fem import load_materials

    return tuple(load_materials(materials_file))


def station_names() -> tuple[str, ...]:
    """The four accelerometer stations, drive end first."""
    from dynamics.response.metrics import station_links

    return tuple(station_links(1))


def chain_models() -> tuple[str, ...]:
    from dynamics.options import MODEL_CHOICES

    return MODEL_CHOICES


def drives() -> tuple[str, ...]:
    """link: the report's single-point drive; wheels: the machine on its wheels (dynamics.models.machine)."""
    from dynamics.options import DRIVES

    return DRIVES


def span_damping_laws() -> tuple[str, ...]:
    from dynamics.options import SPAN_DAMPING_LAWS

    return SPAN_DAMPING_LAWS


def solver_methods() -> dict:
    """Method id -> dynamics.options.SolverMethod (what each can model; its implementation is
    dynamics.solvers.METHODS[id])."""
    from dynamics.options import SOLVER_METHODS

    return SOLVER_METHODS
