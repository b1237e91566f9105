"""The unknowns estimated before meshing (geometry.mesh_estimate) against the real count of every
default mesh level: the built-in link and example STEP, and where the wild corpus is found
(benchmarks/wild_corpus.py: ../shared/wild/ beside the checkout or its main checkout, or $LINK_CONVEYOR_WILD) its parts
that run, the two --bores runs with their bores.

    python benchmarks/run.py --only mesh_estimate [--quick]     (--quick: the repository's links only)

Each level is meshed as the stiffness study meshes it (curved P2, the finest on the mirror half
where the part is symmetric) and its P2 unknowns counted.
"""

from __future__ import annotations

import time

import geometry
from benchmarks.wild_corpus import WILD
from fem.budget import mesh_dofs
from fem.cli import build_parser
from fem.settings import DEFAULT_BORE_REFINEMENT
from fem.study import default_mesh_sizes
from geometry.mesh_estimate import estimated_dofs
from geometry.options import link_source

CORPUS = [
    ("gripper_connector_2holes_inventor.stp", []),
    ("gripper_connector_3holes_inventor.stp", []),
    ("arm_bar_400mm_inventor.stp", []),
    ("robot_arm_link_pockets_inventor.stp", []),
    ("arm_bar_slots_inventor.stp", ["--bores=30,30,-30:20,370,-30"]),
    ("quadruped_upper_leg_onshape.step", ["--bores=-103.32,2.2,-25:4.95,-15.05,-3.55"]),
]


def _parts(quick: bool):
    yield "built-in link", geometry.resolve_part(None)
    yield "example STEP", geometry.resolve_part(geometry.EXAMPLE_STEP)
    if quick or WILD is None:
        return
    for name, options in CORPUS:
        path = str(WILD / name)
        yield name, geometry.resolve_part(link_source(path, build_parser().parse_args([path, *options])))


def run(quick: bool) -> list[str]:
    lines = ["part | level | size mm | unknowns | estimate | real / estimate | meshing s"]
    for label, part in _parts(quick):
        sizes = default_mesh_sizes(part)
        for level, size in enumerate(sizes):
            half = level == len(sizes) - 1 and part.mirror_plane is not None
            start = time.perf_counter()
            link = geometry.mesh_part(
                part,
                mesh_size_m=size,
                order=2,
                bore_refinement=DEFAULT_BORE_REFINEMENT,
                mirror=half,
            )
            seconds = time.perf_counter() - start
            real = mesh_dofs(link.tets, link.tets10, 2)
            features = part.geometry.mesh_features
            estimate = estimated_dofs(features, size, DEFAULT_BORE_REFINEMENT * size, 2, half)
            which = "finest" + (" (half)" if half else "") if level == len(sizes) - 1 else "coarse"
            lines.append(
                f"{label} | {which} | {size * 1e3:.3g} | {real} | {estimate:.0f} | {real / estimate:.3f} | {seconds:.1f}"
            )
    return lines
