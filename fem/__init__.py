"""FEA stage: link stiffness, mass and stress with scikit-fem linear elasticity (SI units).

The names below are imported on first use (PEP 562 `__getattr__`), so that `fem.errors`,
`fem.cache` and `fem.materials` load without scikit-fem and SciPy's solvers: `pipeline.py`'s own
process needs only those, its FEA runs in a process of its own (stages.beside), and importing the
whole package took 1.1 s of a loaded machine's start-up (`python -X importtime`).
"""

from lazy_imports import lazy_exports

_MODULE_OF = {
    "FemError": "errors",
    "write_solution_vtu": "export",
    "LinkSolution": "link",
    "analyse_link": "link",
    "analyse_link_materials": "link",
    "Material": "materials",
    "get_material": "materials",
    "load_materials": "materials",
    "render_deformed": "render",
    "Extrapolation": "richardson",
    "extrapolate": "richardson",
    "FeaSettings": "settings",
    "StressEstimate": "stress",
    "stress_study": "stress",
    "StiffnessEstimate": "study",
    "stiffness_studies": "study",
    "stiffness_study": "study",
}

__all__ = sorted(_MODULE_OF)
__getattr__, __dir__ = lazy_exports(__name__, _MODULE_OF)
