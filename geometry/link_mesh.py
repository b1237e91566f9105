"""The contract between the geometry stage and the FEA stage: one meshed link with its two pin bores."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Bore:
    """A cylindrical pin bore. All lengths in metres."""

    center_m: np.ndarray  # (3,) point on the axis, midway along the bore
    axis: np.ndarray  # (3,) unit vector along the bore axis
    radius_m: float
    length_m: float


_ON_PLANE = 1e-9
# A tetrahedron's vertices 1 and 2 exchanged, with its edges (01 <-> 02, 13 <-> 23), VTK order.
_SWAP_1_2 = np.array([0, 2, 1, 3, 6, 5, 4, 7, 9, 8])


def part_size_m(points_m: np.ndarray) -> float:
    """The largest extent of points (3, n) along a coordinate axis: the scale that `MirrorPlane.on_plane`
    measures its tolerance against."""
    return float(np.ptp(np.asarray(points_m), axis=1).max())


@dataclass(frozen=True)
class MirrorPlane:
    """A plane of mirror symmetry of the link and its load case, normal to a coordinate axis (so
    that symmetry is one fixed displacement component on the plane)."""

    offset_m: float  # the plane is x[axis] = offset_m
    axis: int  # 0, 1 or 2: the plane's normal

    def distance_m(self, points_m: np.ndarray) -> np.ndarray:
        """Signed distance of points (3, ...) from the plane, along the axis."""
        return np.asarray(points_m)[self.axis] - self.offset_m

    def on_plane(self, points_m: np.ndarray, part_size_m: float) -> np.ndarray:
        """Which points (3, ...) lie on the plane: within a 1e-9 fraction of the part's size (mesh
        nodes there are placed on it up to round-off)."""
        return np.abs(self.distance_m(points_m)) <= _ON_PLANE * part_size_m

    def reflect(self, points_m: np.ndarray) -> np.ndarray:
        """Mirror images of points (3, ...)."""
        mirrored = np.array(points_m, dtype=float, copy=True)
        mirrored[self.axis] = 2 * self.offset_m - mirrored[self.axis]
        return mirrored

    @property
    def name(self) -> str:
        """E.g. "y = 0 mm", for messages."""
        return f"{'xyz'[self.axis]} = {self.offset_m * 1e3:.4g} mm"

    def whole(self, points_m: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A half's mesh joined with its mirror image: (points (3, m), cells (n_local, 2 n), image)
        where image[i] is the index of point i's mirror image (itself on the plane).

        cells: (4 or 10, n) tetrahedra in VTK / meshio order (vertices, then edges 01 12 02 03 13
        23); the mirrored cells get vertices 1 and 2 swapped (and their edges) to keep their
        orientation."""
        points_m = np.asarray(points_m, dtype=float)
        off = ~self.on_plane(points_m, part_size_m(points_m))
        n = points_m.shape[1]
        image = np.arange(n)
        image[off] = n + np.arange(np.count_nonzero(off))
        whole_points = np.hstack([points_m, self.reflect(points_m[:, off])])
        swap = _SWAP_1_2[: cells.shape[0]]
        return whole_points, np.hstack([cells, image[cells[swap]]]), image


@dataclass(frozen=True)
class LinkMesh:
    """A tetrahedral mesh of one link, in metres, with the two bore surfaces tagged.

    The load case pulls the link apart: the fixed bore is clamped, the loaded bore carries the
    pin bearing pressure in the direction from the fixed bore's axis to the loaded bore's axis.
    With a `mirror_plane` the mesh is the half of the link on its positive side: the bore facets
    are those of that half, `mirror_facets` lie on the plane and the load case is the whole
    link's, halved (the FEA applies the symmetry there).
    """

    points_m: np.ndarray  # (3, n_nodes)
    tets: np.ndarray  # (4, n_tets) vertex indices of linear tetrahedra
    fixed_bore_facets: np.ndarray  # (3, n) vertex indices of triangles on the fixed bore
    loaded_bore_facets: np.ndarray  # (3, n) vertex indices of triangles on the loaded bore
    fixed_bore: Bore
    loaded_bore: Bore
    cad_volume_m3: float  # exact solid volume from the CAD kernel
    mesh_size_m: float
    source: str  # file path, or "default" for the built-in parametric link
    # Optional curved (isoparametric) quadratic mesh: (10, n_tets) node indices into points_m in
    # meshio's "tetra10" order, first four columns equal to `tets`. None for a linear mesh.
    tets10: np.ndarray | None = None
    mirror_plane: MirrorPlane | None = None
    mirror_facets: np.ndarray | None = None  # (3, n) vertex indices of triangles on the mirror plane

    @property
    def load_direction(self) -> np.ndarray:
        """Unit vector from the fixed bore axis to the loaded bore axis, normal to the axes."""
        d = self.loaded_bore.center_m - self.fixed_bore.center_m
        a = self.fixed_bore.axis
        d = d - np.dot(d, a) * a
        return d / np.linalg.norm(d)

    @property
    def pitch_m(self) -> float:
        """Distance between the two bore axes."""
        d = self.loaded_bore.center_m - self.fixed_bore.center_m
        a = self.fixed_bore.axis
        return float(np.linalg.norm(d - np.dot(d, a) * a))
