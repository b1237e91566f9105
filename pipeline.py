"""link-conveyor: from one link's CAD file to the vibration of the whole cam-indexed chain.

    python pipeline.py [--geometry LINK.step] [--materials al6061-t6,ti-grade2] [--links 85] ...

Stages: geometry (gmsh) -> FEA per material (scikit-fem: stiffness, mass, stress per newton) ->
chain dynamics per material x cam law -> summary.json, tables, plots, report.html in --out.
Everything inside is SI; tables and plots for people show mm where that reads better.

This script only maps flags onto `settings.RunConfig` fields: the defaults, the allowed values and
the checks live in the settings package.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from settings import RunConfig, SettingsError, cam_ids, check_run_config, extra_cam_ids, m_to_mm, mm_to_m, registries
from stages.progress import Progress, timed

if TYPE_CHECKING:
    from stages.beside import Beside


def build_parser() -> argparse.ArgumentParser:
    from geometry.options import add_part_arguments

    d = RunConfig()
    p = argparse.ArgumentParser(
        prog="pipeline.py",
        description=(
            "Mesh a chain link, solve its axial stiffness and mass per material with linear "
            "elasticity, and simulate the closed chain driven by a cam indexer. Units: SI inside "
            "and in summary.json (m, kg, s, N, Pa); options state their units."
        ),
    )
    p.add_argument(
        "--geometry",
        type=Path,
        default=d.geometry,
        help="STEP file of one link with two pin bores (other holes and hardware solids allowed: see the part options), "
        "any length unit the file declares (default: the built-in parametric link)",
    )
    add_part_arguments(p)
    p.add_argument(
        "--materials",
        default=",".join(d.materials),
        help="comma-separated material ids (default: %(default)s); see fem/data/materials.toml or --materials-file",
    )
    p.add_argument(
        "--materials-file",
        type=Path,
        default=d.materials_file,
        help="TOML file of extra user-defined materials (E in Pa, density in kg/m^3, yield in Pa)",
    )
    p.add_argument(
        "--links", type=int, default=d.links, help="number of links N in the closed chain (default: %(default)s)"
    )
    p.add_argument("--rpm", type=float, default=d.rpm, help="cam speed in rev/min (default: %(default)s)")
    p.add_argument(
        "--cams",
        default="all",
        help=f"comma-separated cam laws or 'all' (default): {', '.join(cam_ids())}; also {', '.join(extra_cam_ids())}",
    )
    p.add_argument(
        "--friction",
        type=float,
        default=d.friction,
        help="Coulomb friction coefficient mu between links and guide, force mu*m*g per link (default: %(default)s)",
    )
    p.add_argument(
        "--damping",
        type=float,
        default=d.damping,
        help="modal damping ratio zeta of every chain mode (default: %(default)s, the sponsor's figure)",
    )
    p.add_argument(
        "--preload",
        type=float,
        default=d.preload_N,
        help="static chain tension from the idler tensioner in N (default: %(default)s)",
    )
    p.add_argument(
        "--solver",
        default=d.solver,
        help="dynamics method (default: %(default)s, exact for the linear model); see docs/performance.md, Dynamics: solvers",
    )
    p.add_argument(
        "--preset",
        choices=registries.PRESETS,
        default=d.preset,
        help="mqp2012: replicate the 2012 report's MATLAB model, quirks included (see docs/user-guide.md, The report replica)",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=d.out,
        help="output folder (default: %(default)s); existing files of the same name are replaced only when the run succeeds",
    )
    p.add_argument("--no-images", action="store_true", help="skip the pyvista images of the deformed link")
    p.add_argument(
        "--serial",
        action="store_true",
        help="run everything in this process: the FEA's stress study and images before the dynamics, a long "
        "chain's scenarios one after the other (default: the FEA in a second process beside the dynamics and "
        "the figures, a long chain's scenarios in one worker process per core; the same results, more "
        "memory at once)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.add_argument(
        "--mesh-size",
        type=float,
        default=None,
        help="FEA element size in mm on the finest of 2 mesh levels (default: relative to the part, for < 1%% error in k)",
    )
    p.add_argument(
        "--max-memory",
        type=float,
        default=d.max_memory_gb,
        metavar="GB",
        help="memory budget of the FEA solves in GB, checked before solving: default sizes are coarsened to "
        "fit it, a --mesh-size that does not fit is refused (default: %(default)s)",
    )
    p.add_argument(
        "--max-fea-dofs",
        type=int,
        default=d.max_fea_dofs,
        metavar="DOFS",
        help="with --tolerance: the largest FEA level the k refinement may solve; beyond it the run reports "
        "its best k and says the tolerance was not met (default: %(default)s)",
    )
    p.add_argument(
        "--order",
        type=int,
        choices=registries.ELEMENT_ORDERS,
        default=d.order,
        help="FEA element order: 1 or 2 (P1/P2 tetrahedra; default: %(default)s)",
    )
    p.add_argument(
        "--hardware-mass",
        type=float,
        default=d.hardware_mass_kg,
        help="mass per link of pins, bushings and rollers in kg (default: %(default).4g)",
    )
    p.add_argument(
        "--hardware-from-step",
        action="store_true",
        help="take the hardware mass from the STEP file's other solids (with --hardware-material) instead of --hardware-mass",
    )
    p.add_argument(
        "--nest-mass",
        type=float,
        default=d.nest_mass_kg,
        help="mass of the nest carried by each link in kg (default: %(default)s)",
    )
    p.add_argument("--cache-dir", type=Path, default=d.cache_dir, help="FEA result cache folder (default: %(default)s)")
    p.add_argument(
        "--from-rest",
        action="store_true",
        help="start the chain from rest at t=0 instead of the periodic steady state of continuous indexing",
    )
    p.add_argument(
        "--samples-per-degree",
        type=int,
        default=d.samples_per_degree,
        help="output samples per degree of cam rotation (default: %(default)s)",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=d.tolerance,
        help="relative tolerance on the reported metrics (e.g. 0.01): picks the FEA mesh and the "
        "time step for it and reports the achieved error estimate (default: fixed settings)",
    )
    p.add_argument(
        "--rpm-sweep",
        metavar="FROM:TO:STEP",
        default=d.rpm_sweep,
        help="also sweep the cam speed (rev/min): residual vibration and peak acceleration at the "
        "tight-side station (or --station) per cam law, critical speeds marked (linear model, "
        "friction left out)",
    )
    p.add_argument(
        "--station",
        choices=registries.station_names(),
        default=d.station,
        help="answer for one accelerometer station only: keep only that link's history (default: every "
        "link, with tables and plots at the tight side)",
    )
    p.add_argument(
        "--settling-band",
        type=float,
        default=None,
        metavar="MM",
        help="band for the settling time after each index: |x - z| within it, in mm "
        f"(default: {m_to_mm(d.settling_band_m):g})",
    )
    p.add_argument(
        "--model",
        choices=registries.chain_models(),
        default=d.model,
        help="chain model: auto (default) runs the exact linear chain where no span leaves pulling contact "
        "(or the clearance is 0), else the clearance chain with pin free play and impacts",
    )
    p.add_argument(
        "--pin-clearance",
        default=None,
        metavar="MM",
        help="axial free play of each span (its two pin joints), mm, or inf for a chain that can only pull "
        f"(default: {m_to_mm(d.pin_clearance_m):g}, 2 x the mean clearance of an ISO 286 H8/f7 fit at "
        "the 19.05 mm pin)",
    )
    p.add_argument(
        "--rayleigh",
        default=None,
        metavar="ALPHA:BETA",
        help="Rayleigh damping C = alpha M + beta K (alpha 1/s, beta s) instead of the modal --damping",
    )
    p.add_argument(
        "--span-damping",
        choices=registries.span_damping_laws(),
        default=d.span_damping,
        help="clearance chain's damping: global (the chain's C, always acting; default) or kelvin-voigt "
        "(a dashpot beta k per span, only while in contact)",
    )
    p.add_argument(
        "--tensioner-rate",
        type=float,
        default=d.tensioner_rate_N_per_m,
        metavar="N/m",
        help="idler tensioner spring rate, N/m (with --tensioner-mass; default: rigid idler)",
    )
    p.add_argument(
        "--tensioner-mass", type=float, default=d.tensioner_mass_kg, metavar="KG", help="idler carriage mass, kg"
    )
    p.add_argument(
        "--tensioner-damping",
        type=float,
        default=d.tensioner_damping_N_s_per_m,
        metavar="N*s/m",
        help="idler carriage damping, N*s/m (default 0 with a tensioner)",
    )
    _add_machine_arguments(p, d)
    return p


def _add_machine_arguments(p: argparse.ArgumentParser, d: RunConfig) -> None:
    """The drive and the wheels (issue #22); see docs/physics.md, The machine on its wheels."""
    p.add_argument(
        "--drive",
        choices=registries.drives(),
        default=d.drive,
        help=f"link: link 1 driven through the drive spring k_d (the 2012 report's model); wheels: the chain on its "
        f"drive sprocket and idler wheel (default: {d.machine_drive}; link with --preset mqp2012)",
    )
    p.add_argument(
        "--sprocket-teeth",
        type=int,
        default=d.sprocket_teeth,
        metavar="Z",
        help="drive sprocket teeth (default: %(default)s; pitch radius p / (2 sin(pi/Z)) on the link's pitch p)",
    )
    p.add_argument(
        "--sprocket-wrap-links",
        type=int,
        default=d.sprocket_wrap_links,
        metavar="W",
        help="links seated on the drive sprocket (default: %(default)s, the report's)",
    )
    p.add_argument(
        "--drive-stiffness",
        type=float,
        default=d.drive_stiffness_N_m_per_rad,
        metavar="N*m/rad",
        help="torsional stiffness between the indexer's cam and the sprocket, or inf to hold the sprocket to the "
        "cam (default: the report's k_d at the sprocket's feed radius, k_d R_m^2)",
    )
    p.add_argument(
        "--sprocket-inertia",
        type=float,
        default=d.sprocket_inertia_kg_m2,
        metavar="KG*M2",
        help="sprocket inertia, kg*m^2 (default: a solid steel disc of the pitch radius, 25 mm thick)",
    )
    p.add_argument(
        "--idler-teeth",
        type=int,
        default=d.idler_teeth,
        metavar="Z",
        help="idler wheel teeth (default: the sprocket's)",
    )
    p.add_argument(
        "--idler-wrap-links",
        type=int,
        default=d.idler_wrap_links,
        metavar="W",
        help="links seated on the idler wheel; 0: no idler wheel, the idler is a point inside a span as with "
        "--drive link (default: the sprocket's)",
    )
    p.add_argument(
        "--idler-inertia",
        type=float,
        default=d.idler_inertia_kg_m2,
        metavar="KG*M2",
        help="idler wheel inertia, kg*m^2 (default: a solid steel disc of its pitch radius, 25 mm thick)",
    )
    p.add_argument(
        "--no-polygonal-action",
        action="store_true",
        help="feed the strands at the wheels' mean ratio instead of through the polygon of the seated pins",
    )
    p.add_argument(
        "--tooth-phase",
        type=float,
        default=d.tooth_phase,
        metavar="F",
        help="where the teeth stand at the dwell, as a fraction of a tooth in [0, 1) (default: %(default)s, a pin "
        "seats at the dwell; a phase F puts the seat change inside the index, when the cam has lifted 1 - F of a "
        "pitch)",
    )
    from dynamics.models.wheels import DEFAULT_TOOTH_STIFFNESS_N_PER_M  # numpy only: the start-up stays light

    p.add_argument(
        "--tooth-stiffness",
        default=None,
        metavar="N/m",
        help="seating on the wheels: a tooth contact stiffness in N/m (each seated link held to its seat by it, "
        "the arriving link seating where it is), rigid (the seated links move with their wheel), or auto (default: "
        "rigid seating where it holds for the run, else the tooth stiffness of the pin's line contact on the "
        f"tooth, {DEFAULT_TOOTH_STIFFNESS_N_PER_M:.2g} N/m, and the run says so)",
    )


def _split_ids(text: str, option: str) -> tuple[str, ...]:
    ids = tuple(s.strip() for s in text.split(",") if s.strip())
    if not ids:
        raise SettingsError(f"{option}: expected a comma-separated list of ids, got {text!r}")
    return ids


def _pin_clearance_m(text: str | None, default_m: float) -> float:
    """--pin-clearance in mm, or inf; not given: the default."""
    if text is None:
        return default_m
    try:
        return mm_to_m(float(text))
    except ValueError:
        raise SettingsError(f"--pin-clearance: expected a free play >= 0 mm or inf, got {text!r}") from None


def _tooth_stiffness(text: str | None) -> float | None:
    """--tooth-stiffness: N/m, rigid (inf) or auto (None, the default)."""
    if text is None or text.strip().lower() == "auto":
        return None
    if text.strip().lower() in ("rigid", "inf"):
        return float("inf")
    try:
        return float(text)
    except ValueError:
        raise SettingsError(f"--tooth-stiffness: expected a stiffness in N/m, rigid or auto, got {text!r}") from None


def _rayleigh(text: str | None) -> tuple[float, float] | None:
    from dynamics.options import parse_rayleigh

    if text is None:
        return None
    try:
        return parse_rayleigh(text)
    except ValueError as e:
        raise SettingsError(f"--rayleigh: {e}") from None


def parse_cli(argv: list[str] | None) -> RunConfig:
    """The RunConfig of a command line, checked (SettingsError on the first bad setting)."""
    from dataclasses import replace

    from geometry.options import link_source, signed_values_attached

    args = build_parser().parse_args(signed_values_attached(argv))
    d = RunConfig()
    cfg = RunConfig(
        geometry=args.geometry,
        materials=_split_ids(args.materials, "--materials"),
        materials_file=args.materials_file,
        links=args.links,
        rpm=args.rpm,
        cams=cam_ids() if args.cams.strip() == "all" else _split_ids(args.cams, "--cams"),
        friction=args.friction,
        damping=args.damping,
        preload_N=args.preload,
        solver=args.solver,
        preset=args.preset,
        out=args.out,
        images=not args.no_images,
        stress_beside=not args.serial,
        scenario_workers=not args.serial,
        quiet=args.quiet,
        mesh_size_m=d.mesh_size_m if args.mesh_size is None else mm_to_m(args.mesh_size),
        order=args.order,
        max_memory_gb=args.max_memory,
        max_fea_dofs=args.max_fea_dofs,
        hardware_mass_kg=args.hardware_mass,
        nest_mass_kg=args.nest_mass,
        cache_dir=args.cache_dir,
        steady_state=not args.from_rest,
        samples_per_degree=args.samples_per_degree,
        tolerance=args.tolerance,
        rpm_sweep=args.rpm_sweep,
        settling_band_m=d.settling_band_m if args.settling_band is None else mm_to_m(args.settling_band),
        station=args.station,
        hardware_material=args.hardware_material,
        hardware_from_step=args.hardware_from_step,
        model=args.model,
        pin_clearance_m=_pin_clearance_m(args.pin_clearance, d.pin_clearance_m),
        span_damping=args.span_damping,
        rayleigh=_rayleigh(args.rayleigh),
        tensioner_rate_N_per_m=args.tensioner_rate,
        tensioner_mass_kg=args.tensioner_mass,
        tensioner_damping_N_s_per_m=args.tensioner_damping,
        drive=args.drive,
        sprocket_teeth=args.sprocket_teeth,
        sprocket_wrap_links=args.sprocket_wrap_links,
        drive_stiffness_N_m_per_rad=args.drive_stiffness,
        sprocket_inertia_kg_m2=args.sprocket_inertia,
        idler_teeth=args.idler_teeth,
        idler_wrap_links=args.idler_wrap_links,
        idler_inertia_kg_m2=args.idler_inertia,
        polygonal_action=not args.no_polygonal_action,
        tooth_phase=args.tooth_phase,
        tooth_stiffness_N_per_m=_tooth_stiffness(args.tooth_stiffness),
    )
    check_run_config(cfg)
    return replace(cfg, link_source=link_source(args.geometry, args))


def check_writable_out(out: Path) -> None:
    """Fail before any work if --out cannot be created or written."""
    from stages.output_folder import out_folder_problem

    problem = out_folder_problem(out, create=True)
    if problem is not None:
        raise SettingsError(problem)


def run(cfg: RunConfig, progress: Progress, fea_process: Beside | None = None) -> None:
    """The run of `cfg`. `fea_process`: a process started for the FEA already (stages.fea.
    waiting_fea_process), handed the FEA if it runs beside, else cancelled."""
    from functools import partial

    from processes import imports_done
    from stages.chain import run_dynamics
    from stages.fea import FeaInProgress, start_fea
    from stages.geometry import inspect_geometry
    from stages.tolerance import run_to_tolerance

    timing: dict[str, float] = {}
    if cfg.preset == "mqp2012" or cfg.tolerance is not None:
        imports_done()  # these import as they go
        if fea_process is not None:
            fea_process.cancel()  # these run no FEA beside: it ends now, not with the run
    if cfg.preset == "mqp2012":
        from reporting.outputs import write_replica_outputs
        from stages.replica import run_replicas

        replicas = run_replicas(cfg, progress)
        timing["dynamics"] = progress.elapsed()
        write_replica_outputs(cfg, replicas, timing, progress)
        return
    cfg, part = inspect_geometry(cfg, progress)  # the part resolved once for the whole run
    if cfg.tolerance is None:
        # the stress study and images (needed by the outputs' stress lines only) run beside what follows
        start = partial(start_fea, part=part, beside=cfg.stress_beside, process=fea_process)
        fea = timed(timing, "fea", progress, start, cfg, progress)
        with fea:  # a failure below stops the process beside
            _import_chain_and_outputs(cfg)  # while the FEA's process starts and meshes
            stiffness = timed(timing, "fea", progress, lambda: fea.stiffness)
            chains, scenarios = timed(timing, "dynamics", progress, run_dynamics, cfg, stiffness, progress)
            _write_outputs(cfg, fea, chains, scenarios, timing, progress)
    else:
        done, chains, scenarios, shortfall = run_to_tolerance(cfg, progress, timing, part)
        if shortfall is not None:
            progress(shortfall)
        _write_outputs(cfg, FeaInProgress.done(done), chains, scenarios, timing, progress, shortfall)


def _import_chain_and_outputs(cfg: RunConfig) -> None:
    """The chain's and the outputs' modules (numba's kernels, matplotlib: 1-2 s), imported while the
    FEA's process imports its own and meshes, before the chain waits for the stiffness; and numba's
    typing and target registries filled, which its first compiled call does otherwise: 0.22-0.28 CPU s
    here took the dynamics stage's first-call overhead from 0.38 to 0.10-0.13 s (measured on the
    default run, kernels from numba's cache); for a chain on its wheels, its cached kernels loaded
    (dynamics.warm_up, 0.12-0.2 CPU s that the stage's first scenario pays otherwise); and
    matplotlib's first text laid out once for the figure workers
    (reporting.outputs.prepare_figure_workers). All of it runs while the FEA's process meshes the
    finest level on one thread, before its levels take both cores. The imports end here
    (processes.imports_done: the garbage collector on again where `python pipeline.py` paused it)."""
    from numba.core.registry import cpu_target

    import dynamics.scene  # noqa: F401
    from processes import imports_done
    from reporting.outputs import prepare_figure_workers

    cpu_target.typing_context.refresh()
    cpu_target.target_context.refresh()
    if cfg.machine_drive == "wheels":
        from dynamics.warm_up import load_machine_kernels

        load_machine_kernels()
    prepare_figure_workers()
    imports_done()


def _write_outputs(
    cfg: RunConfig, fea, chains, scenarios, timing: dict, progress: Progress, shortfall: str | None = None
) -> None:
    from reporting.outputs import write_default_outputs
    from stages.chain import RunResults, run_rpm_sweeps

    sweeps = timed(timing, "rpm_sweep", progress, run_rpm_sweeps, cfg, fea.stiffness, progress) if cfg.rpm_sweep else {}
    write_default_outputs(RunResults(cfg, fea, chains, scenarios, sweeps, timing, shortfall), progress)


def main(argv: list[str] | None = None, fea_process: Beside | None = None) -> int:
    """One run of the command line `argv`. `fea_process`: a process started for the FEA before the
    command line is read (stages.fea.waiting_fea_process, as `python pipeline.py` does): the run
    hands it the FEA, or it is cancelled."""
    from dynamics.errors import DynamicsError
    from fem.errors import FemError
    from geometry.errors import GeometryError
    from stages.beside import BesideError

    try:
        cfg = parse_cli(argv)
        check_writable_out(cfg.out)
        run(cfg, Progress(cfg.quiet), fea_process)
    except (SettingsError, GeometryError, FemError, DynamicsError, BesideError) as e:
        print(f"pipeline.py: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("pipeline.py: interrupted; nothing in --out was changed", file=sys.stderr)
        return 130
    finally:
        if fea_process is not None:
            fea_process.cancel()  # ended already where the run used it; else (an error, --help) now
    return 0


def exit_now(status: int) -> None:
    """End the process without the interpreter's teardown: once main has returned, everything is
    written and the FEA's process joined, and tearing down what the run imported and made (numba,
    matplotlib, SciPy, the histories) took 0.5-0.8 s of the whole job's wall (measured: main
    returning to the process's end, 0.03 s this way)."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


if __name__ == "__main__":
    from processes import pause_collector_for_imports

    pause_collector_for_imports()  # until the run's imports are done (processes.imports_done)
    from stages.fea import waiting_fea_process

    exit_now(main(fea_process=waiting_fea_process()))
