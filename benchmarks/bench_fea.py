"""FEA benchmark: our assembly and solve against scikit-fem's stock path and against SfePy.

Same mesh (the default link meshed once with linear tets, P2 field on straight tets, the only
geometry all three codes share), same clamp (every DOF on the fixed-bore facets), same load (our
bearing-pressure load vector, given to SfePy as nodal forces), aluminium 6061-T6, F = 1 kN.
k = F^2 / (f . u). Paths:
- ours: scalar P2 basis with an exact rule (degree 2), six scalar-block assembly
  (fem.assembly), PARDISO Cholesky (fem.solvers);
- scikit-fem stock: `ElementVector(ElementTetP2())` with its default quadrature (degree 4),
  `skfem.models.elasticity.linear_elasticity`, `condense` + `skfem.solve` (SciPy's default sparse
  direct solver, SuperLU);
- SfePy: `Field` approx_order 2, term `dw_lin_elastic` with an order-2 integral, its EBC
  elimination, and its default linear solver `ls.scipy_direct` (UMFPACK if scikit-umfpack is
  installed, else SciPy's SuperLU); and the same with `ls.pypardiso`, to separate assembly from
  solver choice.
Each path runs in a fresh subprocess (so peak memory is its own; both direct solvers are loaded
and initialised on a tiny system first, as in a long-running process): setup = basis/field and
regions; assembly = the stiffness matrix; solve = constraints + linear solve. Peak memory is the
subprocess's peak resident set from the setup on (VmHWM, reset just before the setup), also given
above the resident set at that point (the work's own footprint, imports, mesh and load excluded).

Time to an accurate k: our `stiffness_to_tolerance` (curved P2, Richardson over refined meshes,
certified by its estimate) against the single straight-P2 mesh each stock code needs for the same
actual accuracy; the actual errors are against a finer Richardson reference (full run only).
"""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

MATERIAL = "al6061-t6"
LOAD_N = 1000.0
AGREEMENT = 1e-8
PATHS = ("ours", "skfem-stock", "sfepy", "sfepy-pardiso")


def _status_MB(field: str) -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return float(line.split()[1]) / 1024.0  # kB
    raise RuntimeError(f"/proc/self/status has no {field}")


def _baseline_MB() -> float:
    """Current resident set, after resetting the peak to it (Linux clear_refs 5).

    getrusage's ru_maxrss is no use here: Linux carries it over fork and exec, so a worker would
    report its parent's peak.
    """
    Path("/proc/self/clear_refs").write_text("5")
    return _status_MB("VmRSS")


def _peak_MB() -> float:
    return _status_MB("VmHWM")


def _prepared(link):
    """Straight-P2 basis, clamped DOFs and load vector (N) exactly as analyse_link builds them."""
    from fem import link as link_module
    from fem import problem

    sk_mesh, index = link_module.skfem_mesh(link, order=2, curved=False)
    basis, fixed, unit, _ = link_module._discretise(link, sk_mesh, index, 2)  # whole link: no mirror DOFs
    resultant = float(link.load_direction @ problem.as_components(unit).sum(axis=1))
    f = unit * (LOAD_N / resultant)
    return sk_mesh, basis, fixed, f, problem.fixed_vector_dofs(basis, fixed)


def _ours(link, lam, mu) -> dict:
    from fem import problem
    from fem.assembly import elasticity_matrix

    sk_mesh, _, _, f, clamped = _prepared(link)
    base = _baseline_MB()
    t0 = time.perf_counter()
    basis = problem.scalar_basis(sk_mesh, 2)
    t1 = time.perf_counter()
    K = elasticity_matrix(basis, lam, mu)
    t2 = time.perf_counter()
    u = problem.solve_displacement(K, f, clamped, problem.dof_locations(basis), solver="pardiso")
    t3 = time.perf_counter()
    return dict(
        k=LOAD_N**2 / float(f @ u), setup=t1 - t0, assembly=t2 - t1, solve=t3 - t2, dofs=K.shape[0], base_MB=base
    )


def _skfem_stock(link, lam, mu) -> dict:
    from skfem import Basis, ElementTetP2, ElementVector, condense, solve
    from skfem.models.elasticity import linear_elasticity

    sk_mesh, _, _, f, clamped = _prepared(link)
    base = _baseline_MB()
    t0 = time.perf_counter()
    basis = Basis(sk_mesh, ElementVector(ElementTetP2()))  # default quadrature
    t1 = time.perf_counter()
    K = linear_elasticity(lam, mu).assemble(basis)
    t2 = time.perf_counter()
    u = solve(*condense(K, f, D=clamped))
    t3 = time.perf_counter()
    return dict(
        k=LOAD_N**2 / float(f @ u), setup=t1 - t0, assembly=t2 - t1, solve=t3 - t2, dofs=K.shape[0], base_MB=base
    )


def _sfepy(link, lam, mu, solver: str) -> dict:
    import logging

    from scipy.spatial import cKDTree
    from sfepy.base.base import output
    from sfepy.discrete import Equation, Equations, FieldVariable, Integral, Integrals, Material, Problem
    from sfepy.discrete.common.region import Region
    from sfepy.discrete.conditions import Conditions, EssentialBC
    from sfepy.discrete.fem import FEDomain, Field, Mesh
    from sfepy.mechanics.matcoefs import stiffness_from_lame
    from sfepy.solvers.ls import PyPardisoSolver, ScipyDirect
    from sfepy.terms import Term

    output.set_output(quiet=True)
    logging.disable(logging.WARNING)
    sk_mesh, basis, fixed, f, clamped = _prepared(link)
    ours_nodes = np.asarray(basis.doflocs).T
    fixed_triangles = sk_mesh.facets[:, fixed]
    points, tets = np.ascontiguousarray(sk_mesh.p.T), np.ascontiguousarray(sk_mesh.t.T.astype(np.int32))
    base = _baseline_MB()
    t0 = time.perf_counter()
    mesh = Mesh.from_data("link", points, None, [tets], [np.zeros(len(tets), np.int32)], ["3_4"])
    domain = FEDomain("domain", mesh)
    omega = domain.create_region("Omega", "all")
    domain.cmesh.setup_connectivity(2, 0)
    facet_vertices = np.sort(domain.cmesh.get_conn(2, 0).indices.reshape(-1, 3), axis=1)
    lookup = {tuple(t): i for i, t in enumerate(facet_vertices)}
    facets = np.array([lookup[tuple(t)] for t in np.sort(fixed_triangles.T, axis=1)])
    clamp = Region.from_facets(facets, domain, "Clamp", kind="facet", parent=omega.name)
    field = Field.from_args("fu", np.float64, "vector", omega, approx_order=2)
    u = FieldVariable("u", "unknown", field)
    v = FieldVariable("v", "test", field, primary_var_name="u")
    material = Material("m", D=stiffness_from_lame(dim=3, lam=lam, mu=mu))
    integral = Integral("i", order=2)  # exact for P2 on straight tets, like ours
    term = Term.new("dw_lin_elastic(m.D, v, u)", integral, omega, m=material, v=v, u=u)
    pb = Problem("link", equations=Equations([Equation("balance", term)]), active_only=True)
    pb.set_bcs(ebcs=Conditions([EssentialBC("clamp", clamp, {"u.all": 0.0})]))
    pb.time_update()
    t1 = time.perf_counter()
    K = pb.evaluate(
        "dw_lin_elastic.i.Omega(m.D, v, u)",
        integrals=Integrals([integral]),
        mode="weak",
        dw_mode="matrix",
        m=material,
        v=v,
        u=u,
        copy_materials=False,
    )
    t2 = time.perf_counter()
    # Our load vector as nodal forces on SfePy's DOFs (matched by node position), then its solver.
    distance, ours_of_sfepy = cKDTree(ours_nodes).query(field.get_coor())
    if distance.max() > 1e-9 * np.ptp(points, axis=0).max():
        raise RuntimeError("SfePy's P2 nodes do not coincide with scikit-fem's")
    f_sfepy = f.reshape(-1, 3)[ours_of_sfepy].ravel()
    eq = pb.get_variables()["u"].eq_map.eq
    active = eq >= 0
    rhs = np.zeros(K.shape[0])
    rhs[eq[active]] = f_sfepy[active]
    linear_solver = PyPardisoSolver({}) if solver == "pardiso" else ScipyDirect({})
    x = linear_solver(rhs, mtx=K)
    t3 = time.perf_counter()
    if not np.array_equal(np.sort(ours_of_sfepy[np.unique(np.flatnonzero(~active) // 3)]), np.unique(clamped // 3)):
        raise RuntimeError("SfePy's clamped nodes differ from ours")
    return dict(
        k=LOAD_N**2 / float(rhs @ x),
        setup=t1 - t0,
        assembly=t2 - t1,
        solve=t3 - t2,
        dofs=len(eq),
        base_MB=base,
        solver=linear_solver.name,
    )


def _warm_up() -> None:
    """Load and initialise both sparse direct solvers on a tiny system, so no path pays for that."""
    import pypardiso
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    A = sp.csr_matrix(sp.diags([4.0] * 8) + sp.eye(8, k=1) + sp.eye(8, k=-1))
    pypardiso.PyPardisoSolver(mtype=2).solve(sp.triu(A, format="csr"), np.ones(8))
    spsolve(A.tocsc(), np.ones(8))


def worker(path: str, mesh_file: str) -> dict:
    import fem

    _warm_up()

    with open(mesh_file, "rb") as fh:
        link = pickle.load(fh)
    lam, mu = fem.get_material(MATERIAL).lame_Pa
    runner = {
        "ours": lambda: _ours(link, lam, mu),
        "skfem-stock": lambda: _skfem_stock(link, lam, mu),
        "sfepy": lambda: _sfepy(link, lam, mu, "default"),
        "sfepy-pardiso": lambda: _sfepy(link, lam, mu, "pardiso"),
    }[path]
    result = runner()
    result["peak_MB"] = _peak_MB()
    return result


def run_worker(path: str, mesh_file: Path) -> dict:
    done = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--worker", path, str(mesh_file)],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    if done.returncode != 0:
        raise RuntimeError(f"{path} worker failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _sfepy_version() -> str | None:
    try:
        import sfepy
    except ImportError:
        return None
    return sfepy.__version__


def compare_on_mesh(mesh_size_m: float, tmp: Path) -> tuple[list[str], dict]:
    import skfem

    import geometry

    start = time.perf_counter()
    link = geometry.load_link(None, mesh_size_m=mesh_size_m, order=1, bore_refinement=0.7)
    mesh_s = time.perf_counter() - start
    mesh_file = tmp / f"link_{mesh_size_m * 1e3:.3g}mm.pickle"
    with open(mesh_file, "wb") as fh:
        pickle.dump(link, fh)
    paths = [p for p in PATHS if _sfepy_version() is not None or not p.startswith("sfepy")]
    results = {p: run_worker(p, mesh_file) for p in paths}
    ours = results["ours"]
    lines = [
        f"same mesh: default link, h = {mesh_size_m * 1e3:.3g} mm, {link.tets.shape[1]} tets, {ours['dofs']} DOFs (P2, straight), "
        f"meshed in {mesh_s:.2f} s; scikit-fem {skfem.__version__}, SfePy {_sfepy_version() or 'not installed'}",
        f"{'path':<15} {'k (N/m)':>18} {'rel diff':>9} {'setup s':>8} {'assembly s':>10} {'solve s':>8} {'total s':>8} {'x ours':>7} {'peak MB':>8} {'work MB':>8}",
    ]
    for path, r in results.items():
        total = r["setup"] + r["assembly"] + r["solve"]
        ours_total = ours["setup"] + ours["assembly"] + ours["solve"]
        diff = abs(r["k"] - ours["k"]) / ours["k"]
        lines.append(
            f"{path:<15} {r['k']:>18.10e} {diff:>9.1e} {r['setup']:>8.2f} {r['assembly']:>10.2f} {r['solve']:>8.2f} "
            f"{total:>8.2f} {total / ours_total:>7.1f} {r['peak_MB']:>8.0f} {r['peak_MB'] - r['base_MB']:>8.0f}"
        )
        if diff > AGREEMENT:  # the benchmark is only meaningful if all paths solve the same problem
            raise RuntimeError(
                f"{path}: k = {r['k']:.10e} differs from ours ({ours['k']:.10e}) by {diff:.1e} > {AGREEMENT:g}"
            )
    for path in results:
        if path != "ours":
            r = results[path]
            lines.append(
                f"{path} / ours: assembly {r['assembly'] / ours['assembly']:.1f}x, solve {r['solve'] / ours['solve']:.1f}x"
                + (f" ({r['solver']})" if "solver" in r else "")
            )
    return lines, {"link": link, "mesh_s": mesh_s, "results": results}


def time_to_accuracy(tolerance: float, tmp: Path, with_reference: bool) -> list[str]:
    import fem
    import geometry
    from fem.adaptive import stiffness_to_tolerance
    from fem.richardson import extrapolate

    material = fem.get_material(MATERIAL)
    start = time.perf_counter()
    estimate = stiffness_to_tolerance(None, material, tolerance)
    adaptive_s = time.perf_counter() - start
    lines = [
        f"ours, stiffness_to_tolerance({tolerance:g}): k = {estimate.stiffness_N_per_m:.6e} N/m, estimated error "
        f"{estimate.stiffness_rel_error_estimate:.2e}, {len(estimate.levels)} levels up to {estimate.levels[-1][1]} DOFs, "
        f"{adaptive_s:.1f} s wall (meshing, assembly, solves and stress post-processing of every level)"
    ]
    if not with_reference:
        return lines
    levels = []
    for h in (0.0038, 0.00285, 0.0025):
        link = geometry.load_link(None, mesh_size_m=h, order=2, bore_refinement=0.7)
        s = fem.analyse_link(link, material, order=2)
        levels.append((s.dofs, s.stiffness_N_per_m))
    ref = extrapolate([k for _, k in levels], [d for d, _ in levels])
    actual = abs(estimate.stiffness_N_per_m - ref.extrapolated) / ref.extrapolated
    lines.append(
        f"reference k = {ref.extrapolated:.6e} N/m (curved P2 3.8/2.85/2.5 mm, {levels[-1][0]} DOFs finest), "
        f"its estimated error {ref.rel_error_estimate:.1e}; adaptive k's actual error {actual:.2e}"
    )
    # The coarsest straight-P2 mesh of the ladder whose own k is within the tolerance (k agrees
    # across the three codes to 1e-8, so ours finds the mesh for all of them).
    h = 0.012
    while True:
        link = geometry.load_link(None, mesh_size_m=h, order=1, bore_refinement=0.7)
        k = fem.analyse_link(link, material, order=2).stiffness_N_per_m
        error = abs(k - ref.extrapolated) / ref.extrapolated
        if error <= tolerance or h < 0.003:
            break
        h *= 3 / 4
    lines.append(f"single straight-P2 mesh within {tolerance:g}: h = {h * 1e3:.3g} mm, error {error:.2e}")
    compare_lines, data = compare_on_mesh(h, tmp)
    for path, r in data["results"].items():
        total = data["mesh_s"] + r["setup"] + r["assembly"] + r["solve"]
        lines.append(
            f"{path}: time to a {tolerance:g}-accurate k on one mesh (meshing + setup + assembly + solve) {total:.1f} s, "
            f"peak {r['peak_MB']:.0f} MB ({r['peak_MB'] - r['base_MB']:.0f} MB for the work)"
        )
    return lines + compare_lines


def run(quick: bool) -> list[str]:
    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        compare_lines, _ = compare_on_mesh(0.012 if quick else 0.0065, Path(tmp))
        lines += compare_lines
        if _sfepy_version() is None:
            lines.append("SfePy not installed (pip install 'link-conveyor[bench]'): its rows are missing")
        lines += time_to_accuracy(0.05 if quick else 0.01, Path(tmp), with_reference=not quick)
    return lines


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--worker":
        print(json.dumps(worker(sys.argv[2], sys.argv[3])))
    else:
        print("\n".join(run("--quick" in sys.argv)))
