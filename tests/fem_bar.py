"""Test helper: a steel bar on roller supports pulled at its end, whose axial stiffness is EA/L
exactly for any valid mesh and element order (uniaxial stress makes u linear in x, y and z)."""

from __future__ import annotations

import numpy as np
from skfem import MeshTet

from fem import problem
from fem.assembly import elasticity_matrix

E_PA, NU = 200e9, 0.3
LAM, MU = E_PA * NU / ((1 + NU) * (1 - 2 * NU)), E_PA / (2 * (1 + NU))
LOAD_N = 1000.0


def bar_on_rollers(mesh: MeshTet, order: int, solver: str, length_m: float, width_m: float, height_m: float):
    """(K, f, u): stiffness matrix, load (LOAD_N spread over the end x = length_m) and displacement
    of the bar whose faces x = 0, y = 0 and z = 0 are on rollers."""
    basis = problem.scalar_basis(mesh, order)
    K = elasticity_matrix(basis, LAM, MU)
    end = mesh.facets_satisfying(lambda x: np.isclose(x[0], length_m))
    traction_Pa = LOAD_N / (width_m * height_m)
    f = problem.traction_load(basis, end, lambda x: np.array([traction_Pa + 0 * x[0], 0 * x[0], 0 * x[0]]))
    rollers = np.concatenate(
        [
            problem.fixed_vector_dofs(basis, mesh.facets_satisfying(lambda x, c=c: np.isclose(x[c], 0.0)), [c])
            for c in range(3)
        ]
    )
    return K, f, problem.solve_displacement(K, f, rollers, basis.doflocs, solver=solver)
