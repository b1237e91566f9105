"""The FEA's process of the whole job in CPU seconds: its stiffness step, then its stress study and
images (issue #24).

    python benchmarks/bench_fea_cpu.py [--repeats 3] [--old-tree DIR]

Runs `stages.fea._fea_steps` on the default run from an empty cache, as `pipeline.py`'s process
beside the chain runs it (stiffness levels concurrent, then the stress study and the two deformed
images), in a fresh process per run, this tree and DIR alternating, and prints the CPU seconds (the
process's, all threads) of the first step (the stiffness, with the process's imports and the part's
measurement), of the stress study (`fem.stress.stress_study`, timed around its call) and of the
rest of the second step (the images), with their medians, each run's k and each tree's last k and
converged stress to the last digit. The whole job keeps both cores busy, so its wall time follows
its CPU time; CPU times are also steadier than wall times on a shared machine.

    python benchmarks/bench_fea_cpu.py --phases [--repeats 3] [--old-tree DIR]

books the stiffness step's and the stress study's CPU to their phases instead ("Where the stiffness
step's CPU goes", docs/performance.md): the same steps with the levels solved one after the other
(`concurrent_levels=False`), so that the process's CPU (PARDISO's threads included) within a
function's call is that function's, each phase timed with `time.process_time()` around the functions
`PHASES` names (patched in the child; a phase a tree does not have is left out). No images. One
level is solved at a time, but the next is meshed beside it in the calling thread, so the coarse
level's CAD and meshing rows also take in some of the finest level's solve (PARDISO's threads).

    python benchmarks/bench_fea_cpu.py --geometry [--repeats 5] [--old-tree DIR]

the stiffness step's geometry alone, as `stages.fea` runs it (the part measured, both levels' CAD
built and meshed; `fem.stiffness_studies` replaced by its meshing, no FEA), in fresh processes:
its CPU seconds, and a hash of the meshes (every level's nodes and P2 cells) that shows whether
both trees mesh alike.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STEPS = ("stiffness", "stress study", "images (the rest of the second step)")

# Per step: (depth in its table, phase, the functions timed as it: "module:qualified.name"), in the
# order they run; a row's CPU is within its parent's (the nearest row above it one level up), and
# "the rest" of a step is its CPU outside its depth-0 rows.
PHASES = {
    "stiffness": (
        # each under its module of this tree and of trees before geometry.measure (then geometry.part's)
        (
            0,
            "the part's CAD built and measured (its mirror half kept)",
            ["geometry.measure:measure", "geometry.part:_measure"],
        ),
        (1, "the thin-wall search", ["geometry.measure:thin_walls", "geometry.part:thin_walls"]),
        (
            1,
            "the symmetry check and the cut",
            [
                "geometry.measure:symmetry_plane",
                "geometry.measure:keep_positive_half",
                "geometry.part:symmetry_plane",
                "geometry.part:keep_positive_half",
            ],
        ),
        (0, "the CAD built again (the coarse level)", ["geometry.part:Part.load_body"]),
        (0, "the solid cut at the loaded bore", ["geometry.load:split_at_loaded_half"]),
        (0, "meshing (geometry.meshing.mesh_volumes)", ["geometry.load:mesh_volumes"]),
        (1, "gmsh's 3D mesh (generate(3))", ["gmsh:model.mesh.generate"]),
        (1, "gmsh's setOrder(2)", ["gmsh:model.mesh.setOrder"]),
        (
            1,
            "the small-hole and thin-wall searches",
            ["geometry.meshing:small_hole_fields", "geometry.meshing:thin_wall_fields"],
        ),
        (1, "the bore and mirror faces", ["geometry.meshing:faces_on_bore", "geometry.meshing:faces_on_plane"]),
        (
            1,
            "the flat-tet check, the mesh arrays",
            ["geometry.meshing:_has_flat_tets", "geometry.meshing:_mesh_arrays"],
        ),
        (
            0,
            "the mesh checks (quality, thin walls)",
            ["fem.study:check_mesh_and_materials", "fem.quality:thin_wall_warning"],
        ),
        (0, "the levels' FEA (fem.link.analyse_link_materials)", ["fem.study:analyse_link_materials"]),
        (1, "scikit-fem's curved mesh and its straightening", ["fem.link:skfem_mesh"]),
        (1, "basis, bore facets and the bearing load", ["fem.link:_discretise_curved", "fem.link:_discretise"]),
        (2, "of it the basis", ["fem.problem:scalar_basis"]),
        (2, "of it the bearing load", ["fem.problem:traction_load"]),
        (1, "assembly of the material-free parts", ["fem.link:elasticity_parts"]),
        (1, "their restriction to the free DOFs", ["fem.assembly:ElasticityParts.restricted"]),
        (1, "a material's matrix", ["fem.assembly:ElasticityParts.matrix"]),
        (1, "PARDISO's analysis and factorisation", ["fem.solvers:Factorization.__init__"]),
        (1, "titanium's CG on that factor", ["fem.solvers:preconditioned_cg"]),
        (1, "PARDISO's back-substitutions (aluminium's and the CG's)", ["fem.solvers:Factorization.solve"]),
        (1, "the stress points (finest level)", ["fem.link:_StressPoints.__init__"]),
        (1, "k and the stresses", ["fem.link:_solution"]),
    ),
    "stress study": (
        (0, "the global's hot spots", ["fem.stress:well_shaped_hot_spots"]),
        (
            0,
            "the CAD loaded and cut (half, loaded bore)",
            [
                "geometry.part:Part.load_body",
                "geometry.ball_mesh:keep_positive_half",
                "geometry.ball_mesh:split_at_loaded_half",
            ],
        ),
        (0, "the balls cut out of it", ["gmsh:model.occ.intersect", "gmsh:model.occ.fuse"]),
        (
            0,
            "the balls' faces told apart",
            ["geometry.ball_mesh:faces_on_bore", "geometry.ball_mesh:faces_on_plane", "geometry.ball_mesh:_on_sphere"],
        ),
        (0, "the sub-model levels meshed", ["geometry.ball_mesh:BallMesher.mesh"]),
        (1, "gmsh's 3D mesh (generate(3))", ["gmsh:model.mesh.generate"]),
        (1, "gmsh's setOrder(2)", ["gmsh:model.mesh.setOrder"]),
        (0, "the sub-model levels solved", ["fem.stress:solve_submodel"]),
        (1, "scikit-fem's mesh and its straightening", ["fem.submodel:skfem_ball_mesh"]),
        (1, "the basis", ["fem.problem:scalar_basis"]),
        (1, "assembly of the material-free parts", ["fem.submodel:elasticity_parts"]),
        (
            1,
            "the global's displacements on the cut",
            ["fem.submodel:GlobalField.interpolation", "fem.submodel:GlobalField.displacement_m"],
        ),
        (1, "the bearing load", ["fem.problem:traction_load"]),
        (1, "the trusted points", ["fem.submodel:_TrustedPoints.__init__"]),
        (1, "PARDISO's analysis and factorisation", ["fem.solvers:Factorization.__init__"]),
        (1, "titanium's CG", ["fem.solvers:preconditioned_cg"]),
        (1, "the stresses", ["fem.submodel:_TrustedPoints.solution"]),
        (0, "the quality near the peak", ["fem.stress:_quality_near"]),
    ),
}

CHILD = """
import dataclasses, json, shutil, tempfile, time
from pathlib import Path
start = time.process_time()
from fem import load_materials
from settings import RunConfig
from stages import fea
from stages.geometry import inspect_geometry
from stages.progress import Progress
import fem.stress
stress_study, stress_cpu = fem.stress.stress_study, []
def timed_stress_study(*args, **kwargs):  # _fea_steps imports it from fem.stress when it runs
    begin = time.process_time()
    try:
        return stress_study(*args, **kwargs)
    finally:
        stress_cpu.append(time.process_time() - begin)
fem.stress.stress_study = timed_stress_study
tmp = tempfile.mkdtemp(prefix="bench-fea-cpu-")
cfg = dataclasses.replace(RunConfig(), cache_dir=Path(tmp) / "cache", out=Path(tmp) / "out")
quiet = Progress(True)
cfg, part = inspect_geometry(cfg, quiet)
library = load_materials(cfg.materials_file)
images = {m: Path(tmp) / f"{m}.png" for m in cfg.materials}
steps = fea._fea_steps(part, fea.fea_settings(cfg), [library[m] for m in cfg.materials], None, None, images,
                       quiet, cfg.max_fea_dofs)
stiffness, _ = next(steps)
after_stiffness = time.process_time()
stresses, _ = next(steps)
end = time.process_time()
shutil.rmtree(tmp, ignore_errors=True)
print(json.dumps({
    "cpu_s": [after_stiffness - start, sum(stress_cpu), end - after_stiffness - sum(stress_cpu)],
    "k": {m: r["stiffness_N_per_m"] for m, r in stiffness.items()},
    "stress": {m: s.peak_Pa_per_N for m, s in stresses.items()},
}))
"""

PHASES_CHILD = """
import dataclasses, importlib, json, shutil, sys, tempfile, threading, time
from collections import defaultdict
from pathlib import Path
import gmsh
import fem.link, fem.problem, fem.solvers, fem.stress, fem.study, fem.submodel
import geometry.ball_mesh, geometry.load, geometry.meshing, geometry.part
from fem import load_materials
from settings import RunConfig
from stages import fea
from stages.geometry import inspect_geometry
from stages.progress import Progress
fem.solvers.resolve("auto")  # pypardiso and MKL, as the first solve loads them
imports = time.process_time()
PHASES = json.loads(sys.argv[1])
cpu = {name: defaultdict(float) for name in PHASES}
step = ["stiffness"]
active = threading.local()

def timed(step_name, depth, label, function):
    key = f"{step_name}: {label}"
    def wrapper(*args, **kwargs):
        # another step's phase, a call inside one of this phase, or a depth-0 phase inside another
        # (keep_positive_half's intersect inside the CAD's load): in the phase that called it
        if step[0] != step_name or getattr(active, key, False) or (depth == 0 and getattr(active, "top", False)):
            return function(*args, **kwargs)
        setattr(active, key, True)
        if depth == 0:
            active.top = True
        begin = time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            setattr(active, key, False)
            if depth == 0:
                active.top = False
            cpu[step_name][label] += time.process_time() - begin
    return wrapper

for step_name, phases in PHASES.items():
    for depth, label, targets in phases:
        for target in targets:
            module_name, _, qualname = target.partition(":")
            *path, name = qualname.split(".")
            try:
                owner = importlib.import_module(module_name)
            except ModuleNotFoundError:  # a module this tree does not have
                continue
            for attribute in path:
                owner = getattr(owner, attribute, None)
            if owner is not None and hasattr(owner, name):  # a phase this tree does not have is left out
                setattr(owner, name, timed(step_name, depth, label, getattr(owner, name)))

tmp = tempfile.mkdtemp(prefix="bench-fea-phases-")
cfg = dataclasses.replace(RunConfig(), cache_dir=Path(tmp) / "cache", out=Path(tmp) / "out")
quiet = Progress(True)
cfg, part = inspect_geometry(cfg, quiet)
library = load_materials(cfg.materials_file)
images = {m: None for m in cfg.materials}  # no images: the phases are the stiffness step's and the stress study's
steps = fea._fea_steps(part, fea.fea_settings(cfg, concurrent_levels=False), [library[m] for m in cfg.materials],
                       None, None, images, quiet, cfg.max_fea_dofs)
stiffness, _ = next(steps)
cpu["stiffness"]["the step"] = time.process_time()  # from the process's start, its imports included
cpu["stiffness"]["interpreter and imports"] = imports
step[0] = "stress study"
begin = time.process_time()
next(steps)
cpu["stress study"]["the step"] = time.process_time() - begin
shutil.rmtree(tmp, ignore_errors=True)
print(json.dumps({"cpu_s": cpu, "k": {m: r["stiffness_N_per_m"] for m, r in stiffness.items()}}))
"""


GEOMETRY_CHILD = """
import hashlib, importlib, importlib.util, json, time
import fem, geometry
for name in ("geometry.load", "geometry.measure"):  # imported before the clock, as stages.fea.FEA_MODULES has them
    if importlib.util.find_spec(name) is not None:  # geometry.measure: trees since it was split from geometry.part
        importlib.import_module(name)
from fem import study
from fem.settings import FeaSettings
from stages.fea import _solve_stiffness
meshes = hashlib.sha256()
def mesh_level_before(part, settings, sizes, level, wall_reference_m):  # trees without study.mesh_planned_level
    return geometry.mesh_part(part, mesh_size_m=sizes[level], order=settings.mesh_order,
                              bore_refinement=settings.bore_refinement, mirror=level == len(sizes) - 1,
                              wall_reference_m=wall_reference_m)
mesh_level = getattr(study, "mesh_planned_level", mesh_level_before)
def meshing_only(part, materials, settings, progress=None):  # fem.stiffness_studies' meshing, finest first
    sizes, wall_reference_m = study.planned_mesh_sizes(part, settings)
    for level in reversed(range(len(sizes))):
        mesh = mesh_level(part, settings, sizes, level, wall_reference_m)
        meshes.update(mesh.points_m.tobytes() + mesh.tets10.tobytes())
    return {}
fem.stiffness_studies = meshing_only  # _solve_stiffness imports it when it runs
part = geometry.resolve_part(None)
begin = time.process_time()
_solve_stiffness(part, FeaSettings(), [], None, lambda line: None, None, 10**6)
print(json.dumps({"cpu_s": time.process_time() - begin, "meshes": meshes.hexdigest()[:16]}))
"""


def run_once(tree: Path, phases: bool = False, geometry: bool = False) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    command = ["-c", PHASES_CHILD, json.dumps(PHASES)] if phases else ["-c", CHILD]
    command = ["-c", GEOMETRY_CHILD] if geometry else command
    done = subprocess.run([sys.executable, *command], cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{tree}: the FEA steps failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old-tree", type=Path, default=None, help="another checkout, run alternately")
    parser.add_argument("--phases", action="store_true", help="each step's CPU booked to its phases, levels in turn")
    parser.add_argument("--geometry", action="store_true", help="the stiffness step's geometry alone (no FEA)")
    args = parser.parse_args(argv)
    trees = {"new": ROOT} | ({"old": args.old_tree.resolve()} if args.old_tree else {})
    runs: dict[str, list[dict]] = {name: [] for name in trees}
    if args.geometry:
        return print_geometry(trees, args.repeats)
    for repeat in range(args.repeats):
        for name, tree in trees.items():
            runs[name].append(run_once(tree, args.phases))
            cpu = runs[name][-1]["cpu_s"]
            steps = [cpu[s]["the step"] for s in PHASES] if args.phases else cpu
            k = ", ".join(f"{m} {v!r}" for m, v in runs[name][-1]["k"].items())
            print(f"run {repeat + 1} {name}: CPU s {', '.join(f'{c:.2f}' for c in steps)}; k (N/m) {k}", flush=True)
    print(f"medians of {args.repeats} runs, trees alternating; load average now {os.getloadavg()[0]:.1f}")
    if args.phases:
        print_phases(runs)
        return 0
    print("| step | " + " | ".join(f"{name}: CPU s (runs)" for name in trees) + " |")
    print("|---|" + "---|" * len(trees))
    for i, step in enumerate(STEPS):
        print(f"| {step} | " + " | ".join(_cell([r["cpu_s"][i] for r in runs[name]]) for name in trees) + " |")
    for name in trees:
        last = runs[name][-1]
        answers = ", ".join(f"{m} k {last['k'][m]!r} N/m, stress {last['stress'][m]!r} Pa/N" for m in last["k"])
        print(f"{name}: {answers}")
    return 0


def print_geometry(trees: dict[str, Path], repeats: int) -> int:
    """`--geometry`: each run's CPU seconds and meshes' hash, then the medians."""
    runs: dict[str, list[dict]] = {name: [] for name in trees}
    for repeat in range(repeats):
        for name, tree in trees.items():
            runs[name].append(run_once(tree, geometry=True))
            print(f"run {repeat + 1} {name}: CPU s {runs[name][-1]['cpu_s']:.2f}, meshes {runs[name][-1]['meshes']}")
    print(f"medians of {repeats} runs, trees alternating; load average now {os.getloadavg()[0]:.1f}")
    for name, tree_runs in runs.items():
        hashes = sorted({r["meshes"] for r in tree_runs})
        print(f"{name}: the stiffness step's geometry {_cell([r['cpu_s'] for r in tree_runs])} CPU s, meshes {hashes}")
    return 0


def print_phases(runs: dict[str, list[dict]]) -> None:
    """One table per step: each phase's CPU, the rest of the step and the step, medians (runs)."""
    for step, phases in PHASES.items():
        rows = [(0, "interpreter and imports")] if step == "stiffness" else []
        rows += [(depth, label) for depth, label, _ in phases] + [(0, "the rest"), (0, "the step")]
        print(f"\n{step} (levels one after the other)")
        print("| phase | " + " | ".join(f"{name}: CPU s (runs)" for name in runs) + " |")
        print("|---|" + "---|" * len(runs))
        for depth, label in rows:
            cells = []
            for tree_runs in runs.values():
                values = [_phase_cpu(r["cpu_s"][step], label, rows) for r in tree_runs]
                cells.append(_cell(values))
            print(f"| {'- ' * depth}{label} | " + " | ".join(cells) + " |")


def _phase_cpu(cpu: dict[str, float], label: str, rows: list[tuple[int, str]]) -> float:
    if label == "the rest":
        return cpu["the step"] - sum(
            cpu.get(name, 0.0) for depth, name in rows if depth == 0 and name not in ("the rest", "the step")
        )
    return cpu.get(label, 0.0)


def _cell(values: list[float]) -> str:
    return f"{statistics.median(values):.2f} ({', '.join(f'{v:.2f}' for v in values)})"


if __name__ == "__main__":
    raise SystemExit(main())
