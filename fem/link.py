"""Axial stiffness, mass and peak stress of one pin-loaded link (`analyse_link`).

Load case: the whole fixed-bore surface is clamped (u = 0). The loaded bore carries a bearing
pressure p0 max(0, cos phi) acting along the outward radial direction e_r (from the bore axis into
the material), phi measured about the bore axis from the load direction d (fixed axis -> loaded
axis), uniform along the bore. p0 is set so that the discrete resultant along d equals F exactly.
k = F / delta with the work-conjugate displacement delta = (1/F) integral(t . u dA) = f . u / F.

A `LinkMesh` with a mirror plane is the half of a symmetric link: it carries F / 2 and its normal
displacement is held at zero on the plane, so its field is the whole link's under F; the work,
strain energy and mesh volume are doubled to give the whole link's k and volume.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree
from skfem import Basis, MeshTet1, MeshTet2
from skfem.quadrature import get_quadrature

from geometry.link_mesh import Bore, LinkMesh, part_size_m

from . import locking, problem, quality, solvers
from .assembly import DIM, elasticity_parts, rigid_body_modes
from .errors import FemError, FemWarning
from .fields import NodalFields
from .materials import Material
from .problem import JACOBIAN_CHECK_INTORDER
from .tets import CurvedTets, Tets, kept, with_nodes

# "Away from the clamp": element nodes farther than this fraction of the fixed bore's radius from
# the rim curves where the clamped bore surface ends. The clamp's rim is a stress singularity
# (the peak there grows without bound under refinement). Outside this distance the peak converges
# only if the part has no other sharp re-entrant edge: the default link's pocket and lug corners
# are sharp, so its peak (there) also grows slowly under refinement.
CLAMP_EXCLUSION_RADIUS_FRACTION = 0.25
# Curved cells whose Jacobian anywhere falls below this fraction of their straight-sided Jacobian
# (negative: inverted) are straightened (see straighten_distorted). At 0.2 scikit-fem's inverse
# facet map (since replaced by the exact points of fem.problem.facet_reference_points) still failed
# on the 1 mm edge-break example; 0.5 fixed it, touching a few cells only, and sets the meshes since.
MIN_CURVED_JACOBIAN_RATIO = 0.5
# Away from the bore facets (where the load and the clamp act) cells may be straightened only when
# nearly folded. Straightening cuts a round off to its chords: at 0.5 everywhere that took 1.0 %
# of the robot-arm link's volume at 3 mm elements (0.4 % at 1.95 mm) through its 2 mm edge rounds,
# and k fell outside its estimate; at 0.02 its curved mesh keeps the volume to 0.04 % (0.03 %).
# But where elements are far larger than a round (the built-in link's 1 mm edge breaks under
# 12 mm elements) the curved cells bulge out of the part (+1.4 % at 0.02, +0.9 % at 0.5), so
# `closest_to_cad` keeps whichever of the two gives the volume nearer the CAD's (measured,
# docs/incoming-wildcad.md).
MIN_CURVED_JACOBIAN_RATIO_AWAY = 0.02
# The Jacobian ratios away from the bore facets `closest_to_cad` chooses between (the k studies').
VOLUME_AWAY_RATIOS = (MIN_CURVED_JACOBIAN_RATIO, MIN_CURVED_JACOBIAN_RATIO_AWAY)
# Straightening a cell moves edges it shares with its neighbours, which can distort them in turn:
# repeat until none is left (the robot-arm link at 1.95 mm needed 5 rounds).
STRAIGHTENING_ROUNDS = 20


@dataclass(frozen=True, eq=False)
class LinkSolution:
    """Result of one solve. Per-newton quantities scale linearly; fields are at `load_N`."""

    material: Material
    order: int  # 1 (P1) or 2 (P2)
    curved: bool  # isoparametric quadratic cells (P2 on the link's tets10)
    load_N: float
    stiffness_N_per_m: float  # F / delta, delta = integral(t . u dA) / F
    stiffness_from_energy_N_per_m: float  # F^2 / (2 U), U = u.K.u / 2; equals the above up to solver round-off
    volume_m3: float  # CAD volume
    mesh_volume_m3: float  # volume of the meshed domain
    mass_kg: float  # density * CAD volume
    peak_von_mises_Pa_per_N: float  # overall, includes the clamp-rim singularity
    peak_von_mises_location_m: list[float]  # where the overall peak is (an element node)
    peak_von_mises_away_from_clamp_Pa_per_N: float
    peak_von_mises_away_location_m: list[float]  # where that peak is (an element node)
    clamp_exclusion_radius_m: float
    pitch_m: float
    bore_radius_m: float  # loaded bore
    mesh_size_m: float
    n_tets: int
    dofs: int  # vector DOFs solved (of the half link, if mirrored), constrained ones included
    whole_link_dofs: int  # dofs, or for a mirrored half those of its mesh joined with its mirror image
    solver: str
    timing_s: dict[str, float]
    link: LinkMesh
    basis: Basis  # scalar basis; displacement component c is displacement_m[c] in it
    displacement_m: np.ndarray  # (3, basis.N) at load_N
    von_mises_at_dofs_Pa: np.ndarray  # (basis.N,) element-node values averaged per DOF, at load_N
    away_from_clamp_at_dofs: np.ndarray  # (basis.N,) bool: the DOF is beyond clamp_exclusion_radius_m of the rims
    # why `solver` is not the one asked for (AMG-CG did not converge: fem.solvers.solve_reported); None: it is
    solver_fallback: str | None = None

    @property
    def mirrored(self) -> bool:
        """Solved on the half of a mirror-symmetric link: mesh, n_tets, dofs and fields are that half's."""
        return self.link.mirror_plane is not None


def fallback_note(solution: LinkSolution) -> str:
    """ ", <why the solver changed>" for a progress line; "" when the asked-for solver solved it."""
    return "" if solution.solver_fallback is None else f", {solution.solver_fallback}"


def whole_link_fields(solution: LinkSolution) -> NodalFields:
    """The solution on the whole link: as solved, or a mirrored half joined with its mirror image
    (positions reflected, the normal displacement component reversed, von Mises unchanged)."""
    points, cells = solution.basis.doflocs, solution.basis.element_dofs  # scikit-fem's node order is VTK's
    u, vm = solution.displacement_m, solution.von_mises_at_dofs_Pa
    if not solution.mirrored:
        return NodalFields(points, cells.T, u, vm)
    plane = solution.link.mirror_plane
    whole_points, whole_cells, image = plane.whole(points, cells)
    mirrored_u = u.copy()
    mirrored_u[plane.axis] *= -1
    displacement = np.empty((3, whole_points.shape[1]))
    displacement[:, image] = mirrored_u
    displacement[:, : u.shape[1]] = u
    von_mises = np.empty(whole_points.shape[1])
    von_mises[image] = vm
    von_mises[: vm.size] = vm
    return NodalFields(whole_points, whole_cells.T, displacement, von_mises)


def check_mesh_and_materials(
    mesh: LinkMesh, materials: Sequence[Material], order: int, *, warn_quality: bool = True
) -> None:
    """Refuse numerically flat elements (the solver would fail obscurely) and warn about slivers
    (unless warn_quality is False) and about P1 near incompressibility (volumetric locking), one
    line each."""
    q = quality.link_quality(mesh)
    quality.require_valid(q)
    messages = [quality.quality_warning(q) if warn_quality else None]
    messages += [locking.locking_warning(material, order) for material in materials]
    for message in messages:
        if message:
            warnings.warn(message, FemWarning, stacklevel=3)


def skfem_mesh(
    link: LinkMesh, order: int, curved: bool = True, away_ratios: Sequence[float] = VOLUME_AWAY_RATIOS
) -> tuple[MeshTet1, np.ndarray]:
    """scikit-fem mesh of the link and the map from LinkMesh point index to mesh vertex index.

    Vertices are renumbered to those used by `tets` in increasing order, which is also how
    scikit-fem renumbers a quadratic mesh; unused points (edge nodes of tets10) map to -1.
    `away_ratios`: the straightening candidates of `closest_to_cad`.
    """
    used = np.unique(link.tets)
    index = np.full(link.points_m.shape[1], -1, dtype=np.int64)
    index[used] = np.arange(len(used))
    if order == 2 and curved and link.tets10 is not None:
        if not np.array_equal(link.tets10[:4], link.tets):
            raise FemError("LinkMesh.tets10: first four rows must equal tets")
        # Compact the points first: scikit-fem keeps unreferenced points as spurious DOF locations.
        used10, compact = np.unique(link.tets10, return_inverse=True)
        points = np.ascontiguousarray(link.points_m[:, used10], dtype=float)
        bores = np.hstack([link.fixed_bore_facets, link.loaded_bore_facets])
        mesh = CurvedTets(points, compact.reshape(link.tets10.shape))
        mesh = closest_to_cad(
            mesh, cells_on_facets(mesh.t, index[bores]), link.cad_volume_m3 / _copies(link), away_ratios
        )
    else:
        mesh = Tets(np.ascontiguousarray(link.points_m[:, used], dtype=float), index[link.tets])
    return mesh, index


def _curved_jacobian_ratio(mesh: MeshTet2) -> np.ndarray:
    """Per element: min over quadrature points and vertices of det J (curved) / det J (straight)."""
    points = _jacobian_check_points(mesh)
    curved = _checked_det_jacobian(mesh)
    straight = Tets(np.ascontiguousarray(mesh.p[:, : mesh.nvertices]), mesh.t)._mapping().detDF(points[:, :1])
    return curved.min(axis=1) / straight[:, 0]


def _jacobian_check_points(mesh: MeshTet2) -> np.ndarray:
    """Where the curved cells' Jacobians are checked: the points of the reference cell's rule of
    JACOBIAN_CHECK_INTORDER, then its vertices."""
    return np.hstack([get_quadrature(mesh.elem.refdom, JACOBIAN_CHECK_INTORDER)[0], np.eye(3, 4, 1)])


def _checked_det_jacobian(mesh: MeshTet2) -> np.ndarray:
    """det J of the curved cells at `_jacobian_check_points`, kept on a `CurvedTets` (the last round
    of straightening, the volume of its result and the stress points' check ask for the same mesh's)."""
    return kept(mesh, "det J at the check points", lambda: _curved_det_jacobian(mesh, _jacobian_check_points(mesh)))


def cells_on_facets(cells: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Per cell (4, n vertex indices): whether one of its faces is among `facets` (3, m)."""
    n = int(max(cells.max(), facets.max())) + 1

    def keys(triangles: np.ndarray) -> np.ndarray:
        a, b, c = np.sort(triangles, axis=0).astype(np.int64)
        return (a * n + b) * n + c

    wanted = keys(facets)
    faces = [cells[[1, 2, 3]], cells[[0, 2, 3]], cells[[0, 1, 3]], cells[[0, 1, 2]]]
    return np.any([np.isin(keys(face), wanted) for face in faces], axis=0)


def closest_to_cad(
    mesh: MeshTet2, on_facets: np.ndarray, cad_volume_m3: float, away_ratios: Sequence[float] = VOLUME_AWAY_RATIOS
) -> MeshTet2:
    """The mesh straightened at MIN_CURVED_JACOBIAN_RATIO at the bore facets and at each of
    `away_ratios` elsewhere (by default: at MIN_CURVED_JACOBIAN_RATIO everywhere, or at
    MIN_CURVED_JACOBIAN_RATIO_AWAY away from the bore facets): whichever has its volume nearer the
    CAD volume."""
    candidates = []
    for away in away_ratios:
        try:
            candidates.append(straighten_distorted(mesh, on_facets=on_facets, away_ratio=away))
        except FemError:
            continue
    if not candidates:
        raise FemError(
            f"LinkMesh.tets10: inverted curved cells remain after {STRAIGHTENING_ROUNDS} rounds of "
            "straightening; pass another --mesh-size MM (or --order 1)"
        )
    return min(candidates, key=lambda m: abs(_curved_volume_m3(m) - cad_volume_m3))


def _curved_volume_m3(mesh: MeshTet2) -> float:
    _, weights = get_quadrature(mesh.elem.refdom, JACOBIAN_CHECK_INTORDER)
    return float(np.sum(np.abs(_checked_det_jacobian(mesh)[:, : weights.size]) @ weights))


def _curved_det_jacobian(mesh: MeshTet2, points: np.ndarray) -> np.ndarray:
    """det J of the cells' isoparametric maps (n_elements, n_points) at reference points (3, n_points):
    scikit-fem's `detDF` to about 1e-12 of itself (another summation order), in one product of the
    cells' nodes with the basis gradients instead of 90 accumulations of the cells' arrays (a third
    of its CPU on the default link's meshes, where the straightening calls it 4-6 times a level)."""
    element = mesh.elem()
    cells = mesh.dofs.element_dofs  # (10, n_elements), scikit-fem's node order
    gradients = np.array([element.lbasis(points, node)[1] for node in range(cells.shape[0])])  # (10, 3, n_points)
    J = np.einsum("ine,njq->ijeq", mesh.doflocs[:, cells], gradients, optimize=True)
    return (
        J[0, 0] * (J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1])
        - J[0, 1] * (J[1, 0] * J[2, 2] - J[1, 2] * J[2, 0])
        + J[0, 2] * (J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0])
    )


def straighten_distorted(
    mesh: MeshTet2,
    min_ratio: float = MIN_CURVED_JACOBIAN_RATIO,
    on_facets: np.ndarray | None = None,
    away_ratio: float = MIN_CURVED_JACOBIAN_RATIO_AWAY,
) -> MeshTet2:
    """Move the mid-edge nodes of badly distorted curved cells back onto their chords.

    gmsh's order-2 meshes can hold inverted cells next to small fillets or chamfers (seen on a
    1 mm edge break); those break the isoparametric map. Straightening a few cells costs only a
    local O(h^2) geometry error there. With `on_facets` (per cell: it has a face on a loaded or
    clamped facet) only those cells are held to `min_ratio`; the others are straightened below
    `away_ratio` only (nearly folded), which keeps the rounds they follow.
    """
    limit = min_ratio if on_facets is None else np.where(on_facets, min_ratio, away_ratio)
    for _ in range(STRAIGHTENING_ROUNDS):
        bad = np.flatnonzero(_curved_jacobian_ratio(mesh) < limit)
        if len(bad) == 0:
            return mesh
        edges = np.unique(mesh.t2e[:, bad])
        doflocs = mesh.doflocs.copy()
        doflocs[:, mesh.nvertices + edges] = 0.5 * (mesh.p[:, mesh.edges[0, edges]] + mesh.p[:, mesh.edges[1, edges]])
        mesh = with_nodes(mesh, doflocs)
    raise FemError(
        f"LinkMesh.tets10: inverted curved cells remain after {STRAIGHTENING_ROUNDS} rounds of "
        "straightening; pass another --mesh-size MM (or --order 1)"
    )


def _facets(mesh, index: np.ndarray, triangles: np.ndarray, name: str) -> np.ndarray:
    triangles = np.asarray(triangles)
    if triangles.ndim != 2 or triangles.shape[0] != 3 or triangles.shape[1] == 0:
        raise FemError(f"LinkMesh.{name}: expected a non-empty (3, n) triangle array, got shape {triangles.shape}")
    mapped = index[triangles]
    if (mapped < 0).any():
        raise FemError(f"LinkMesh.{name}: triangles use points that are not tetrahedron vertices")
    facets = problem.facet_indices(mesh, mapped)
    if (mesh.f2t[1, facets] != -1).any():
        raise FemError(f"LinkMesh.{name}: some triangles are interior faces, expected boundary facets of the mesh")
    return facets


def _discretise(link: LinkMesh, sk_mesh, index: np.ndarray, order: int):
    """Basis, clamped facets, the load vector of a unit bearing pressure p0 = 1 Pa, and the scalar
    DOFs on the mirror plane of a half link (none for a whole one)."""
    fixed = _facets(sk_mesh, index, link.fixed_bore_facets, "fixed_bore_facets")
    loaded = _facets(sk_mesh, index, link.loaded_bore_facets, "loaded_bore_facets")
    basis = problem.scalar_basis(sk_mesh, order)
    traction = bearing_traction(link.loaded_bore, link.load_direction, 1.0)
    unit = problem.traction_load(basis, loaded, traction)
    on_plane = np.zeros(0, dtype=np.int64)
    if link.mirror_plane is not None:
        if link.mirror_facets is None:
            raise FemError("LinkMesh.mirror_facets: expected the facets on the mirror plane of a half link")
        mirror = _facets(sk_mesh, index, link.mirror_facets, "mirror_facets")
        on_plane = np.unique(basis.get_dofs(facets=mirror).flatten())
    return basis, fixed, unit, on_plane


def bearing_traction(bore: Bore, direction: np.ndarray, p0_Pa: float):
    """t(x) = p0 max(0, cos phi) e_r on a bore, phi from `direction` about the bore axis."""
    center = np.asarray(bore.center_m, dtype=float)
    axis = np.asarray(bore.axis, dtype=float) / np.linalg.norm(bore.axis)
    direction = np.asarray(direction, dtype=float)

    def traction(x: np.ndarray) -> np.ndarray:
        rel = x - center.reshape(3, *([1] * (x.ndim - 1)))
        radial = rel - np.einsum("i,i...->...", axis, rel) * axis.reshape(3, *([1] * (x.ndim - 1)))
        e_r = radial / np.linalg.norm(radial, axis=0)
        cos_phi = np.einsum("i,i...->...", direction, e_r)
        return p0_Pa * np.maximum(cos_phi, 0.0) * e_r

    return traction


def _rim_points(mesh, facets: np.ndarray, mirror_plane=None, samples_per_edge: int = 4) -> np.ndarray:
    """Points (n, 3) along the boundary curves of a facet set (edges used by one facet only), less
    the edges on a mirror plane (there the facet set continues in the other half)."""
    return rim_points_of_triangles(mesh.p, mesh.facets[:, facets], mirror_plane, samples_per_edge)


def rim_points_of_triangles(
    points_m: np.ndarray, triangles: np.ndarray, mirror_plane=None, samples_per_edge: int = 4
) -> np.ndarray:
    """`_rim_points` of triangles (3, m) of vertex indices into points (3, n)."""
    tri = np.asarray(triangles)
    edges = np.sort(np.hstack([tri[[0, 1]], tri[[1, 2]], tri[[0, 2]]]), axis=0)
    unique, counts = np.unique(edges, axis=1, return_counts=True)
    rim = unique[:, counts == 1]
    if mirror_plane is not None:
        on_plane = mirror_plane.on_plane(points_m[:, rim], part_size_m(points_m))  # (2, n_edges)
        rim = rim[:, ~on_plane.all(axis=0)]
    s = np.linspace(0.0, 1.0, samples_per_edge + 1)
    a, b = points_m[:, rim[0]], points_m[:, rim[1]]
    return (a[:, :, None] * (1 - s) + b[:, :, None] * s).reshape(3, -1).T


def analyse_link(
    mesh: LinkMesh,
    material: Material,
    *,
    order: int = 2,
    load_N: float = 1000.0,
    solver: str = "auto",
) -> LinkSolution:
    """Solve the link's load case; see the module docstring. SI units in and out."""
    return analyse_link_materials(mesh, [material], order=order, load_N=load_N, solver=solver)[material.name]


def analyse_link_materials(
    mesh: LinkMesh,
    materials: Sequence[Material],
    *,
    order: int = 2,
    load_N: float = 1000.0,
    solver: str = "auto",
    stress: bool = True,
    checked: bool = False,
    away_ratios: Sequence[float] = VOLUME_AWAY_RATIOS,
    solve_slot: AbstractContextManager | None = None,
) -> dict[str, LinkSolution]:
    """`analyse_link` for several materials on one mesh, keyed by material name.

    Everything but the material is built once: basis, load, clamp and the material-free parts of
    the stiffness matrix (`assembly.ElasticityParts`). The first material is factorised; a material
    with the same Poisson's ratio is that solution scaled by the ratio of Young's moduli (exact); any
    other is solved by CG preconditioned with the first one's factorisation (PARDISO; a few
    back-substitutions, its error's energy norm to solvers.REUSE_ENERGY_TOLERANCE of the solution's),
    or directly with other solvers.
    Shared costs are booked in the first material's `timing_s`. stress=False skips the stress
    evaluation (its fields are NaN): a study needs stresses on its finest level only. checked=True:
    the caller has run `check_mesh_and_materials` (a study does, before it solves the level in a
    thread of its own, so that its warnings come from the caller's thread). `away_ratios`: how
    curved cells are straightened (`closest_to_cad`; the stress study holds them to one ratio).
    `solve_slot`: held from the first matrix to the factorisation's release (the solves and the
    stresses), so that levels solved side by side that share one never hold two factorisations at
    once (fem.study); None: not waited for.
    """
    problem.element(order)
    if not (np.isfinite(load_N) and load_N > 0):
        raise FemError(f"load_N must be a positive number, got {load_N!r}")
    if not materials or len({m.name for m in materials}) != len(materials):
        raise FemError(f"materials: expected a non-empty list of distinct materials, got {[m.name for m in materials]}")
    method = solvers.resolve(solver)
    shared: dict[str, float] = {}

    start = time.perf_counter()
    if not checked:
        check_mesh_and_materials(mesh, materials, order)
    sk_mesh, index = skfem_mesh(mesh, order, away_ratios=away_ratios)
    basis, fixed, unit, on_plane = _discretise(mesh, sk_mesh, index, order)
    direction = mesh.load_direction
    resultant_per_Pa = float(direction @ problem.as_components(unit).sum(axis=1))
    if not resultant_per_Pa > 0:
        raise FemError("LinkMesh.loaded_bore_facets: the bearing pressure has no resultant along the load direction")
    f = unit * (load_N / _copies(mesh) / resultant_per_Pa)
    # the clamp, and on a mirror plane the displacement normal to it
    held = problem.fixed_vector_dofs(basis, fixed)
    if mesh.mirror_plane is not None:
        held = np.concatenate([held, DIM * on_plane + mesh.mirror_plane.axis])
    free = np.setdiff1d(np.arange(f.size), held)
    # the whole link's mesh: a mirrored half's DOFs twice, less the shared plane's once
    whole_dofs = DIM * (_copies(mesh) * basis.N - (_copies(mesh) - 1) * len(on_plane))
    shared["basis_and_load"] = time.perf_counter() - start

    start = time.perf_counter()
    parts = elasticity_parts(basis).restricted(free)
    shared["assembly"] = time.perf_counter() - start

    start = time.perf_counter()
    stress_points = (
        _StressPoints(basis, sk_mesh, fixed, mesh.fixed_bore.radius_m, mesh.mirror_plane) if stress else None
    )
    shared["post"] = time.perf_counter() - start

    results: dict[str, LinkSolution] = {}
    first: tuple[Material, np.ndarray] | None = None
    factor = None
    fallback = None  # why the first solve left the asked-for solver: the others use the one it took
    modes = rigid_body_modes(problem.dof_locations(basis))[free] if method == "amg" else None
    with solve_slot if solve_slot is not None else nullcontext():
        try:
            for material in materials:
                timing = dict(shared) if first is None else {}
                lam, mu = material.lame_Pa
                start = time.perf_counter()
                K = parts.matrix(lam, mu)
                timing["assembly"] = timing.get("assembly", 0.0) + time.perf_counter() - start
                start = time.perf_counter()
                u = np.zeros(f.size)
                if first is None:
                    if method == "pardiso":
                        factor = solvers.Factorization(K)
                        u[free] = factor.solve(f[free])
                    else:
                        solved = solvers.solve_reported(K, f[free], method, near_nullspace=modes)
                        u[free], method, fallback = solved.x, solved.solver, solved.fallback
                    first = (material, u)
                else:
                    u[free] = _reuse(first, material, K, f[free], free, factor, method, modes)
                timing["solve"] = time.perf_counter() - start
                start = time.perf_counter()
                results[material.name] = _solution(
                    mesh,
                    sk_mesh,
                    basis,
                    material,
                    order,
                    load_N,
                    f,
                    u,
                    free,
                    K,
                    method,
                    stress_points,
                    timing,
                    whole_dofs,
                )
                if fallback is not None:
                    results[material.name] = replace(results[material.name], solver_fallback=fallback)
                timing["post"] = timing.get("post", 0.0) + time.perf_counter() - start
        finally:
            if factor is not None:
                factor.free()
    return results


def _copies(mesh: LinkMesh) -> int:
    """How many copies of the meshed part make the link (2 for a mirrored half)."""
    return 1 if mesh.mirror_plane is None else 2


def _same_poisson_ratio(a: Material, b: Material) -> bool:
    return abs(a.poisson_ratio - b.poisson_ratio) <= 1e-12 * abs(a.poisson_ratio)


def _reuse(
    first: tuple[Material, np.ndarray],
    material: Material,
    K,
    f_free: np.ndarray,
    free: np.ndarray,
    factor,
    method: str,
    modes: np.ndarray | None,
) -> np.ndarray:
    """Displacement (free DOFs) of `material` from the first material's solution on the same mesh."""
    first_material, first_u = first
    scale = first_material.youngs_modulus_Pa / material.youngs_modulus_Pa
    if _same_poisson_ratio(first_material, material):
        return first_u[free] * scale  # K is E times a matrix that depends on nu only
    if factor is None:
        return solvers.solve(K, f_free, method, near_nullspace=modes)
    return solvers.further_material_cg(K, f_free, factor, first_material, first_u[free], material)


class _StressPoints:
    """Material-free data of the stress evaluation: element-node points, their distance from the
    clamped bore's rim, and the basis that evaluates gradients there."""

    def __init__(self, basis: Basis, sk_mesh, fixed_facets: np.ndarray, fixed_radius_m: float, mirror_plane=None):
        local = basis.elem.doflocs.T
        self.at_nodes = Basis(basis.mesh, basis.elem, quadrature=(local, np.ones(local.shape[1])), dofs=basis.dofs)
        self.where = np.asarray(basis.mapping.F(local))  # (3, n_elements, n_local)
        self.exclusion_radius_m = CLAMP_EXCLUSION_RADIUS_FRACTION * fixed_radius_m
        distance, _ = cKDTree(_rim_points(sk_mesh, fixed_facets, mirror_plane)).query(self.where.reshape(3, -1).T)
        self.away = distance.reshape(self.where.shape[1:]) > self.exclusion_radius_m
        self.element_dofs = basis.element_dofs.T  # (n_elements, n_local)
        # a curved cell kept nearly folded for the volume of the round it follows (below
        # MIN_CURVED_JACOBIAN_RATIO, see closest_to_cad) carries the stiffness but its stress is the
        # map's artefact (39.8 MPa/kN on the default link's 4.5 mm level, 14 converged): the peaks skip it
        self.well_shaped = (
            _curved_jacobian_ratio(sk_mesh) >= MIN_CURVED_JACOBIAN_RATIO
            if isinstance(sk_mesh, MeshTet2)
            else np.ones(self.where.shape[1], dtype=bool)
        )
        flat = self.element_dofs.ravel()
        near = np.bincount(flat, ~self.away.ravel(), basis.N)
        self.away_at_dofs = near == 0

    def von_mises(self, u: np.ndarray, lam: float, mu: float) -> np.ndarray:
        components = problem.as_components(u)
        grads = np.array([np.asarray(self.at_nodes.interpolate(components[c]).grad) for c in range(3)])
        return problem.von_mises_Pa(grads, lam, mu)  # (n_elements, n_local)


def _solution(
    mesh: LinkMesh,
    sk_mesh,
    basis: Basis,
    material: Material,
    order: int,
    load_N: float,
    f: np.ndarray,
    u: np.ndarray,
    free: np.ndarray,
    K,
    method: str,
    points: _StressPoints | None,
    timing: dict,
    whole_dofs: int,
) -> LinkSolution:
    work = _copies(mesh) * solvers.dot(f, u)  # of the whole link
    if not work > 0:
        raise FemError("the link did not deform under the load: check the bore facet sets")
    return LinkSolution(
        material=material,
        order=order,
        curved=not sk_mesh.affine,
        load_N=float(load_N),
        stiffness_N_per_m=load_N**2 / work,
        stiffness_from_energy_N_per_m=load_N**2 / (_copies(mesh) * solvers.dot(u[free], K @ u[free])),
        volume_m3=float(mesh.cad_volume_m3),
        mesh_volume_m3=_copies(mesh) * float(np.sum(basis.dx)),
        mass_kg=material.density_kg_per_m3 * float(mesh.cad_volume_m3),
        clamp_exclusion_radius_m=CLAMP_EXCLUSION_RADIUS_FRACTION * mesh.fixed_bore.radius_m,
        pitch_m=mesh.pitch_m,
        bore_radius_m=float(mesh.loaded_bore.radius_m),
        mesh_size_m=float(mesh.mesh_size_m),
        n_tets=int(mesh.tets.shape[1]),
        dofs=int(3 * basis.N),
        whole_link_dofs=whole_dofs,
        solver=method,
        timing_s=timing,
        link=mesh,
        basis=basis,
        displacement_m=problem.as_components(u).copy(),
        **_stress_fields(points, basis, material, u, load_N),
    )


def _stress_fields(
    points: _StressPoints | None, basis: Basis, material: Material, u: np.ndarray, load_N: float
) -> dict:
    """The LinkSolution's stress fields: evaluated at `points`, or NaN where the stress is skipped
    (points None: a study's coarser levels)."""
    if points is None:
        nan = float("nan")
        return dict(
            peak_von_mises_Pa_per_N=nan,
            peak_von_mises_location_m=[nan] * 3,
            peak_von_mises_away_from_clamp_Pa_per_N=nan,
            peak_von_mises_away_location_m=[nan] * 3,
            von_mises_at_dofs_Pa=np.full(basis.N, nan),
            away_from_clamp_at_dofs=np.zeros(basis.N, dtype=bool),
        )
    lam, mu = material.lame_Pa
    vm = points.von_mises(u, lam, mu)
    dofs = points.element_dofs
    at_dofs = np.bincount(dofs.ravel(), vm.ravel(), basis.N) / np.bincount(dofs.ravel(), minlength=basis.N)
    where = points.where.reshape(3, -1)
    trusted = np.where(points.well_shaped[:, None], vm, -np.inf)
    away = points.away & points.well_shaped[:, None]
    peak = int(np.argmax(trusted))
    away_peak = int(np.argmax(np.where(away, vm, -np.inf))) if away.any() else peak
    return dict(
        peak_von_mises_Pa_per_N=float(trusted.ravel()[peak]) / load_N,
        peak_von_mises_location_m=where[:, peak].tolist(),
        peak_von_mises_away_from_clamp_Pa_per_N=float(vm[away].max()) / load_N if away.any() else float("nan"),
        peak_von_mises_away_location_m=where[:, away_peak].tolist(),
        von_mises_at_dofs_Pa=at_dofs,
        away_from_clamp_at_dofs=points.away_at_dofs,
    )
