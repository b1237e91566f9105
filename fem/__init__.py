"""FEA stage: link stiffness, mass and stress with scikit-fem linear elasticity (SI units)."""

from .errors import FemError
from .export import write_solution_vtu
from .link import LinkSolution, analyse_link, analyse_link_materials
from .materials import Material, get_material, load_materials
from .render import render_deformed
from .richardson import Extrapolation, extrapolate
from .settings import FeaSettings
from .stress import StressEstimate, stress_study
from .study import StiffnessEstimate, stiffness_studies, stiffness_study

__all__ = [
    "Extrapolation",
    "FeaSettings",
    "FemError",
    "LinkSolution",
    "Material",
    "StiffnessEstimate",
    "analyse_link",
    "analyse_link_materials",
    "extrapolate",
    "get_material",
    "load_materials",
    "render_deformed",
    "stiffness_studies",
    "stiffness_study",
    "StressEstimate",
    "stress_study",
    "write_solution_vtu",
]
