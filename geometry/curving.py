"""How well curved quadratic tetrahedra follow the CAD, and where the mesh must be finer for them.

gmsh's `setOrder(2)` puts the mid-edge nodes of boundary edges on the CAD surfaces. Where an
element is large next to a small round (a 2 mm edge fillet under 3 mm elements), a boundary edge's
midpoint sits far off its chord and the cell's Jacobian changes sign: the isoparametric map
folds. The FEA then straightens such cells (fem.link.straighten_distorted), which cuts the round
off: on the robot-arm link of the wild corpus that took 0.5-1.0 % of the part's volume and k fell
outside its estimate. Meshing those rounds finer instead keeps the geometry: `distorted_cells`
finds the folded cells, `faces_of_cells` the CAD faces they lie on, and geometry.meshing meshes
again with elements a fraction of each such face's radius there.
"""

from __future__ import annotations

import gmsh
import numpy as np

# Cells whose Jacobian anywhere falls below this fraction of their straight-sided Jacobian count
# as distorted (fem.link straightens them at the same ratio).
MIN_JACOBIAN_RATIO = 0.5
# Barycentric sample points: vertices, edge midpoints, face centroids and the centroid.
_VERTICES = np.eye(4)
_EDGE_PAIRS = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))  # meshio tetra10 order of the edge nodes
_SAMPLES = np.vstack([
    _VERTICES,
    [(_VERTICES[i] + _VERTICES[j]) / 2 for i, j in _EDGE_PAIRS],
    (1 - _VERTICES) / 3,  # the centroid of the face opposite each vertex
    [np.full(4, 0.25)],
])


def _shape_gradients(lam: np.ndarray) -> np.ndarray:
    """(10, 3): d N_a / d xi_k of the 10 quadratic shape functions at barycentric point `lam`,
    xi_k = lam_k (k = 1..3), lam_0 = 1 - sum xi."""
    dn_dlam = np.zeros((10, 4))
    for a in range(4):
        dn_dlam[a, a] = 4 * lam[a] - 1
    for e, (i, j) in enumerate(_EDGE_PAIRS):
        dn_dlam[4 + e, i] = 4 * lam[j]
        dn_dlam[4 + e, j] = 4 * lam[i]
    return dn_dlam[:, 1:] - dn_dlam[:, :1]


_GRADIENTS = np.stack([_shape_gradients(lam) for lam in _SAMPLES])  # (n_samples, 10, 3)
# Keast's 5-point rule, exact for cubics (det J of a quadratic cell is one): barycentric points
# and weights on the reference tetrahedron (volume 1/6).
_KEAST_POINTS = np.vstack([np.full(4, 0.25), (np.eye(4) * 2 / 6 + 1 / 6)])
_KEAST_WEIGHTS = np.array([-2 / 15, 3 / 40, 3 / 40, 3 / 40, 3 / 40])
_KEAST_GRADIENTS = np.stack([_shape_gradients(lam) for lam in _KEAST_POINTS])


def jacobian_ratios(points_m: np.ndarray, tets10: np.ndarray) -> np.ndarray:
    """Per cell: min over sample points of det J (curved) / det J (straight-sided); 1 for a cell
    whose mid-edge nodes sit at its edges' midpoints, <= 0 for a folded one.

    points_m: (3, n); tets10: (10, m) in meshio tetra10 order."""
    x = np.asarray(points_m, float)[:, tets10]  # (3, 10, m)
    jac = np.einsum("dam,sak->smdk", x, _GRADIENTS)  # (n_samples, m, 3, 3)
    curved = np.linalg.det(jac)
    edges = x[:, 1:4] - x[:, :1]  # (3, 3, m)
    straight = np.linalg.det(np.moveaxis(edges, 2, 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = curved.min(axis=0) / straight
    return np.where(np.isfinite(ratio), ratio, -np.inf)


def straightening_volume_m3(points_m: np.ndarray, tets10: np.ndarray, cells: np.ndarray) -> float:
    """How much volume straightening these cells would remove: their curved volume less their
    straight-sided volume (positive where they bulge out of their chords)."""
    x = np.asarray(points_m, float)[:, tets10[:, cells]]
    curved = np.einsum("q,qm->m", _KEAST_WEIGHTS, np.linalg.det(np.einsum("dam,qak->qmdk", x, _KEAST_GRADIENTS)))
    edges = x[:, 1:4] - x[:, :1]
    straight = np.linalg.det(np.moveaxis(edges, 2, 0)) / 6
    return float(np.sum(np.abs(curved) - np.abs(straight)))


def distorted_cells(points_m: np.ndarray, tets10: np.ndarray, min_ratio: float = MIN_JACOBIAN_RATIO) -> np.ndarray:
    """Indices of the cells whose Jacobian ratio is below `min_ratio`."""
    return np.flatnonzero(jacobian_ratios(points_m, tets10) < min_ratio)


def faces_of_cells(node_tags: np.ndarray, faces: list[int]) -> list[int]:
    """The CAD faces (surface tags among `faces`) holding any of these mesh nodes (gmsh tags)."""
    wanted = set(np.asarray(node_tags, np.int64).tolist())
    found = []
    for face in faces:
        tags, _, _ = gmsh.model.mesh.getNodes(2, face, includeBoundary=True)
        if wanted.intersection(np.asarray(tags, np.int64).tolist()):
            found.append(face)
    return found


def face_radius_m(face: int) -> float | None:
    """The smallest radius of curvature of a cylinder, torus, sphere or cone face (None for others;
    a cone's is taken at its sampled points)."""
    kind = gmsh.model.getType(2, face)
    _, reals = gmsh.model.getEntityProperties(2, face)
    if kind == "Cylinder":
        return float(reals[6])
    if kind == "Torus":
        return float(min(reals[6], reals[7]))
    if kind == "Sphere":
        return float(reals[3])
    lo, hi = gmsh.model.getParametrizationBounds(2, face)
    uv = np.array([[u, v] for u in np.linspace(lo[0], hi[0], 5) for v in np.linspace(lo[1], hi[1], 5)]).ravel()
    curvature_max, curvature_min, _, _ = gmsh.model.getPrincipalCurvatures(face, uv)
    largest = float(np.max(np.abs(np.concatenate([curvature_max, curvature_min]))))
    return 1 / largest if largest > 0 else None
