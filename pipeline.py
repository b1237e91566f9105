"""link-conveyor: from one link's CAD file to the vibration of the whole cam-indexed chain.

    python pipeline.py [--geometry LINK.step] [--materials al6061-t6,ti-grade2] [--links 85] ...

Stages: geometry (gmsh) -> FEA per material (scikit-fem: stiffness, mass, stress per newton) ->
chain dynamics per material x cam law -> summary.json, tables, plots, report.html in --out.
Everything inside is SI; tables and plots for people show mm where that reads better.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

CAM_IDS = ("modified-sine", "modified-trapezoid", "cycloidal", "poly-345", "poly-4567")
EXTRA_CAM_IDS = ("simple-harmonic",)  # accepted by name, not in 'all' (infinite jerk at the joints)
# Chains above dynamics.reduction.DENSE_LINK_LIMIT links are solved in their lowest modes.
MAX_LINKS = 10_000
DEFAULT_MATERIALS = ("al6061-t6", "ti-grade2")


class InputError(ValueError):
    """A command-line value that cannot be used; the message names it and what was expected."""


@dataclass(frozen=True)
class RunConfig:
    geometry: Path | None
    materials: tuple[str, ...]
    materials_file: Path | None
    links: int
    rpm: float
    cams: tuple[str, ...]
    friction: float
    damping: float
    preload_N: float
    solver: str
    preset: str | None
    out: Path
    images: bool
    quiet: bool
    mesh_size_m: float | None
    order: int
    hardware_mass_kg: float
    nest_mass_kg: float
    cache_dir: Path
    steady_state: bool
    samples_per_degree: int
    tolerance: float | None
    rpm_sweep: str | None
    settling_band_m: float
    station: str | None


class Progress:
    """Stage lines with elapsed time on stderr, so stdout stays clean for the final summary."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.start = time.perf_counter()

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(f"[{self.elapsed():7.1f} s] {message}", file=sys.stderr, flush=True)


def build_parser() -> argparse.ArgumentParser:
    from fem.cache import default_cache_dir
    from geometry import DEFAULT_HARDWARE_MASS_KG, NEST_MASS_KG

    p = argparse.ArgumentParser(
        prog="pipeline.py",
        description=(
            "Mesh a chain link, solve its axial stiffness and mass per material with linear "
            "elasticity, and simulate the closed chain driven by a cam indexer. Units: SI inside "
            "and in summary.json (m, kg, s, N, Pa); options state their units."
        ),
    )
    p.add_argument("--geometry", type=Path, default=None,
                   help="STEP file of one link with two pin bores, any length unit the file declares (default: the built-in parametric link)")
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
    )


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
    if out.exists() and not out.is_dir():
        raise InputError(f"--out: {str(out)!r} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".write-test-"):
            pass
    except OSError as e:
        raise InputError(f"--out: cannot write to {str(out)!r} ({e.strerror or e})") from None


@dataclass(frozen=True)
class MaterialFea:
    """What the dynamics and the outputs need of one material's FEA (SI)."""

    material: str
    stiffness_N_per_m: float
    stiffness_rel_error_estimate: float
    body_mass_kg: float
    body_volume_m3: float
    pitch_m: float
    bore_radius_m: float
    peak_von_mises_Pa_per_N: float
    peak_von_mises_away_from_clamp_Pa_per_N: float
    peak_von_mises_converged_Pa_per_N: float  # converged by local refinement (fem.stress): the design stress
    peak_von_mises_converged_rel_change: float  # its last change under refinement (estimated error)
    safety_factor_stress: str  # which stress the yield safety factor uses, in words
    yield_strength_Pa: float
    dofs: int
    mesh_size_m: float
    timing_s: dict
    warnings: list
    cached: bool
    image: Path | None


def fea_cache_settings(cfg: RunConfig, material, stiffness_tolerance: float | None) -> dict:
    from dataclasses import asdict

    from fem.stress import DEFAULT_TOLERANCE

    return {"material": asdict(material), "mesh_size_m": cfg.mesh_size_m, "order": cfg.order,
            "stiffness_tolerance": stiffness_tolerance, "stress_tolerance": DEFAULT_TOLERANCE}


def _fea_record(name: str, material, study, stress) -> dict:
    fine = study.finest
    return {
        "material": name,
        "stiffness_N_per_m": study.stiffness_N_per_m,
        "stiffness_rel_error_estimate": study.stiffness_rel_error_estimate,
        "body_mass_kg": fine.mass_kg,
        "body_volume_m3": fine.volume_m3,
        "pitch_m": fine.pitch_m,
        "bore_radius_m": fine.bore_radius_m,
        "peak_von_mises_Pa_per_N": fine.peak_von_mises_Pa_per_N,
        "peak_von_mises_away_from_clamp_Pa_per_N": fine.peak_von_mises_away_from_clamp_Pa_per_N,
        "peak_von_mises_converged_Pa_per_N": stress.peak_Pa_per_N,
        "peak_von_mises_converged_rel_change": stress.rel_change,
        "safety_factor_stress": stress.description,
        "yield_strength_Pa": material.yield_strength_Pa,
        "dofs": fine.dofs,
        "mesh_size_m": fine.mesh_size_m,
        "timing_s": study.timing_s,
        "warnings": [],
    }


def _solve_fea(cfg: RunConfig, materials: list, stiffness_tolerance: float | None, progress: Progress,
               solved_levels: dict | None) -> tuple[dict, dict]:
    """FEA studies of the materials not in the cache: fixed levels, or refined to a k tolerance
    (reusing the levels in `solved_levels`, see fem.adaptive); then the peak stress converged by
    local refinement from the finest level (fem.stress). Returns (stiffness, stress) per material."""
    from fem import stiffness_studies
    from fem.adaptive import stiffnesses_to_tolerance
    from fem.stress import stress_study
    from fem.study import levels_for_finest

    source = "built-in default link" if cfg.geometry is None else str(cfg.geometry)
    if stiffness_tolerance is None:
        progress(f"FEA {', '.join(m.name for m in materials)}: {source}, P{cfg.order}, 2 mesh levels")
        sizes = None if cfg.mesh_size_m is None else levels_for_finest(cfg.mesh_size_m)
        studies = stiffness_studies(cfg.geometry, materials, mesh_sizes_m=sizes, order=cfg.order, progress=progress)
    else:
        progress(f"FEA {', '.join(m.name for m in materials)}: {source}, P{cfg.order}, refining to a k error <= "
                 f"{100 * stiffness_tolerance:.2g} %")
        studies = stiffnesses_to_tolerance(cfg.geometry, materials, stiffness_tolerance, order=cfg.order,
                                           progress=progress, solved=solved_levels)
    finest = {name: study.finest for name, study in studies.items()}
    stresses = stress_study(cfg.geometry, materials, base_mesh_size_m=next(iter(finest.values())).mesh_size_m,
                            order=cfg.order, base=finest, progress=progress)
    return studies, stresses


def run_fea(cfg: RunConfig, progress: Progress, stiffness_tolerance: float | None = None,
            solved_levels: dict | None = None) -> dict[str, MaterialFea]:
    """Stiffness, mass and stress per material, from the cache when nothing they depend on changed."""
    import warnings

    from fem import load_materials, render_deformed
    from fem.cache import FeaCache, cache_key, geometry_fingerprint
    from fem.errors import FemWarning
    from geometry import DEFAULT_LINK

    library = load_materials(cfg.materials_file)
    unknown = [m for m in cfg.materials if m not in library]
    if unknown:
        raise InputError(f"--materials: unknown material {unknown[0]!r}; expected one of {', '.join(library)}")
    cache = FeaCache(cfg.cache_dir)
    fingerprint = geometry_fingerprint(cfg.geometry, repr(DEFAULT_LINK))
    keys = {name: cache_key(fingerprint, fea_cache_settings(cfg, library[name], stiffness_tolerance))
            for name in cfg.materials}
    images = {name: cache.image_path(key) if cfg.images else None for name, key in keys.items()}
    out: dict[str, MaterialFea] = {}
    for name, key in keys.items():
        stored = cache.load(key)
        if stored is not None and (images[name] is None or images[name].exists()):
            progress(f"FEA {name}: cached result (k = {stored['stiffness_N_per_m']:.5g} N/m)")
            out[name] = MaterialFea(**stored, cached=True, image=images[name])
    missing = [library[name] for name in cfg.materials if name not in out]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FemWarning)
        studies, stresses = _solve_fea(cfg, missing, stiffness_tolerance, progress, solved_levels) if missing else ({}, {})
    cautions = list(dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, FemWarning)))
    for message in cautions:
        print(f"pipeline.py: warning: {message}", file=sys.stderr)
    for material in missing:
        name, study = material.name, studies[material.name]
        stored = {**_fea_record(name, material, study, stresses[name]), "warnings": cautions}
        progress(f"FEA {name}: k = {study.stiffness_N_per_m:.5g} N/m "
                 f"(estimated error {100 * study.stiffness_rel_error_estimate:.2g} %)")
        if images[name] is not None:
            images[name].parent.mkdir(parents=True, exist_ok=True)
            render_deformed(study.finest, images[name], title=f"{name}: k = {study.stiffness_N_per_m:.4g} N/m")
        cache.store(keys[name], stored)
        out[name] = MaterialFea(**stored, cached=False, image=images[name])
    return {name: out[name] for name in cfg.materials}


@dataclass(frozen=True)
class Scenario:
    """One material x cam law: its histories (for plots), its metrics and their error estimate."""

    history: object  # reporting.history.CamHistory
    metrics: object  # dynamics.metrics.LinkMetrics
    stations: dict
    tension: object  # dynamics.metrics.TensionExtremes
    samples_per_degree: int
    rel_error_estimate: dict | None  # {"time_step", "stiffness", "total"} when --tolerance is given
    settling_time_s: "np.ndarray"  # per link, the longest settling into --settling-band over the dwells (NaN: never)


def output_times_s(rpm: float, samples_per_degree: int, window_deg: float = 180.0) -> "np.ndarray":
    """Output samples over the report's 180 deg window (two index cycles)."""
    import numpy as np

    degrees = np.arange(int(round(window_deg * samples_per_degree)) + 1) / samples_per_degree
    return degrees / (6.0 * rpm)


def chain_model(cfg: RunConfig, result: MaterialFea, stiffness_N_per_m: float | None = None):
    from dynamics.chain import ChainModel

    return ChainModel(
        n_links=cfg.links,
        link_mass_kg=result.body_mass_kg + cfg.hardware_mass_kg + cfg.nest_mass_kg,
        stiffness_N_per_m=result.stiffness_N_per_m if stiffness_N_per_m is None else stiffness_N_per_m,
        damping_ratio=cfg.damping,
        preload_N=cfg.preload_N,
        friction_coefficient=cfg.friction,
    )


def simulate_scenario(cfg: RunConfig, model, material: str, cam_id: str, pitch_m: float,
                      samples_per_degree: int) -> Scenario:
    import warnings

    from dynamics.cams import CamProgram
    from dataclasses import replace

    import numpy as np

    from dynamics.metrics import link_metrics, settling_times, station_links, station_metrics, tension_extremes
    from dynamics.reduction import modes_to_keep
    from reporting.history import CamHistory
    from dynamics.simulate import SlackChainWarning, simulate

    t = output_times_s(cfg.rpm, samples_per_degree)
    cam = CamProgram.indexing(cam_id, pitch_m=pitch_m, rpm=cfg.rpm)
    # a one-station question keeps one link's history (the spring tensions are kept whole: they are
    # what the slack check and the stress need)
    kept = None if cfg.station is None else (station_links(cfg.links)[cfg.station],)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SlackChainWarning)  # reported through the minimum tension
        r = simulate(model, cam, t, method=cfg.solver, steady_state=cfg.steady_state,
                     links=None if kept is None else [link - 1 for link in kept],
                     n_modes=modes_to_keep(cfg.links))
    history = CamHistory(material, cam_id, t, r.z_m, r.zdot_m_s, r.zddot_m_s2, r.x_m, r.v_m_s, r.a_m_s2,
                         r.tension_N, cam.dwell_mask(t), kept)
    metrics = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, history.dwell_mask)
    stations = (station_metrics(metrics) if kept is None
                else {cfg.station: replace(metrics.at_link(1), link=kept[0])})
    settling = settling_times(t, r.x_m, r.z_m, history.dwell_mask, cfg.settling_band_m).settling_time_s
    # a link that stays outside the band in any dwell has not settled: NaN wins over the maximum
    worst = np.where(np.isnan(settling).any(axis=0), np.nan, np.nanmax(settling, axis=0, initial=0.0))
    return Scenario(history, metrics, stations, tension_extremes(r.tension_N), samples_per_degree, None, worst)


def scenario_to_tolerance(cfg: RunConfig, result: MaterialFea, material: str, cam_id: str) -> Scenario:
    """Finest sampling the tolerance needs, with the error estimate from the step and from k."""
    from dataclasses import replace

    from dynamics.fidelity import choose_samples_per_degree, stiffness_sensitivity

    model = chain_model(cfg, result)
    runs: dict[int, Scenario] = {}

    def stations_at(spd: int):
        runs[spd] = simulate_scenario(cfg, model, material, cam_id, result.pitch_m, spd)
        return runs[spd].stations

    choice, stations = choose_samples_per_degree(stations_at, cfg.tolerance / 2)
    spd = choice.samples_per_degree
    k_error = stiffness_sensitivity(
        lambda k: simulate_scenario(cfg, chain_model(cfg, result, k), material, cam_id, result.pitch_m,
                                    spd).stations,
        result.stiffness_N_per_m, result.stiffness_rel_error_estimate, stations)
    estimate = {"time_step": choice.rel_error_estimate, "stiffness": k_error,
                "total": choice.rel_error_estimate + k_error}
    return replace(runs[spd], rel_error_estimate=estimate)


def run_dynamics(cfg: RunConfig, fea: dict[str, MaterialFea], progress: Progress):
    """Simulate every material x cam law; returns the chain models and the scenarios."""
    from dynamics.reduction import lowest_natural_frequencies_Hz, modes_to_keep

    models, scenarios = {}, {}
    for name, result in fea.items():
        models[name] = chain_model(cfg, result)
        for cam_id in cfg.cams:
            if cfg.tolerance is None:
                scenarios[name, cam_id] = simulate_scenario(cfg, models[name], name, cam_id, result.pitch_m,
                                                            cfg.samples_per_degree)
            else:
                scenarios[name, cam_id] = sc = scenario_to_tolerance(cfg, result, name, cam_id)
                progress(f"dynamics {name} / {cam_id}: {sc.samples_per_degree} samples per degree, "
                         f"estimated error {100 * sc.rel_error_estimate['total']:.2g} %")
        progress(f"dynamics {name}: {len(cfg.cams)} cam laws, N = {cfg.links}, "
                 f"f1 = {lowest_natural_frequencies_Hz(models[name], 10)[0]:.1f} Hz"
                 + ("" if modes_to_keep(cfg.links) is None else f", solved in its {modes_to_keep(cfg.links)} lowest modes"))
    return models, scenarios


def run(cfg: RunConfig, progress: Progress) -> None:
    from reporting.outputs import write_default_outputs, write_replica_outputs

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
    if cfg.tolerance is None:
        fea = _timed(timing, "fea", progress, run_fea, cfg, progress)
        models, scenarios = _timed(timing, "dynamics", progress, run_dynamics, cfg, fea, progress)
    else:
        fea, models, scenarios = run_to_tolerance(cfg, progress, timing)
    sweeps = _timed(timing, "rpm_sweep", progress, run_rpm_sweeps, cfg, fea, progress) if cfg.rpm_sweep else {}
    write_default_outputs(cfg, fea, models, scenarios, timing, progress, sweeps)


def run_rpm_sweeps(cfg: RunConfig, fea: dict[str, MaterialFea], progress: Progress) -> dict:
    """Speed sweep per material on the linear chain (the fast modal path cannot carry friction)."""
    from dataclasses import replace

    from dynamics.reduction import modes_to_keep
    from dynamics.sweep import parse_rpm_range, rpm_sweep

    rpms = parse_rpm_range(cfg.rpm_sweep)
    sweeps = {}
    for name, result in fea.items():
        model = replace(chain_model(cfg, result), friction_coefficient=0.0)
        sweeps[name] = rpm_sweep(model, cfg.cams, rpms, pitch_m=result.pitch_m, station=cfg.station or "tight-side",
                                 n_modes=modes_to_keep(cfg.links))
        progress(f"speed sweep {name}: {rpms.size} speeds x {len(cfg.cams)} cam laws, "
                 f"{len(sweeps[name].critical_speeds)} critical speeds in range"
                 + (" (friction left out of the sweep)" if cfg.friction > 0 else ""))
    return sweeps


def _timed(timing: dict, stage: str, progress: Progress, stage_function, *args):
    """Run one stage and add its wall time to timing[stage] (a stage may run more than once)."""
    start = progress.elapsed()
    result = stage_function(*args)
    timing[stage] = timing.get(stage, 0.0) + progress.elapsed() - start
    return result


def run_to_tolerance(cfg: RunConfig, progress: Progress, timing: dict):
    """Half the tolerance goes to the time step, half to the FEA stiffness. How much a k error moves
    the metrics is measured (not assumed) after a first FEA pass; if it moves them by more than its
    half, the FEA is refined once more to the k accuracy that the measured sensitivity asks for."""
    budget = cfg.tolerance / 2
    stiffness_tolerance = budget
    levels: dict = {}  # the refinement pass extends the first pass's levels instead of re-solving them
    fea = _timed(timing, "fea", progress, run_fea, cfg, progress, stiffness_tolerance, levels)
    models, scenarios = _timed(timing, "dynamics", progress, run_dynamics, cfg, fea, progress)
    from_k = max(sc.rel_error_estimate["stiffness"] for sc in scenarios.values())
    if from_k > budget:
        worst_k_error = max(r.stiffness_rel_error_estimate for r in fea.values())
        stiffness_tolerance = 0.8 * worst_k_error * budget / from_k
        progress(f"a {100 * worst_k_error:.2g} % error in k moves the metrics by {100 * from_k:.2g} %: "
                 f"refining the FEA to {100 * stiffness_tolerance:.2g} %")
        fea = _timed(timing, "fea", progress, run_fea, cfg, progress, stiffness_tolerance, levels)
        models, scenarios = _timed(timing, "dynamics", progress, run_dynamics, cfg, fea, progress)
    return fea, models, scenarios


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
