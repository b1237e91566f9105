"""Write a solved link to VTU (ParaView) with meshio: displacement and von Mises stress per node."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.atomic import atomic_target

from .errors import FemError
from .link import LinkSolution, whole_link_fields


def write_solution_vtu(solution: LinkSolution, path: str | Path) -> Path:
    """Quadratic (P2) or linear (P1) tetrahedra in metres; point data in m and Pa at `load_N`.

    scikit-fem's P1/P2 node order is meshio's "tetra"/"tetra10" (VTK) order. A mirrored half is
    written as the whole link. Written atomically.
    """
    import meshio  # here, not at the top: 60-90 ms of imports (beyond fem's own) that only writing needs

    path = Path(path)
    if path.suffix.lower() != ".vtu":
        raise FemError(f"solution path {str(path)!r}: expected a .vtu file")
    fields = whole_link_fields(solution)
    cells = fields.cells
    mesh = meshio.Mesh(
        points=np.ascontiguousarray(fields.points_m.T),
        cells=[("tetra10" if cells.shape[1] == 10 else "tetra", cells)],
        point_data={
            "displacement_m": np.ascontiguousarray(fields.displacement_m.T),
            "von_mises_Pa": fields.von_mises_Pa,
        },
        field_data={"load_N": np.array([solution.load_N]), "stiffness_N_per_m": np.array([solution.stiffness_N_per_m])},
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_target(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return path
