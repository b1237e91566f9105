"""Time the linear solvers on the default link's condensed P2 systems: `python -m fem.bench_solvers`.

Prints one line per (mesh size, solver): DOFs, solve time, and k relative to PARDISO's.
Options: mesh sizes in mm (default 6.5 4.5 3.5), --solvers (default pardiso amg spsolve),
--spsolve-max-dofs (SuperLU is skipped above this size; it needs minutes and >10 GB beyond ~150k).
"""

from __future__ import annotations

import argparse
import time

from geometry import load_link

from . import problem, solvers
from .assembly import elasticity_matrix
from .link import _discretise, skfem_mesh
from .materials import get_material
from .study import DEFAULT_BORE_REFINEMENT


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m fem.bench_solvers", description=__doc__)
    parser.add_argument("sizes_mm", nargs="*", type=float, default=[6.5, 4.5, 3.5])
    parser.add_argument("--solvers", nargs="+", default=list(solvers.SOLVERS))
    parser.add_argument("--spsolve-max-dofs", type=int, default=80_000)
    args = parser.parse_args(argv)
    lam, mu = get_material("al6061-t6").lame_Pa
    for size_mm in args.sizes_mm:
        link = load_link(None, mesh_size_m=size_mm * 1e-3, order=2, bore_refinement=DEFAULT_BORE_REFINEMENT)
        mesh, index = skfem_mesh(link, 2)
        basis, fixed, f = _discretise(link, mesh, index, 2)
        start = time.perf_counter()
        K = elasticity_matrix(basis, lam, mu)
        assembly = time.perf_counter() - start
        clamped = problem.fixed_vector_dofs(basis, fixed)
        reference = None
        for name in args.solvers:
            if name == "spsolve" and K.shape[0] > args.spsolve_max_dofs:
                print(f"{size_mm:4.1f} mm {K.shape[0]:7d} DOFs  {name:8s} skipped (> {args.spsolve_max_dofs} DOFs)")
                continue
            start = time.perf_counter()
            u = problem.solve_displacement(K, f, clamped, basis.doflocs, solver=name)
            elapsed = time.perf_counter() - start
            work = float(f @ u)
            reference = work if reference is None else reference
            print(
                f"{size_mm:4.1f} mm {K.shape[0]:7d} DOFs  {name:8s} solve {elapsed:6.2f} s  "
                f"(assembly {assembly:.2f} s)  k / k_first - 1 = {reference / work - 1:+.1e}",
                flush=True,
            )


if __name__ == "__main__":
    main()
