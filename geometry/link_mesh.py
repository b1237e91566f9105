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


@dataclass(frozen=True)
class LinkMesh:
    """A tetrahedral mesh of one link, in metres, with the two bore surfaces tagged.

    The load case pulls the link apart: the fixed bore is clamped, the loaded bore carries the
    pin bearing pressure in the direction from the fixed bore's axis to the loaded bore's axis.
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
