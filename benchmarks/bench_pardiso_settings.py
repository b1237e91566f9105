"""MKL PARDISO with its own defaults against the project's settings (`fem.solvers.PARDISO_IPARM`)
on the default link's condensed P2 system at 4.5 mm (the finest default level):
`python benchmarks/run.py --only pardiso_settings`.

Each phase is timed apart (analysis = ordering and symbolic factorisation, numeric factorisation,
one back-substitution), the two settings alternate, and the median of the repeats is printed with
the relative residual of the solve.
"""

from __future__ import annotations

import statistics
import time

import numpy as np
import scipy.sparse as sp

from fem import problem, solvers
from fem.assembly import elasticity_matrix
from fem.link import _discretise, skfem_mesh
from fem.materials import get_material
from fem.settings import DEFAULT_BORE_REFINEMENT
from geometry import load_link

SETTINGS = {"MKL defaults": {}, "PARDISO_IPARM": solvers.PARDISO_IPARM}


def _condensed_system(size_mm: float) -> tuple[sp.csr_matrix, np.ndarray]:
    link = load_link(None, mesh_size_m=size_mm * 1e-3, order=2, bore_refinement=DEFAULT_BORE_REFINEMENT)
    mesh, index = skfem_mesh(link, 2)
    basis, fixed, f, _ = _discretise(link, mesh, index, 2)  # a whole link: no mirror-plane DOFs
    K = elasticity_matrix(basis, *get_material("al6061-t6").lame_Pa)
    free = np.setdiff1d(np.arange(K.shape[0]), problem.fixed_vector_dofs(basis, fixed))
    return K[free][:, free].tocsr(), f[free]


def _phases(K: sp.csr_matrix, upper: sp.csr_matrix, b: np.ndarray, iparm: dict) -> dict[str, float]:
    import pypardiso

    solver = pypardiso.PyPardisoSolver(mtype=2)
    for one_based, value in iparm.items():
        solver.set_iparm(one_based, value)
    times = {}
    x = None
    for name, phase in (("analysis", 11), ("factorisation", 22), ("solve", 33)):
        solver.set_phase(phase)
        start = time.perf_counter()
        x = solver._call_pardiso(upper, b)
        times[name] = time.perf_counter() - start
    solver.free_memory(everything=True)
    times["residual"] = float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))
    return times


def run(quick: bool) -> list[str]:
    solvers._point_pypardiso_at_mkl()
    K, b = _condensed_system(4.5)
    upper = sp.triu(K, format="csr")
    upper.sort_indices()
    runs: dict[str, list[dict]] = {name: [] for name in SETTINGS}
    for _ in range(2 if quick else 5):
        for name, iparm in SETTINGS.items():
            runs[name].append(_phases(K, upper, b, iparm))
    lines = [
        f"default link, 4.5 mm, {K.shape[0]} DOFs; medians of {len(runs['MKL defaults'])} alternating runs",
        "| settings | analysis (s) | factorisation (s) | one solve (s) | relative residual |",
        "|---|---|---|---|---|",
    ]
    for name, rows in runs.items():
        median = {key: statistics.median(r[key] for r in rows) for key in rows[0]}
        lines.append(
            f"| {name} | {median['analysis']:.3f} | {median['factorisation']:.3f} | {median['solve']:.3f} | "
            f"{median['residual']:.1e} |"
        )
    return lines


if __name__ == "__main__":
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    print("\n".join(run(quick="--quick" in sys.argv)))
