"""Export a LinkMesh (and fields on it) to VTU for ParaView, through meshio."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from geometry.atomic import atomic_target
from geometry.errors import GeometryError
from geometry.link_mesh import LinkMesh


def write_vtu(
    mesh: LinkMesh,
    path: str | os.PathLike,
    *,
    point_data: dict[str, np.ndarray] | None = None,
    cell_data: dict[str, np.ndarray] | None = None,
) -> Path:
    """Write the link's tetrahedra (quadratic "tetra10" if the mesh has them) to a .vtu file.

    point_data arrays have one row per node of `mesh.points_m` (n_nodes, ...), cell_data arrays one
    row per tetrahedron (n_tets, ...). The file appears atomically (temporary file + rename).
    """
    import meshio  # here, not at the top: 60-90 ms of imports (beyond fem's own) that only writing needs

    path = Path(path)
    cells = [("tetra10", mesh.tets10.T)] if mesh.tets10 is not None else [("tetra", mesh.tets.T)]
    n_points, n_cells = mesh.points_m.shape[1], mesh.tets.shape[1]
    point_data = {name: np.asarray(a) for name, a in (point_data or {}).items()}
    cell_data = {name: np.asarray(a) for name, a in (cell_data or {}).items()}
    for kind, data, n in (("point_data", point_data, n_points), ("cell_data", cell_data, n_cells)):
        for name, a in data.items():
            if a.ndim == 0 or a.shape[0] != n:
                raise GeometryError(f"{kind}[{name!r}] has shape {a.shape}; expected ({n}, ...) for this mesh")
    out = meshio.Mesh(
        mesh.points_m.T,
        cells,
        point_data=point_data,
        cell_data={name: [a] for name, a in cell_data.items()},
    )
    with atomic_target(path) as tmp:
        meshio.write(tmp, out, file_format="vtu")
    return path
