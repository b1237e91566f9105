"""Volumetric locking: linear tetrahedra are far too stiff for nearly incompressible materials.

As nu -> 0.5 the bulk modulus grows without bound and the displacement must become nearly
divergence-free. P1 has one such constraint per tet and a tet mesh has 5-6 tets per vertex, more
than the 3 unknowns per vertex, so P1 "locks": the computed displacement is too small and the
error barely falls under refinement. P2 has enough such fields and keeps converging, though its
constant grows as nu -> 0.5 (measured on a thick cylinder with a known answer, see
tests/test_fea_failure_locking.py: at nu = 0.4999 P1 is 27 % too stiff at every mesh tried, curved
P2 converges from 3.6 % to 0.3 % when the mesh is halved).
"""

from __future__ import annotations

from .materials import Material

# lambda / mu = 2 nu / (1 - 2 nu) is 9 at nu = 0.45: the cylinder's P1 error is then over twice its
# value at nu = 0.3 on the same mesh (4.0 % vs 1.7 %) and grows fast beyond (11 % at 0.49).
P1_LOCKING_POISSON_RATIO = 0.45
# At nu = 0.499 curved P2 on the cylinder's coarse mesh was 0.6 % off (vs 0.02 % at nu = 0.3):
# still converging fast, but a mesh chosen for a compressible material may not be fine enough.
P2_LOCKING_POISSON_RATIO = 0.499


def locking_warning(material: Material, order: int) -> str | None:
    """One-line warning when `material` is nearly incompressible for elements of `order`, else None."""
    nu = material.poisson_ratio
    if order == 1 and nu >= P1_LOCKING_POISSON_RATIO:
        return (
            f"material {material.name!r}: Poisson's ratio {nu:g} >= {P1_LOCKING_POISSON_RATIO:g} locks linear (P1) "
            f"tetrahedra: k will be too high; use order 2"
        )
    if order == 2 and nu >= P2_LOCKING_POISSON_RATIO:
        return (
            f"material {material.name!r}: Poisson's ratio {nu:g} >= {P2_LOCKING_POISSON_RATIO:g} is nearly incompressible: "
            f"P2 converges but needs finer meshes; check k with a tolerance (stiffness_to_tolerance)"
        )
    return None
