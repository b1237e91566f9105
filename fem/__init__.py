"""FEA stage: link stiffness, mass and stress with scikit-fem linear elasticity (SI units)."""

from .errors import FemError
from .export import write_solution_vtu
from .link import LinkSolution, analyse_link
from .materials import Material, get_material, load_materials
from .render import render_deformed
from .richardson import Extrapolation, extrapolate
from .study import StiffnessEstimate, stiffness_studies, stiffness_study

__all__ = [
    "Extrapolation",
    "FemError",
    "LinkSolution",
    "Material",
    "StiffnessEstimate",
    "analyse_link",
    "extrapolate",
    "get_material",
    "load_materials",
    "render_deformed",
    "stiffness_studies",
    "stiffness_study",
    "write_solution_vtu",
]
