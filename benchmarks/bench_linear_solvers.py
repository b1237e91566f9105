"""Time the linear solvers on the default link's condensed P2 systems (the measurement behind
`solver="auto"`): `python benchmarks/run.py --only linear_solvers`, or directly
`python benchmarks/bench_linear_solvers.py [SIZES_MM ...] [--solvers ...] [--spsolve-max-dofs N]`.

One line per (mesh size, solver): DOFs, solve time, and k relative to the first solver's.
SuperLU is skipped above --spsolve-max-dofs (it needs minutes and > 10 GB beyond ~150k DOFs).
"""

from __future__ import annotations

import argparse
import time

from fem import problem, solvers
from fem.assembly import elasticity_matrix
from fem.link import _discretise, skfem_mesh
from fem.materials import get_material
from fem.settings import DEFAULT_BORE_REFINEMENT
from geometry import load_link


def run(quick: bool) -> list[str]:
    """The benchmark runner's entry: 6.5 and 4.5 mm quick, up to 3.5 mm in full."""
    return measure([6.5] if quick else [6.5, 4.5, 3.5], list(solvers.SOLVERS), 80_000)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench_linear_solvers.py", description=__doc__)
    parser.add_argument("sizes_mm", nargs="*", type=float, default=[6.5, 4.5, 3.5])
    parser.add_argument("--solvers", nargs="+", default=list(solvers.SOLVERS))
    parser.add_argument("--spsolve-max-dofs", type=int, default=80_000)
    args = parser.parse_args(argv)
    for line in measure(args.sizes_mm, args.solvers, args.spsolve_max_dofs):
        print(line, flush=True)


def measure(sizes_mm: list[float], solver_names: list[str], spsolve_max_dofs: int) -> list[str]:
    lines = []
    lam, mu = get_material("al6061-t6").lame_Pa
    for size_mm in sizes_mm:
        link = load_link(None, mesh_size_m=size_mm * 1e-3, order=2, bore_refinement=DEFAULT_BORE_REFINEMENT)
        mesh, index = skfem_mesh(link, 2)
        basis, fixed, f, _ = _discretise(link, mesh, index, 2)  # a whole link: no mirror-plane DOFs
        start = time.perf_counter()
        K = elasticity_matrix(basis, lam, mu)
        assembly = time.perf_counter() - start
        clamped = problem.fixed_vector_dofs(basis, fixed)
        reference = None
        for name in solver_names:
            if name == "spsolve" and K.shape[0] > spsolve_max_dofs:
                lines.append(f"{size_mm:4.1f} mm {K.shape[0]:7d} DOFs  {name:8s} skipped (> {spsolve_max_dofs} DOFs)")
                continue
            start = time.perf_counter()
            u = problem.solve_displacement(K, f, clamped, basis.doflocs, solver=name)
            elapsed = time.perf_counter() - start
            work = float(f @ u)
            reference = work if reference is None else reference
            lines.append(
                f"{size_mm:4.1f} mm {K.shape[0]:7d} DOFs  {name:8s} solve {elapsed:6.2f} s  "
                f"(assembly {assembly:.2f} s)  k / k_first - 1 = {reference / work - 1:+.1e}"
            )
    return lines


if __name__ == "__main__":
    main()
