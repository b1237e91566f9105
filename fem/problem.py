"""Small building blocks of a 3D linear-elastic solve with scikit-fem: basis, loads, solve, stress.

Vector fields are stored interleaved (see `assembly`); as arrays for people they are (3, N).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementTetP1, ElementTetP2, Mesh
from skfem.quadrature import get_quadrature

from . import solvers
from .assembly import DIM, rigid_body_modes, vector_dofs
from .errors import FemError
from .options import check_element_order

ELEMENTS = {1: ElementTetP1, 2: ElementTetP2}
# Facet quadrature for tractions: the link's bearing pressure max(0, cos phi) has a kink at
# |phi| = 90 deg, so no rule is exact there; degree 4 keeps that error far below the
# discretisation error (and the resultant is normalised exactly anyway).
TRACTION_INTORDER = 4
# Isoparametric P2: a rule exact for degree 2k - 2 = 2 on the reference cell keeps P2's optimal
# rates (Ciarlet & Raviart's quadrature condition); the default link's k moved by 1.4e-4 relative
# from degree 4 (11 points) to 2 (4 points), against a discretisation error of ~1 %, and
# basis + assembly took about half the time (measured).
CURVED_INTORDER = 2
# The curved cells' Jacobian check (link.straighten_distorted) samples more points than that.
JACOBIAN_CHECK_INTORDER = 4


def element(order: int):
    check_element_order(order)
    return ELEMENTS[order]()


def scalar_basis(mesh: Mesh, order: int) -> Basis:
    """Scalar Lagrange basis of the given order, with a quadrature exact for its stiffness.

    On straight tetrahedra the stiffness integrand is a polynomial of degree 2 (order - 1), so
    that rule integrates it exactly; curved (isoparametric) cells get CURVED_INTORDER.
    """
    intorder = max(1, 2 * (order - 1)) if mesh.affine else CURVED_INTORDER
    return Basis(mesh, element(order), intorder=intorder)


def facet_reference_points(mesh: Mesh, facets: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cells of boundary facets and the reference coordinates in them (3, n facets, n points) of
    points (2, n points) of the reference triangle mapped onto each facet through its own vertex order.

    scikit-fem's `FacetBasis` maps a facet's points to space and then inverts the cell's map at each
    one (on curved cells by Newton's method, to 1e-12), yet the point lies on a known face of the
    cell: at the barycentric combination of that face's reference corners. Here it is taken there
    exactly, with no inversion (the Newton iteration and the facet basis were three quarters of a
    default level's bearing load, 0.11 CPU s against 0.03 now).
    """
    cells = mesh.f2t[0, facets]
    corners = mesh.t[:, cells]  # (4, n)
    vertices = mesh.facets[:, facets]  # (3, n)
    local = np.argmax(corners[None, :, :] == vertices[:, None, :], axis=1)  # each facet vertex's place in its cell
    barycentric = np.vstack([1.0 - points.sum(axis=0), points])  # (3 corners, n points)
    reference = np.einsum("dkn,kq->dnq", mesh.refdom.p[:, local], barycentric)
    return cells, reference


def traction_load(
    basis: Basis,
    facets: np.ndarray,
    traction_Pa: Callable[[np.ndarray], np.ndarray],
) -> np.ndarray:
    """Interleaved load vector (N) of a traction t(x) (Pa, shape (3, ...) from x (3, ...)) on boundary
    facets: scikit-fem's `FacetBasis` and `LinearForm` on the facets (its points and weights, the
    facets' own map to space), with the basis evaluated at `facet_reference_points`
    (tests/test_fem_link.py: scikit-fem's to round-off, on curved and on straight cells)."""
    facets = np.asarray(facets)
    mesh = basis.mesh
    points, weights = get_quadrature(mesh.brefdom, TRACTION_INTORDER)
    x = basis.mapping.G(points, find=facets)  # (3, n facets, n points)
    dx = np.abs(basis.mapping.detDG(points, find=facets)) * weights
    cells, reference = facet_reference_points(mesh, facets, points)
    weighted = np.asarray(traction_Pa(x)) * dx  # (3, n facets, n points)
    dofs = basis.element_dofs[:, cells]  # (n local, n facets)
    values = np.array([basis.elem.lbasis(reference, i)[0] for i in range(basis.Nbfun)])  # (n local, n facets, n points)
    load = np.einsum("cfq,ifq->cif", weighted, values)
    return np.array([np.bincount(dofs.ravel(), load[c].ravel(), basis.N) for c in range(DIM)]).T.ravel()


def solve_displacement(
    K: sp.csr_matrix,
    f: np.ndarray,
    fixed_dofs: np.ndarray,
    dof_points_m: np.ndarray,
    *,
    fixed_values_m: np.ndarray | None = None,
    solver: str = "auto",
) -> np.ndarray:
    """Interleaved displacement solving K u = f with u[fixed_dofs] = fixed_values (default 0)."""
    n = K.shape[0]
    u = np.zeros(n)
    fixed = np.unique(np.asarray(fixed_dofs, dtype=np.int64))
    if fixed_values_m is not None:
        u[np.asarray(fixed_dofs)] = fixed_values_m
    free = np.setdiff1d(np.arange(n), fixed)
    rhs = f[free] - K[free][:, fixed] @ u[fixed] if fixed_values_m is not None else f[free]
    K_free = K[free][:, free]
    modes = rigid_body_modes(dof_points_m)[free] if solvers.resolve(solver) == "amg" else None
    u[free] = solvers.solve(K_free, rhs, solver, near_nullspace=modes)
    return u


def as_components(u: np.ndarray) -> np.ndarray:
    """(3N,) interleaved -> (3, N)."""
    return u.reshape(-1, DIM).T


def displacement_gradients(basis: Basis, u: np.ndarray, local_points: np.ndarray) -> np.ndarray:
    """Displacement gradient du_i/dx_j (3, 3, n_elements, n_points) at reference-element points."""
    at_points = Basis(basis.mesh, basis.elem, quadrature=(local_points, np.ones(local_points.shape[1])))
    components = as_components(u)
    return np.array([np.asarray(at_points.interpolate(components[c]).grad) for c in range(DIM)])


def von_mises_Pa(grad_u: np.ndarray, lam_Pa: float, mu_Pa: float) -> np.ndarray:
    """Von Mises stress from displacement gradients (3, 3, ...) of an isotropic material."""
    strain = 0.5 * (grad_u + np.swapaxes(grad_u, 0, 1))
    trace = np.einsum("ii...->...", strain)
    stress = 2 * mu_Pa * strain
    for i in range(DIM):
        stress[i, i] += lam_Pa * trace
    deviator = stress - np.eye(DIM).reshape(DIM, DIM, *([1] * trace.ndim)) * np.einsum("ii...->...", stress) / 3
    return np.sqrt(1.5 * np.einsum("ij...,ij...->...", deviator, deviator))


def facet_indices(mesh: Mesh, triangles: np.ndarray) -> np.ndarray:
    """Indices into mesh.facets of the given vertex triangles (3, n); all must be mesh facets."""
    n_vertices = mesh.p.shape[1]
    if float(n_vertices) ** 3 >= 2.0**62:
        raise FemError(f"mesh too large for facet lookup: {n_vertices} vertices")

    def keys(tri: np.ndarray) -> np.ndarray:
        s = np.sort(tri.astype(np.int64), axis=0)
        return (s[0] * n_vertices + s[1]) * n_vertices + s[2]

    mesh_keys = keys(mesh.facets)
    order = np.argsort(mesh_keys)
    wanted = keys(np.asarray(triangles))
    pos = np.searchsorted(mesh_keys, wanted, sorter=order)
    pos = np.minimum(pos, len(order) - 1)
    found = mesh_keys[order[pos]] == wanted
    if not found.all():
        raise FemError(f"{int((~found).sum())} of {len(wanted)} tagged triangles are not facets of the mesh")
    return order[pos]


def dof_locations(basis: Basis) -> np.ndarray:
    """Coordinates (3, N) of the scalar DOFs."""
    return np.asarray(basis.doflocs)


def fixed_vector_dofs(basis: Basis, facets: np.ndarray, components=(0, 1, 2)) -> np.ndarray:
    """Interleaved DOFs of the given components on the given facets (all nodes of the facets)."""
    scalar = basis.get_dofs(facets=np.asarray(facets)).flatten()
    return (DIM * scalar[:, None] + np.asarray(components)).ravel()


__all__ = [
    "as_components",
    "displacement_gradients",
    "dof_locations",
    "element",
    "facet_indices",
    "facet_reference_points",
    "fixed_vector_dofs",
    "scalar_basis",
    "solve_displacement",
    "traction_load",
    "vector_dofs",
    "von_mises_Pa",
]
