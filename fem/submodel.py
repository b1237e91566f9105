"""A stress sub-model: the link inside balls around its hot spots, driven by a global solution.

The sub-model's domain is the part (or its mirror half) inside one or more balls
(geometry.ball_mesh). On the faces the balls cut (`cut_facets`) its displacement is the global
solution's, interpolated there (`GlobalField`); on its free surface it is traction free; on a
clamped bore inside a ball u = 0, on the loaded bore the global's bearing pressure, on the mirror
plane the normal displacement is held, all as in fem.link. Where the sub-model's mesh is the global
mesh restricted to the balls, its solution is the global's (tested): the sub-model only adds
resolution, not another problem. The global's error reaches the sub-model through the cut, and its
effect on the stress at the ball's centre decays with the distance to the cut (Saint-Venant), so
the peak is taken at least `trusted_margin_m` inside the cut.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from skfem import Basis

from . import problem, solvers
from .assembly import DIM, elasticity_parts
from .errors import FemError
from .link import (
    MIN_CURVED_JACOBIAN_RATIO,
    LinkSolution,
    bearing_traction,
    rim_points_of_triangles,
    straighten_distorted,
)
from .materials import Material
from .tets import CurvedTets, Tets

_CANDIDATES = 12  # nearest cells (by centroid) tried for each point located in the global mesh
# A further material's CG on the first one's factor (fem.solvers.further_material_cg) stops at this
# energy-norm error, tighter than the global's REUSE_ENERGY_TOLERANCE: a sub-model is driven by
# displacements on its cut, and the energy the CG measures the error against is its free part's
# with the cut held still, near-rigid motion included, far more than the strain energy its stresses
# come from. On the default link's loaded-bore ball (tests/test_fem_submodel.py) the displacement's
# error was 1.8e-4 of the largest at 1e-4, 5.5e-7 at this 1e-6.
SUBMODEL_ENERGY_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class Interpolation:
    """A global basis's values at points: each point's cell's DOFs and the basis functions there,
    (n_local, n) each."""

    basis: Basis
    dofs: np.ndarray
    phi: np.ndarray


@dataclass(frozen=True, eq=False)
class GlobalField:
    """What a sub-model takes from one material's global solution: its displacement anywhere, the
    bearing pressure it carried, and where the clamp's rims are."""

    solution: LinkSolution

    @property
    def material(self) -> Material:
        return self.solution.material

    @property
    def load_N(self) -> float:
        return self.solution.load_N

    @property
    def mirror_axis(self) -> int | None:
        """The normal of the global's mirror plane (held on a sub-model's faces there), if a half."""
        plane = self.solution.link.mirror_plane
        return None if plane is None else plane.axis

    @property
    def clamp_exclusion_m(self) -> float:
        return self.solution.clamp_exclusion_radius_m

    def bearing_traction(self, p0_Pa: float):
        """The loaded bore's bearing traction at p0 (fem.link.bearing_traction)."""
        link = self.solution.link
        return bearing_traction(link.loaded_bore, link.load_direction, p0_Pa)

    def displacement_m(self, points_m: np.ndarray, at: Interpolation | None = None) -> np.ndarray:
        """The global displacement (3, n) at points (3, n), at the global's load. `at`: the points'
        `interpolation` made by another field, used where it is on this field's basis (one stiffness
        level's materials share their mesh and basis, so the points are located once), else the
        points are located again."""
        if at is None or at.basis is not self.solution.basis:
            at = self.interpolation(points_m)
        values = np.zeros((3, at.phi.shape[1]))
        for dofs, phi in zip(at.dofs, at.phi):
            values += self.solution.displacement_m[:, dofs] * phi
        return values

    def interpolation(self, points_m: np.ndarray) -> Interpolation:
        """Where points (3, n) lie in the global's basis: the cell holding a point found among the
        nearest by centroid, its reference coordinates by the cell's own (curved) map; a point just
        outside the global's faceted boundary gets the nearest cell's polynomial continued (the
        sub-model's CAD surface and the global's mesh differ by O(h^3))."""
        basis = self.solution.basis
        points_m = np.asarray(points_m, dtype=float)
        if points_m.shape[1] == 0:
            return Interpolation(basis, np.zeros((basis.Nbfun, 0), dtype=np.int64), np.zeros((basis.Nbfun, 0)))
        best, best_local = _locate(basis.mesh, points_m)
        if not basis.mesh.affine:
            best_local = _curved_local(basis.mapping, points_m, best, best_local)
        phi = [
            np.asarray(basis.elem.gbasis(basis.mapping, best_local[:, :, None], i, tind=best)[0])[:, 0]
            for i in range(basis.Nbfun)
        ]
        return Interpolation(basis, basis.element_dofs[:, best], np.array(phi))

    def bearing_pressure_Pa(self) -> float:
        """p0 of the global's bearing pressure at its load (the discrete resultant normalised as
        fem.link does it)."""
        link, basis = self.solution.link, self.solution.basis
        index = _vertex_index(link)
        facets = problem.facet_indices(basis.mesh, index[link.loaded_bore_facets])
        unit = problem.traction_load(basis, facets, bearing_traction(link.loaded_bore, link.load_direction, 1.0))
        resultant_per_Pa = float(link.load_direction @ problem.as_components(unit).sum(axis=1))
        copies = 1 if link.mirror_plane is None else 2
        return self.solution.load_N / copies / resultant_per_Pa

    def clamp_rim_points_m(self) -> np.ndarray:
        """Points (n, 3) along the clamped bore's rims (the edges its facets use once)."""
        link = self.solution.link
        return rim_points_of_triangles(link.points_m, link.fixed_bore_facets, link.mirror_plane)


def _locate(mesh, points_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each point (3, n): the cell among the nearest `_CANDIDATES` (by centroid) whose straight
    tetrahedron holds it, or is nearest to holding it (least negative barycentric coordinate), and
    the point's reference coordinates (3, n) in that straight cell."""
    vertices = mesh.p[:, mesh.t[:4]]  # (3, 4, n_cells)
    _, near = cKDTree(vertices.mean(axis=1).T).query(points_m.T, k=min(_CANDIDATES, mesh.t.shape[1]))
    near = near.reshape(points_m.shape[1], -1)
    best = near[:, 0].copy()
    best_outside = np.full(points_m.shape[1], np.inf)
    best_local = np.zeros((3, points_m.shape[1]))
    for cells in near.T:
        origin = vertices[:, 0, cells]
        edges = np.transpose(vertices[:, 1:, cells] - origin[:, None, :], (2, 0, 1))  # (n, 3, 3)
        local = np.linalg.solve(edges, (points_m - origin).T[:, :, None])[:, :, 0].T
        outside = np.maximum(-np.vstack([local, 1 - local.sum(axis=0)]).min(axis=0), 0.0)
        better = outside < best_outside
        best[better], best_outside[better], best_local[:, better] = cells[better], outside[better], local[:, better]
    return best, best_local


_NEWTON_ITERATIONS = 20
_NEWTON_TOLERANCE = 1e-13


def _curved_local(mapping, points_m: np.ndarray, cells: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Reference coordinates (3, n) of points in their curved cells: Newton's method on the cells'
    isoparametric maps from the straight cells' coordinates (not clipped to the cell: a point just
    outside the global's boundary gets the cell's map continued)."""
    X = start[:, :, None].copy()
    x = points_m[:, :, None]
    for _ in range(_NEWTON_ITERATIONS):
        dX = np.einsum("ijkl,jkl->ikl", mapping.invDF(X, cells), x - mapping.F(X, cells))
        X += dX
        if np.abs(dX).max() < _NEWTON_TOLERANCE:
            break
    return X[:, :, 0]


def _vertex_index(link) -> np.ndarray:
    used = np.unique(link.tets)
    index = np.full(link.points_m.shape[1], -1, dtype=np.int64)
    index[used] = np.arange(len(used))
    return index


@dataclass(frozen=True, eq=False)
class SubModelSolution:
    """One material's sub-model solution; stresses per newton of the global's load."""

    material: Material
    peak_Pa_per_N: float  # over element nodes at least trusted_margin_m inside the cut, away from the clamp
    location_m: tuple[float, float, float]
    dofs: int
    basis: Basis
    displacement_m: np.ndarray  # (3, basis.N)
    von_mises_at_dofs_Pa: np.ndarray  # (basis.N,) at the global's load
    trusted_at_dofs: np.ndarray  # (basis.N,) bool: inside the trusted region, away from the clamp


def skfem_ball_mesh(ball, order: int):
    """scikit-fem mesh of a `geometry.ball_mesh.BallMesh` (curved P2 cells straightened at
    MIN_CURVED_JACOBIAN_RATIO everywhere, as the stress study's levels are) and the map from its
    point index to mesh vertex index."""
    used = np.unique(ball.tets)
    index = np.full(ball.points_m.shape[1], -1, dtype=np.int64)
    index[used] = np.arange(len(used))
    if order == 2 and ball.tets10 is not None:
        used10, compact = np.unique(ball.tets10, return_inverse=True)
        mesh = CurvedTets(np.ascontiguousarray(ball.points_m[:, used10]), compact.reshape(ball.tets10.shape))
        return straighten_distorted(mesh, MIN_CURVED_JACOBIAN_RATIO), index
    return Tets(np.ascontiguousarray(ball.points_m[:, used]), index[ball.tets]), index


def solve_submodel(
    ball,
    fields: Sequence[GlobalField],
    *,
    order: int = 2,
    trusted_margin_m: float,
    solver: str = "auto",
) -> dict[str, SubModelSolution]:
    """Solve the sub-model on `ball` (a `geometry.ball_mesh.BallMesh`) for each material's global
    field; everything but the material and its driving data is built once (mesh, basis, the
    material-free stiffness parts), and the first material's factorisation preconditions the others
    (as fem.link does)."""
    sk_mesh, index = skfem_ball_mesh(ball, order)
    basis = problem.scalar_basis(sk_mesh, order)
    triangles = {
        "cut": ball.cut_facets,
        "fixed": ball.fixed_bore_facets,
        "loaded": ball.loaded_bore_facets,
        "mirror": ball.mirror_facets,
    }
    facets = {
        name: problem.facet_indices(sk_mesh, index[tri]) if tri.shape[1] else np.zeros(0, dtype=np.int64)
        for name, tri in triangles.items()
    }
    clamped = problem.fixed_vector_dofs(basis, facets["fixed"]) if facets["fixed"].size else np.zeros(0, np.int64)
    cut_scalar = np.unique(basis.get_dofs(facets=facets["cut"]).flatten())
    floating = _floating_dofs(basis, np.concatenate([cut_scalar, clamped // DIM]))
    cut_scalar = np.union1d(cut_scalar, floating)  # a piece held by nothing follows the global
    held = [DIM * cut_scalar[:, None] + np.arange(DIM), clamped.reshape(-1, 1)]
    axis = fields[0].mirror_axis
    if facets["mirror"].size and axis is not None:
        on_plane = np.unique(basis.get_dofs(facets=facets["mirror"]).flatten())
        held.append((DIM * on_plane + axis).reshape(-1, 1))
    held_dofs = np.unique(np.concatenate([h.ravel() for h in held]))
    free = np.setdiff1d(np.arange(DIM * basis.N), held_dofs)
    parts = elasticity_parts(basis)
    locations = problem.dof_locations(basis)
    stress_points = _TrustedPoints(basis, ball, fields[0], trusted_margin_m, floating)
    unit_bearing = None
    if facets["loaded"].size:
        unit_bearing = problem.traction_load(basis, facets["loaded"], fields[0].bearing_traction(1.0))
    on_cut = locations[:, cut_scalar]
    at_cut = fields[0].interpolation(on_cut)
    results: dict[str, SubModelSolution] = {}
    factor = None
    first_u = None
    try:
        for field in fields:
            material = field.material
            driving = field.displacement_m(on_cut, at_cut)
            u = np.zeros(DIM * basis.N)
            u[(DIM * cut_scalar[:, None] + np.arange(DIM)).ravel()] = driving.T.ravel()
            f = np.zeros(DIM * basis.N) if unit_bearing is None else unit_bearing * field.bearing_pressure_Pa()
            K = parts.matrix(*material.lame_Pa)
            rhs = f[free] - K[free][:, held_dofs] @ u[held_dofs]
            K_free = K[free][:, free]
            if factor is None and solvers.resolve(solver) == "pardiso":
                factor = solvers.Factorization(K_free)
                u[free] = factor.solve(rhs)
            elif factor is not None:
                u[free] = solvers.further_material_cg(
                    K_free, rhs, factor, fields[0].material, first_u, material, SUBMODEL_ENERGY_TOLERANCE
                )
            else:
                u[free] = solvers.solve(K_free, rhs, solver)
            if first_u is None:
                first_u = u[free].copy()
            results[material.name] = stress_points.solution(material, u, field.load_N)
    finally:
        if factor is not None:
            factor.free()
    return results


def _floating_dofs(basis: Basis, anchored: np.ndarray) -> np.ndarray:
    """Scalar DOFs of the pieces of the mesh (cells joined through shared nodes) that hold none of
    the `anchored` DOFs: a ball can clip a thin feature off the rest of the part inside it, and such
    a piece, neither cut nor clamped, would be a free body. The sub-model drives it by the global
    displacements and does not take its stress."""
    cells = basis.element_dofs  # (n_local, n_cells)
    first = np.broadcast_to(cells[:1], cells[1:].shape)
    graph = sp.coo_matrix((np.ones(first.size), (first.ravel(), cells[1:].ravel())), shape=(basis.N, basis.N))
    _, piece = connected_components(graph, directed=False)
    return np.flatnonzero(~np.isin(piece, piece[anchored]))


class _TrustedPoints:
    """Element-node points of a sub-model, and which are trusted: at least the margin inside every
    cut sphere's surface (far enough from the driven boundary) and beyond the clamp exclusion
    distance from the clamped bore's rims."""

    def __init__(self, basis: Basis, ball, field: GlobalField, margin_m: float, floating: np.ndarray):
        local = basis.elem.doflocs.T
        self.basis = basis
        self.at_nodes = Basis(basis.mesh, basis.elem, quadrature=(local, np.ones(local.shape[1])))
        self.where = np.asarray(basis.mapping.F(local))  # (3, n_elements, n_local)
        flat = self.where.reshape(3, -1)
        centers = np.atleast_2d(ball.centers_m)
        radii = np.broadcast_to(np.asarray(ball.radius_m, dtype=float), (centers.shape[0],))
        depth = np.max([r - np.linalg.norm(flat.T - c, axis=1) for c, r in zip(centers, radii)], axis=0)
        inside = depth >= margin_m
        rims = field.clamp_rim_points_m()
        distance = cKDTree(rims).query(flat.T)[0] if len(rims) else np.full(flat.shape[1], np.inf)
        exclusion = field.clamp_exclusion_m
        self.element_dofs = basis.element_dofs.T
        held_by_nothing = np.isin(self.element_dofs, floating)
        self.trusted = (inside & (distance > exclusion)).reshape(self.where.shape[1:]) & ~held_by_nothing
        near = np.bincount(self.element_dofs.ravel(), ~self.trusted.ravel(), basis.N)
        self.trusted_at_dofs = near == 0

    def solution(self, material: Material, u: np.ndarray, load_N: float) -> SubModelSolution:
        lam, mu = material.lame_Pa
        components = problem.as_components(u)
        grads = np.array([np.asarray(self.at_nodes.interpolate(components[c]).grad) for c in range(DIM)])
        vm = problem.von_mises_Pa(grads, lam, mu)
        dofs = self.element_dofs.ravel()
        at_dofs = np.bincount(dofs, vm.ravel(), self.basis.N) / np.bincount(dofs, minlength=self.basis.N)
        if not self.trusted.any():
            raise FemError("the stress sub-model has no element node inside its trusted region: enlarge its balls")
        peak = int(np.argmax(np.where(self.trusted, vm, -np.inf)))
        return SubModelSolution(
            material=material,
            peak_Pa_per_N=float(vm.ravel()[peak]) / load_N,
            location_m=tuple(float(x) for x in self.where.reshape(3, -1)[:, peak]),
            dofs=int(DIM * self.basis.N),
            basis=self.basis,
            displacement_m=components.copy(),
            von_mises_at_dofs_Pa=at_dofs,
            trusted_at_dofs=self.trusted_at_dofs,
        )
