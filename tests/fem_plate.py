"""Test helper: a plate with two pin bores meshed directly with gmsh, as a LinkMesh.

It lets the FEA tests run without the geometry stage. Lengths in metres.
"""

from __future__ import annotations

import gmsh
import numpy as np

from geometry.link_mesh import Bore, LinkMesh
from geometry.session import initialize_gmsh

GMSH_TET10_TO_MESHIO = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]


def plate_link(
    mesh_size_m: float = 0.006,
    *,
    order: int = 1,
    pitch_m: float = 0.1125,
    bore_radius_m: float = 0.008,
    width_m: float = 0.05,
    thickness_m: float = 0.02,
    end_m: float = 0.03,
) -> LinkMesh:
    """Plate along x with bores on z-parallel axes at x = 0 (fixed) and x = pitch (loaded)."""
    initialize_gmsh()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        plate = occ.addBox(-end_m, -width_m / 2, -thickness_m / 2, pitch_m + 2 * end_m, width_m, thickness_m)
        tools = [(3, occ.addCylinder(x, 0, -thickness_m, 0, 0, 2 * thickness_m, bore_radius_m)) for x in (0, pitch_m)]
        solid, _ = occ.cut([(3, plate)], tools)
        occ.synchronize()
        volume = occ.getMass(3, solid[0][1])
        bores: dict[str, list[int]] = {"fixed": [], "loaded": []}
        for _, surface in gmsh.model.getEntities(2):
            if gmsh.model.getType(2, surface) == "Cylinder":
                x = occ.getCenterOfMass(2, surface)[0]
                bores["fixed" if abs(x) < pitch_m / 2 else "loaded"].append(surface)
        field = gmsh.model.mesh.field
        distance = field.add("Distance")
        field.setNumbers(distance, "SurfacesList", bores["fixed"] + bores["loaded"])
        threshold = field.add("Threshold")
        field.setNumber(threshold, "InField", distance)
        field.setNumber(threshold, "SizeMin", 0.4 * mesh_size_m)
        field.setNumber(threshold, "SizeMax", mesh_size_m)
        field.setNumber(threshold, "DistMin", 0.3 * bore_radius_m)
        field.setNumber(threshold, "DistMax", 2 * bore_radius_m)
        field.setAsBackgroundMesh(threshold)
        for option in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{option}", 0)
        gmsh.model.mesh.generate(3)
        if order == 2:
            gmsh.model.mesh.setOrder(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        points = np.zeros((3, int(tags.max()) + 1))
        points[:, tags.astype(int)] = coords.reshape(-1, 3).T
        _, _, nodes = gmsh.model.mesh.getElements(3)
        cells = nodes[0].reshape(-1, 10 if order == 2 else 4).T.astype(np.int64)

        def triangles(surfaces: list[int]) -> np.ndarray:
            parts = []
            for surface in surfaces:
                _, _, facet_nodes = gmsh.model.mesh.getElements(2, surface)
                parts.append(facet_nodes[0].reshape(-1, 6 if order == 2 else 3)[:, :3].T.astype(np.int64))
            return np.hstack(parts)

        fixed, loaded = triangles(bores["fixed"]), triangles(bores["loaded"])
    finally:
        gmsh.finalize()
    axis = np.array([0.0, 0.0, 1.0])
    return LinkMesh(
        points_m=points,
        tets=np.ascontiguousarray(cells[:4]),
        fixed_bore_facets=fixed,
        loaded_bore_facets=loaded,
        fixed_bore=Bore(np.zeros(3), axis, bore_radius_m, thickness_m),
        loaded_bore=Bore(np.array([pitch_m, 0.0, 0.0]), axis, bore_radius_m, thickness_m),
        cad_volume_m3=volume,
        mesh_size_m=mesh_size_m,
        source="test plate",
        tets10=np.ascontiguousarray(cells[GMSH_TET10_TO_MESHIO]) if order == 2 else None,
    )
