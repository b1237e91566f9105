"""link-conveyor: from one link's CAD file to the vibration of the whole cam-indexed chain.

    python pipeline.py [--geometry LINK.step] [--materials al6061-t6,ti-grade2] [--links 85] ...

Stages: geometry (gmsh) -> FEA per material (scikit-fem: stiffness, mass, stress per newton) ->
chain dynamics per material x cam law -> summary.json, tables, plots, report.html in --out.
Everything inside is SI; tables and plots for people show mm where that reads better.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from stages.config import RunConfig
from stages.progress import Progress, timed

CAM_IDS = ("modified-sine", "modified-trapezoid", "cycloidal", "poly-345", "poly-4567")
EXTRA_CAM_IDS = ("simple-harmonic",)  # accepted by name, not in 'all' (infinite jerk at the joints)
# Chains above dynamics.reduction.DENSE_LINK_LIMIT links are solved in their lowest modes.
MAX_LINKS = 10_000
DEFAULT_MATERIALS = ("al6061-t6", "ti-grade2")


class InputError(ValueError):
    """A command-line value that cannot be used; the message names it and what was expected."""


def build_parser() -> argparse.ArgumentParser:
    from fem.cache import default_cache_dir
    from geometry import DEFAULT_HARDWARE_MASS_KG, NEST_MASS_KG
    from geometry.options import add_part_arguments

    p = argparse.ArgumentParser(
        prog="pipeline.py",
        description=(
            "Mesh a chain link, solve its axial stiffness and mass per material with linear "
            "elasticity, and simulate the closed chain driven by a cam indexer. Units: SI inside "
            "and in summary.json (m, kg, s, N, Pa); options state their units."
        ),
    )
    p.add_argument("--geometry", type=Path, default=None,
                   help="STEP file of one link with two pin bores (other holes and hardware solids allowed: see the part options), "
                        "any length unit the file declares (default: the built-in parametric link)")
    add_part_arguments(p)
    p.add_argument("--materials", default=",".join(DEFAULT_MATERIALS),
                   help="comma-separated material ids (default: %(default)s); see fem/data/materials.toml or --materials-file")
    p.add_argument("--materials-file", type=Path, default=None,
                   help="TOML file of extra user-defined materials (E in Pa, density in kg/m^3, yield in Pa)")
    p.add_argument("--links", type=int, default=85, help="number of links N in the closed chain (default: %(default)s)")
    p.add_argument("--rpm", type=float, default=180.0, help="cam speed in rev/min (default: %(default)s)")
    p.add_argument("--cams", default="all",
                   help=f"comma-separated cam laws or 'all' (default): {', '.join(CAM_IDS)}; "
                        f"also {', '.join(EXTRA_CAM_IDS)}")
    p.add_argument("--friction", type=float, default=0.35,
                   help="Coulomb friction coefficient mu between links and guide, force mu*m*g per link (default: %(default)s)")
    p.add_argument("--damping", type=float, default=0.13, help="modal damping ratio zeta of every chain mode (default: %(default)s, the sponsor's figure)")
    p.add_argument("--preload", type=float, default=2224.0,
                   help="static chain tension from the idler tensioner in N (default: %(default)s)")
    p.add_argument("--solver", default="exact", help="dynamics method (default: %(default)s, exact for the linear model); see README, Solvers")
    p.add_argument("--preset", choices=["mqp2012"], default=None,
                   help="mqp2012: replicate the 2012 report's MATLAB model, quirks included (see README)")
    p.add_argument("--out", type=Path, default=Path("results"), help="output folder (default: %(default)s); existing files of the same name are replaced only when the run succeeds")
    p.add_argument("--no-images", action="store_true", help="skip the pyvista images of the deformed link")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.add_argument("--mesh-size", type=float, default=None,
                   help="FEA element size in mm on the finest of 3 mesh levels (default: chosen for < 1%% error in k)")
    p.add_argument("--order", type=int, choices=[1, 2], default=2, help="FEA element order: 1 or 2 (P1/P2 tetrahedra; default: %(default)s)")
    p.add_argument("--hardware-mass", type=float, default=DEFAULT_HARDWARE_MASS_KG,
                   help="mass per link of pins, bushings and rollers in kg (default: %(default).4g)")
    p.add_argument("--hardware-from-step", action="store_true",
                   help="take the hardware mass from the STEP file's other solids (with --hardware-material) instead of --hardware-mass")
    p.add_argument("--nest-mass", type=float, default=NEST_MASS_KG, help="mass of the nest carried by each link in kg (default: %(default)s)")
    p.add_argument("--cache-dir", type=Path, default=default_cache_dir(), help="FEA result cache folder (default: %(default)s)")
    p.add_argument("--from-rest", action="store_true",
                   help="start the chain from rest at t=0 instead of the periodic steady state of continuous indexing")
    p.add_argument("--samples-per-degree", type=int, default=4,
                   help="output samples per degree of cam rotation (default: %(default)s)")
    p.add_argument("--tolerance", type=float, default=None,
                   help="relative tolerance on the reported metrics (e.g. 0.01): picks the FEA mesh and the "
                        "time step for it and reports the achieved error estimate (default: fixed settings)")
    p.add_argument("--rpm-sweep", metavar="FROM:TO:STEP", default=None,
                   help="also sweep the cam speed (rev/min): residual vibration and peak acceleration at the "
                        "tight-side station (or --station) per cam law, critical speeds marked (linear model, "
                        "friction left out)")
    p.add_argument("--station", choices=["drive-end", "tight-side", "idler-end", "slack-side"], default=None,
                   help="answer for one accelerometer station only: keep only that link's history (default: every "
                        "link, with tables and plots at the tight side)")
    p.add_argument("--settling-band", type=float, default=0.5, metavar="MM",
                   help="band for the settling time after each index: |x - z| within it, in mm (default: %(default)s)")
    p.add_argument("--model", choices=["auto", "linear", "clearance"], default="auto",
                   help="chain model: auto (default) runs the exact linear chain where no span leaves pulling contact "
                        "(or the clearance is 0), else the clearance chain with pin free play and impacts")
    p.add_argument("--pin-clearance", default="0.094", metavar="MM",
                   help="axial free play of each span (its two pin joints), mm, or inf for a chain that can only pull "
                        "(default: %(default)s, 2 x the mean clearance of an ISO 286 H8/f7 fit at the 19.05 mm pin)")
    p.add_argument("--rayleigh", default=None, metavar="ALPHA:BETA",
                   help="Rayleigh damping C = alpha M + beta K (alpha 1/s, beta s) instead of the modal --damping")
    p.add_argument("--span-damping", choices=["global", "kelvin-voigt"], default="global",
                   help="clearance chain's damping: global (the chain's C, always acting; default) or kelvin-voigt "
                        "(a dashpot beta k per span, only while in contact)")
    p.add_argument("--tensioner-rate", type=float, default=None, metavar="N/m",
                   help="idler tensioner spring rate, N/m (with --tensioner-mass; default: rigid idler)")
    p.add_argument("--tensioner-mass", type=float, default=None, metavar="KG", help="idler carriage mass, kg")
    p.add_argument("--tensioner-damping", type=float, default=None, metavar="N*s/m",
                   help="idler carriage damping, N*s/m (default 0 with a tensioner)")
    return p


def _split_ids(text: str, name: str) -> tuple[str, ...]:
    ids = tuple(s.strip() for s in text.split(",") if s.strip())
    if not ids:
        raise InputError(f"{name}: expected a comma-separated list of ids, got {text!r}")
    return ids


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise InputError(message)


def parse_cli(argv: list[str] | None) -> RunConfig:
    args = build_parser().parse_args(argv)
    cams = CAM_IDS if args.cams.strip() == "all" else _split_ids(args.cams, "--cams")
    unknown = [c for c in cams if c not in CAM_IDS + EXTRA_CAM_IDS]
    if unknown:
        raise InputError(f"--cams: unknown cam law {unknown[0]!r}; expected one of "
                         f"{', '.join(CAM_IDS + EXTRA_CAM_IDS)} or 'all'")
    _require(2 <= args.links <= MAX_LINKS, f"--links: expected a whole number of links from 2 to {MAX_LINKS}, "
             f"got {args.links}")
    _require(args.rpm > 0, f"--rpm: expected a cam speed > 0 rev/min, got {args.rpm:g}")
    _require(0.0 <= args.friction <= 1.0, f"--friction: expected a coefficient in [0, 1], got {args.friction:g}")
    _require(0.0 <= args.damping < 1.0, f"--damping: expected a damping ratio in [0, 1), got {args.damping:g}")
    _require(args.preload >= 0, f"--preload: expected a tension >= 0 N, got {args.preload:g}")
    _require(args.hardware_mass >= 0, f"--hardware-mass: expected a mass >= 0 kg, got {args.hardware_mass:g}")
    _require(args.nest_mass >= 0, f"--nest-mass: expected a mass >= 0 kg, got {args.nest_mass:g}")
    _require(args.mesh_size is None or args.mesh_size > 0,
             f"--mesh-size: expected an element size > 0 mm, got {args.mesh_size}")
    _require(args.samples_per_degree >= 1,
             f"--samples-per-degree: expected a whole number >= 1, got {args.samples_per_degree}")
    _require(args.tolerance is None or 0 < args.tolerance < 1,
             f"--tolerance: expected a relative tolerance in (0, 1), e.g. 0.01, got {args.tolerance}")
    _require(args.settling_band > 0, f"--settling-band: expected a band > 0 mm, got {args.settling_band:g}")
    _check_solver(args.solver, args.friction)
    chain_options = _chain_model_options(args)
    if args.rpm_sweep is not None:
        from dynamics.sweep import parse_rpm_range

        try:
            parse_rpm_range(args.rpm_sweep)
        except ValueError as e:
            raise InputError(f"--rpm-sweep: {e}") from None
    if args.preset == "mqp2012":
        _require(args.links >= 8, f"--links: the mqp2012 preset needs >= 8 links (its preload positions), got {args.links}")
        outside = [c for c in cams if c not in CAM_IDS]
        if outside:
            raise InputError(f"--cams: the mqp2012 preset has the report's cams only ({', '.join(CAM_IDS)}), "
                             f"got {outside[0]!r}")
        strange = [m for m in _split_ids(args.materials, "--materials") if m not in DEFAULT_MATERIALS]
        if strange:
            raise InputError(f"--materials: the mqp2012 preset knows {' and '.join(DEFAULT_MATERIALS)}, "
                             f"got {strange[0]!r}")
    if args.geometry is not None:
        _require(args.geometry.is_file(), f"--geometry: no such file {str(args.geometry)!r}; expected a STEP file of one link")
    if args.materials_file is not None:
        _require(args.materials_file.is_file(), f"--materials-file: no such file {str(args.materials_file)!r}")
    _require(args.geometry is not None or (args.hardware_material is None and not args.hardware_from_step),
             "--hardware-material/--hardware-from-step: only for a --geometry STEP file; expected --geometry with them")
    _require(not args.hardware_from_step or args.hardware_material is not None,
             "--hardware-from-step: the hardware solids need a material; expected --hardware-material ID[,ID...]")
    from geometry.options import link_source

    return RunConfig(
        geometry=args.geometry,
        materials=_split_ids(args.materials, "--materials"),
        materials_file=args.materials_file,
        links=args.links,
        rpm=args.rpm,
        cams=cams,
        friction=args.friction,
        damping=args.damping,
        preload_N=args.preload,
        solver=args.solver,
        preset=args.preset,
        out=args.out,
        images=not args.no_images,
        quiet=args.quiet,
        mesh_size_m=None if args.mesh_size is None else args.mesh_size / 1000.0,
        order=args.order,
        hardware_mass_kg=args.hardware_mass,
        nest_mass_kg=args.nest_mass,
        cache_dir=args.cache_dir,
        steady_state=not args.from_rest,
        samples_per_degree=args.samples_per_degree,
        tolerance=args.tolerance,
        rpm_sweep=args.rpm_sweep,
        settling_band_m=args.settling_band / 1000.0,
        station=args.station,
        **chain_options,
        link_source=link_source(args.geometry, args),
        hardware_material=args.hardware_material,
        hardware_from_step=args.hardware_from_step,
    )


def _chain_model_options(args) -> dict:
    """The chain-model options (issue #11), checked; the rules live in dynamics.clearance_sim."""
    from dynamics.clearance_sim import parse_rayleigh, tensioner_from

    try:
        clearance_mm = float(args.pin_clearance)
    except ValueError:
        clearance_mm = float("nan")
    _require(clearance_mm >= 0, f"--pin-clearance: expected a free play >= 0 mm or inf, got {args.pin_clearance!r}")
    rayleigh = None
    if args.rayleigh is not None:
        try:
            rayleigh = parse_rayleigh(args.rayleigh)
        except ValueError as e:
            raise InputError(f"--rayleigh: {e}") from None
        _require(args.span_damping == "global" or rayleigh[0] == 0.0,
                 f"--rayleigh: the kelvin-voigt span damping takes BETA only (ALPHA 0), got {args.rayleigh!r}")
    for name, value, low in (("--tensioner-rate", args.tensioner_rate, 0.0), ("--tensioner-mass", args.tensioner_mass, None),
                             ("--tensioner-damping", args.tensioner_damping, 0.0)):
        if value is not None and not ((value >= low if low is not None else value > 0) and value < float("inf")):
            raise InputError(f"{name}: expected a finite value {'> 0' if low is None else '>= 0'}, got {value:g}")
    try:
        tensioner_from(args.tensioner_rate, args.tensioner_mass, args.tensioner_damping)
    except ValueError as e:
        raise InputError(f"--tensioner-mass: {e}") from None
    return {"model": args.model, "pin_clearance_m": clearance_mm / 1000.0, "span_damping": args.span_damping,
            "rayleigh": rayleigh, "tensioner_rate_N_per_m": args.tensioner_rate,
            "tensioner_mass_kg": args.tensioner_mass, "tensioner_damping_N_s_per_m": args.tensioner_damping}


def _check_solver(method: str, friction: float) -> None:
    """Refuse a method that does not exist or cannot model friction before any FEA is spent."""
    from dynamics.solvers import METHODS

    if method not in METHODS:
        raise InputError(f"--solver: unknown method {method!r}; expected one of {', '.join(METHODS)}")
    if friction > 0 and not METHODS[method].handles_nonlinear_force:
        capable = ", ".join(m for m, info in METHODS.items() if info.handles_nonlinear_force)
        raise InputError(f"--solver: {method} cannot model friction (--friction {friction:g} > 0); "
                         f"use one of {capable} or --friction 0")


def check_writable_out(out: Path) -> None:
    """Fail before any work if --out cannot be created or written."""
    from stages.output_folder import out_folder_problem

    problem = out_folder_problem(out, create=True)
    if problem is not None:
        raise InputError(problem)


def run(cfg: RunConfig, progress: Progress) -> None:
    from functools import partial

    from reporting.outputs import write_default_outputs, write_replica_outputs
    from stages.chain import run_dynamics, run_rpm_sweeps
    from stages.fea import run_fea
    from stages.geometry import inspect_geometry
    from stages.tolerance import run_to_tolerance

    timing: dict[str, float] = {}
    if cfg.preset == "mqp2012":
        from dynamics.mqp2012 import run_mqp2012

        replicas = {}
        for material in cfg.materials:
            progress(f"mqp2012 replica {material}: RK45 restarted every degree, N = {cfg.links}")
            replicas[material] = run_mqp2012(material, n_links=cfg.links, rpm=cfg.rpm, friction=cfg.friction,
                                             cams=cfg.cams)
            if not replicas[material].stable:
                progress(f"warning: the script's model is unstable for N = {cfg.links} ({material}): its damping "
                         "matrix feeds energy in below N = 24, so its numbers grow without bound (as the script's did)")
        timing["dynamics"] = progress.elapsed()
        write_replica_outputs(cfg, replicas, timing, progress)
        return
    cfg, part = inspect_geometry(cfg, progress)  # the part resolved once for the whole run
    if cfg.tolerance is None:
        fea = timed(timing, "fea", progress, partial(run_fea, part=part), cfg, progress)
        models, scenarios = timed(timing, "dynamics", progress, run_dynamics, cfg, fea, progress)
    else:
        fea, models, scenarios = run_to_tolerance(cfg, progress, timing, part)
    sweeps = timed(timing, "rpm_sweep", progress, run_rpm_sweeps, cfg, fea, progress) if cfg.rpm_sweep else {}
    write_default_outputs(cfg, fea, models, scenarios, timing, progress, sweeps)


def main(argv: list[str] | None = None) -> int:
    from dynamics.errors import DynamicsError
    from fem.errors import FemError
    from geometry.errors import GeometryError

    try:
        cfg = parse_cli(argv)
        check_writable_out(cfg.out)
        run(cfg, Progress(cfg.quiet))
    except (InputError, GeometryError, FemError, DynamicsError) as e:
        print(f"pipeline.py: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("pipeline.py: interrupted; nothing in --out was changed", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
