"""Every check on a RunConfig, before any work: one-line errors that name the option to fix.

`check_run_config` raises `SettingsError`; the numeric ranges are `settings.run.LIMITS`, the named
choices come from `settings.registries`.
"""

from __future__ import annotations

from settings import registries
from settings.run import LIMITS, RunConfig, SettingsError


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise SettingsError(message)


def check_run_config(cfg: RunConfig) -> None:
    """Raise SettingsError on the first setting that cannot be used."""
    _check_cams(cfg.cams)
    for name, limit in LIMITS.items():
        value = getattr(cfg, name)
        if value is not None:
            problem = limit.problem(value)
            _require(problem is None, problem)
    _check_choices(cfg)
    _check_solver(cfg.solver, cfg.friction)
    _check_chain_model(cfg)
    _check_machine(cfg)
    if cfg.rpm_sweep is not None:
        from dynamics.response.sweep import parse_rpm_range

        try:
            parse_rpm_range(cfg.rpm_sweep)
        except ValueError as e:
            raise SettingsError(f"--rpm-sweep: {e}") from None
    if cfg.preset == "mqp2012":
        _check_mqp2012(cfg)
    _check_files(cfg)


def _check_cams(cams: tuple[str, ...]) -> None:
    _require(len(cams) > 0, "--cams: expected at least one cam law id or 'all', got none")
    known = registries.known_cam_ids()
    unknown = [c for c in cams if c not in known]
    if unknown:
        raise SettingsError(f"--cams: unknown cam law {unknown[0]!r}; expected one of {', '.join(known)} or 'all'")


def _check_choices(cfg: RunConfig) -> None:
    for option, value, allowed in (
        ("--order", cfg.order, registries.ELEMENT_ORDERS),
        ("--preset", cfg.preset, (None, *registries.PRESETS)),
        ("--station", cfg.station, (None, *registries.station_names())),
        ("--model", cfg.model, registries.chain_models()),
        ("--span-damping", cfg.span_damping, registries.span_damping_laws()),
    ):
        _require(
            value in allowed,
            f"{option}: expected one of {', '.join(str(a) for a in allowed if a is not None)}, got {value!r}",
        )
    _require(len(cfg.materials) > 0, "--materials: expected a comma-separated list of material ids, got none")


def _check_solver(method: str, friction: float) -> None:
    """Refuse a method that does not exist or cannot model friction before any FEA is spent."""
    methods = registries.solver_methods()
    _require(method in methods, f"--solver: unknown method {method!r}; expected one of {', '.join(methods)}")
    if friction > 0 and not methods[method].handles_nonlinear_force:
        capable = ", ".join(m for m, info in methods.items() if info.handles_nonlinear_force)
        raise SettingsError(
            f"--solver: {method} cannot model friction (--friction {friction:g} > 0); "
            f"use one of {capable} or --friction 0"
        )


def _check_chain_model(cfg: RunConfig) -> None:
    """The chain-model options (issue #11); the tensioner's rules live in dynamics.models.tensioner."""
    from dynamics.models.tensioner import tensioner_from

    if cfg.rayleigh is not None:
        alpha, beta = cfg.rayleigh
        _require(
            cfg.span_damping == "global" or alpha == 0.0,
            f"--rayleigh: the kelvin-voigt span damping takes BETA only (ALPHA 0), got {alpha:g}:{beta:g}",
        )
    try:
        tensioner_from(cfg.tensioner_rate_N_per_m, cfg.tensioner_mass_kg, cfg.tensioner_damping_N_s_per_m)
    except ValueError as e:
        raise SettingsError(f"--tensioner-mass: {e}") from None


def _check_machine(cfg: RunConfig) -> None:
    """The drive and the wheels (issue #22); the model's own rules live in dynamics.models.machine."""
    drives = registries.drives()
    _require(cfg.drive in (None, *drives), f"--drive: expected one of {', '.join(drives)}, got {cfg.drive!r}")
    _require(
        cfg.preset != "mqp2012" or cfg.machine_drive == "link",
        "--drive: the mqp2012 preset replicates the report's link drive; expected --drive link (or no --drive) with it",
    )
    if cfg.machine_drive != "wheels":
        return
    for option, wrap, teeth in (
        ("--sprocket-wrap-links", cfg.sprocket_wrap_links, cfg.sprocket_teeth),
        ("--idler-wrap-links", cfg.idler_wrap_links_used, cfg.idler_teeth_used),
    ):
        _require(wrap < teeth, f"{option}: expected fewer seated links than the wheel's {teeth} teeth, got {wrap}")
    _check_tooth_stiffness(cfg)
    seated = cfg.sprocket_wrap_links + cfg.idler_wrap_links_used
    _require(
        cfg.links - seated >= 2,
        f"--links: {seated} links seated on the wheels leave {cfg.links - seated} free of {cfg.links}; expected at "
        "least two free links (more --links or fewer --sprocket-wrap-links/--idler-wrap-links)",
    )


def _check_tooth_stiffness(cfg: RunConfig) -> None:
    """A tooth contact stiffness asked for (a finite --tooth-stiffness) needs what its model carries
    (dynamics.models.machine): wheels with inertia (each is a body of its own)."""
    k_t = cfg.tooth_stiffness_N_per_m
    if k_t is None or k_t == float("inf"):
        return
    for option, inertia in (
        ("--sprocket-inertia", cfg.sprocket_inertia_kg_m2),
        ("--idler-inertia", cfg.idler_inertia_kg_m2),
    ):
        _require(
            inertia is None or inertia > 0,
            f"{option}: expected > 0 kg*m^2 with --tooth-stiffness (the wheel is a body of its own), got {inertia!r}",
        )


def _check_mqp2012(cfg: RunConfig) -> None:
    _require(cfg.links >= 8, f"--links: the mqp2012 preset needs >= 8 links (its preload positions), got {cfg.links}")
    cams = registries.preset_cam_ids("mqp2012")
    outside = [c for c in cfg.cams if c not in cams]
    if outside:
        raise SettingsError(
            f"--cams: the mqp2012 preset has the report's cams only ({', '.join(cams)}), got {outside[0]!r}"
        )
    materials = registries.preset_material_ids("mqp2012")
    strange = [m for m in cfg.materials if m not in materials]
    if strange:
        raise SettingsError(f"--materials: the mqp2012 preset knows {' and '.join(materials)}, got {strange[0]!r}")


def _check_files(cfg: RunConfig) -> None:
    if cfg.geometry is not None:
        _require(
            cfg.geometry.is_file(), f"--geometry: no such file {str(cfg.geometry)!r}; expected a STEP file of one link"
        )
    if cfg.materials_file is not None:
        _require(cfg.materials_file.is_file(), f"--materials-file: no such file {str(cfg.materials_file)!r}")
    _require(
        cfg.geometry is not None or (cfg.hardware_material is None and not cfg.hardware_from_step),
        "--hardware-material/--hardware-from-step: only for a --geometry STEP file; expected --geometry with them",
    )
    _require(
        not cfg.hardware_from_step or cfg.hardware_material is not None,
        "--hardware-from-step: the hardware solids need a material; expected --hardware-material ID[,ID...]",
    )
