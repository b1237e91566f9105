"""Everything `pipeline.py` writes into --out: summary.json, tables, plots, images, report.html.

Files are first written into a hidden staging folder inside --out and moved into place one by one
with os.replace only when all of them exist, so a failed run leaves an existing --out as it was and
a reader never sees half a file.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dynamics.response.metrics import rank_cams, rms, station_links
from dynamics.scene import ChainModelKind, linear_validity_at_yield
from reporting import html, plots, replica_sections
from reporting.drawing import FigureJob, draw_figures
from reporting.history import CamHistory
from reporting.sections import Report, build_sections
from reporting.tables import Table, max_acceleration_table, rms_table

if TYPE_CHECKING:
    from stages.chain import RunResults
    from stages.replica import ReplicaRun

RANKING_METRIC = "residual_vibration_m"
SUMMARY_STATION_KEYS = (
    "rms_displacement_m",
    "rms_velocity_m_s",
    "rms_acceleration_m_s2",
    "max_abs_acceleration_m_s2",
    "max_deviation_m",
    "max_velocity_deviation_m_s",
    "max_acceleration_deviation_m_s2",
    "residual_vibration_m",
)
PER_LINK_KEYS = (
    "rms_displacement_m",
    "rms_velocity_m_s",
    "rms_acceleration_m_s2",
    "max_abs_acceleration_m_s2",
    "residual_vibration_m",
)


class StagedOutput:
    """Collects output files in a staging folder; `commit` moves them into the output folder."""

    def __init__(self, out: Path):
        self.out = out
        self.staging = Path(tempfile.mkdtemp(dir=out, prefix=".staging-"))
        self.names: list[str] = []

    def path(self, name: str) -> Path:
        self.names.append(name)
        return self.staging / name

    def write_text(self, name: str, text: str) -> Path:
        p = self.path(name)
        p.write_text(text, encoding="utf-8")
        return p

    def commit(self) -> None:
        for name in self.names:
            os.replace(self.staging / name, self.out / name)
        shutil.rmtree(self.staging, ignore_errors=True)

    def discard(self) -> None:
        shutil.rmtree(self.staging, ignore_errors=True)

    def __enter__(self) -> StagedOutput:
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.commit()
        else:
            self.discard()
        return False


def _close_timing(timing: dict, progress) -> None:
    timing["outputs"] = progress.elapsed() - sum(timing.values())
    timing["total"] = progress.elapsed()


def _announce(cfg, staged: StagedOutput, timing: dict, progress, table: Table) -> None:
    progress(f"done in {timing['total']:.1f} s: {len(staged.names)} files in {cfg.out}/")
    if not cfg.quiet:
        print(table.to_markdown())


def _input_rms(h: CamHistory) -> dict[str, float]:
    return {
        "input_rms_displacement_m": float(rms(h.z_m)),
        "input_rms_velocity_m_s": float(rms(h.zdot_m_s)),
        "input_rms_acceleration_m_s2": float(rms(h.zddot_m_s2)),
    }


def _station_dict(station) -> dict:
    return {"link": station.link, **{k: getattr(station, k) for k in SUMMARY_STATION_KEYS}}


def _settling(value: float) -> float | None:
    return None if np.isnan(value) else float(value)


def _focus(cfg) -> str:
    return cfg.focus_station


def _tension_extremes_N(scenario) -> tuple[float, float]:
    """Peak and minimum span force as the chain model saw them (the clearance integrator: every step)."""
    return scenario.contact.peak_tension_N, scenario.contact.min_tension_N


def _number_or_null(value: float) -> float | None:
    """JSON has no NaN: a figure the model does not measure (NaN) is null."""
    return None if np.isnan(value) else float(value)


def _contact_summary(contact, linear_validity=None) -> dict:
    """Which model ran and why, and what it says about free play and impacts (issue #11).
    `linear_validity`: the linear model's validity with the link's yield load
    (dynamics.scene.linear_validity_at_yield); None: the contact's own."""
    ss = contact.steady_state
    linear_validity = contact.linear_model_validity if linear_validity is None else linear_validity
    return {
        "model": contact.model,
        "model_reason": contact.reason,
        "pin_clearance_m": None if np.isinf(contact.clearance_m) else contact.clearance_m,
        "contact_lost": bool(contact.contact_lost),
        "free_play_time_fraction": float(contact.free_play_time_fraction),
        "impacts_per_cycle": float(contact.impacts_per_cycle),
        "impact_force_spike_N": float(contact.impact_force_spike_N),
        **{
            f"impact_{name}": _number_or_null(value)
            for name, value in vars(contact.impacts).items()
            if name != "force_spike_N"
        },
        "preload_for_full_contact_N": float(contact.preload_for_full_contact_N),
        "linear_min_tension_N": float(contact.linear_min_tension_N),
        "linear_model_validity": None if linear_validity is None else vars(linear_validity),
        "clearance_steady_state": None
        if ss is None
        else {
            "found": ss.found,
            "period_cycles": ss.period_cycles,
            "cycles": ss.cycles,
            "residual": ss.residual,
            "statement": ss.statement,
        },
        "steps_per_output_sample": contact.steps_per_output,
        "peak_sampling": contact.peak_sampling,
        "lowest_mode": None if contact.lowest_mode is None else vars(contact.lowest_mode),
        "nearest_resonance": _resonance_summary(contact.nearest_resonance),
    }


def _resonance_summary(resonance) -> dict | None:
    """dynamics.scene.Resonance as one flat record: the mode's number, harmonic share and the highest
    mode searched beside its LowestMode fields."""
    if resonance is None:
        return None
    return {
        "mode_number": resonance.mode_number,
        "harmonic_share": resonance.harmonic_share,
        "searched_up_to_Hz": resonance.searched_up_to_Hz,
        **vars(resonance.mode),
    }


def _scenario_summary(scenario, fea, band_m: float) -> dict:
    peak_N, min_N = _tension_extremes_N(scenario)
    peak_stress = peak_N * fea.peak_von_mises_converged_Pa_per_N if fea is not None else None
    out = {
        "stations": {
            name: {
                **_station_dict(s),
                "settling_time_s": _settling(scenario.settling_time_s[scenario.history.column(s.link)]),
                "settling_band_m": band_m,
            }
            for name, s in scenario.stations.items()
        },
        "per_link": {k: getattr(scenario.metrics, k).tolist() for k in PER_LINK_KEYS},
        "peak_tension_N": peak_N,
        "min_tension_N": min_N,
        **_contact_summary(scenario.contact, _linear_validity(scenario.contact, fea)),
        "samples_per_degree": scenario.samples_per_degree,
    }
    if scenario.machine is not None:
        out["machine"] = machine_cycle_summary(scenario.machine)
    if scenario.rel_error_estimate is not None:
        out["rel_error_estimate"] = scenario.rel_error_estimate
    if peak_stress is not None:
        out["peak_link_stress_Pa"] = peak_stress
        out["yield_safety_factor"] = fea.yield_strength_Pa / peak_stress if peak_stress > 0 else None
    return out


def _linear_validity(contact, fea):
    """The contact's linear_model_validity with the link's yield load where the FEA gives it."""
    if fea is None:
        return contact.linear_model_validity
    return linear_validity_at_yield(contact, fea.yield_strength_Pa, fea.peak_von_mises_converged_Pa_per_N)


def _rankings(scenarios: dict, materials, cams, station: str) -> dict:
    result = {}
    for material in materials:
        by_cam = {cam: scenarios[material, cam].stations for cam in cams}
        result[material] = {
            metric: [list(cv) for cv in rank_cams(by_cam, metric, station).order]
            for metric in (RANKING_METRIC, "max_abs_acceleration_m_s2", "rms_acceleration_m_s2")
        }
    return result


def machine_parts_summary(parts) -> dict:
    """A material's machine as it ran (stages.machine.MachineParts), SI; an infinite drive stiffness
    (the sprocket held to the cam) is null with drive_held true."""
    k_theta = parts.drive_stiffness_N_m_per_rad
    return {
        "drive": parts.drive,
        "wheels": {
            name: {
                "teeth": w.teeth,
                "pitch_radius_m": w.pitch_radius_m,
                "feed_radius_m": w.feed_radius_m,
                "wrap_links": w.wrap_links,
                "inertia_kg_m2": w.inertia_kg_m2,
            }
            for name, w in parts.wheels.items()
        },
        "drive_stiffness_N_m_per_rad": None if k_theta is None or np.isinf(k_theta) else float(k_theta),
        "drive_held": k_theta is not None and bool(np.isinf(k_theta)),
        "polygonal_action": parts.polygonal_action,
        "idler_carriage": parts.idler_carriage,
    }


def machine_cycle_summary(cycle) -> dict:
    """The seat changes of an index cycle on the wheels (stages.machine.MachineCycle), SI."""
    return {
        "steady_state_frame": cycle.frame,
        "seating": {
            name: {"speed_m_s": seat.speed_m_s, "impact_energy_J": seat.impact_energy_J}
            for name, seat in cycle.seating.items()
        },
        "transfer_energy_change_J": cycle.transfer_energy_change_J,
        "seating_model": seating_validity_summary(cycle.seating_validity),
    }


def seating_validity_summary(validity) -> dict:
    """Which seating model ran and whether it holds (dynamics.response.seating.SeatingValidity), SI; the
    tooth model's k_t and, where the run switched to it, rigid seating's verdict it left (the keys are
    there only when the tooth model ran: rigid seating's record is as it was)."""
    out = {
        "model": validity.model,
        "valid": validity.valid,
        "reason": validity.reason,
        "snap_J": validity.snap_J,
        "cam_speed_fraction_at_seat_change": validity.cam_speed_fraction,
        "cam_acceleration_fraction_at_seat_change": validity.cam_acceleration_fraction,
        "at_rest_threshold": validity.threshold,
        "instead": validity.instead,
    }
    if validity.tooth_stiffness_N_per_m is not None:
        out["tooth_stiffness_N_per_m"] = validity.tooth_stiffness_N_per_m
        left = validity.switched_from
        out["switched_from"] = None if left is None else seating_validity_summary(left)
    return out


def _machine(results: RunResults) -> dict:
    """What ran for the whole run: the drive, the polygonal action, the steady state's frame, the tooth
    phase (on the wheels)."""
    first = next(iter(results.chains.values())).machine
    frames = sorted({sc.machine.frame for sc in results.scenarios.values() if sc.machine is not None})
    return {
        "drive": first.drive,
        "polygonal_action": first.polygonal_action,
        "steady_state_frame": frames[0] if len(frames) == 1 else None,
        "stations_are": "places on the machine: the link there at the start of an index"
        if first.drive == "wheels"
        else "links",
        # on the wheels: where the teeth stand at the dwell (the seats change inside the index when != 0
        # with the polygonal action); the link drive has no teeth
        **({"tooth_phase": results.cfg.tooth_phase} if first.drive == "wheels" else {}),
    }


def _stations(results: RunResults) -> dict[str, int]:
    """1-based link at each station (the same layout for every material)."""
    return next(iter(results.chains.values())).machine.stations


def default_summary(results: RunResults) -> dict:
    cfg, fea, scenarios = results.cfg, results.fea, results.scenarios
    first = next(iter(fea.values()))
    return {
        "inputs": _inputs(cfg),
        "machine": _machine(results),
        "geometry": {
            "source": "default" if cfg.geometry is None else str(cfg.geometry),
            "pitch_m": first.pitch_m,
            "body_volume_m3": first.body_volume_m3,
            "bore_radius_m": first.bore_radius_m,
        },
        "stations": {
            name: link for name, link in _stations(results).items() if cfg.station is None or name == cfg.station
        },
        "cams": {cam: _input_rms(scenarios[first.material, cam].history) for cam in cfg.cams},
        "materials": {
            name: {
                "stiffness_N_per_m": r.stiffness_N_per_m,
                "stiffness_rel_error_estimate": r.stiffness_rel_error_estimate,
                "body_mass_kg": r.body_mass_kg,
                "lumped_mass_kg": results.chains[name].model.link_mass_kg,
                "natural_frequencies_Hz": results.chains[name].natural_frequencies_Hz.tolist(),
                "machine": machine_parts_summary(results.chains[name].machine),
                "peak_von_mises_Pa_per_N": r.peak_von_mises_Pa_per_N,
                "peak_von_mises_away_from_clamp_Pa_per_N": r.peak_von_mises_away_from_clamp_Pa_per_N,
                "peak_von_mises_converged_Pa_per_N": r.peak_von_mises_converged_Pa_per_N,
                "peak_von_mises_converged_rel_change": r.peak_von_mises_converged_rel_change,
                "safety_factor_stress": r.safety_factor_stress,
                "yield_strength_Pa": r.yield_strength_Pa,
                "fea_dofs": r.dofs,
                "fea_mesh_size_m": r.mesh_size_m,
                "fea_from_cache": r.cached,
                "fea_warnings": r.warnings,
                "cams": {cam: _scenario_summary(scenarios[name, cam], r, cfg.settling_band_m) for cam in cfg.cams},
            }
            for name, r in fea.items()
        },
        "ranking": {"station": _focus(cfg), "by_material": _rankings(scenarios, fea, cfg.cams, _focus(cfg))},
        "fidelity": _fidelity(cfg, fea, scenarios, results.tolerance_shortfall),
        "timing_s": results.timing,
    }


def _fidelity(cfg, fea: dict, scenarios: dict, shortfall: str | None) -> dict:
    """What resolution each stage used and the error it is estimated to leave in the metrics; with
    --tolerance, whether it is met and, where not, why."""
    estimates = [sc.rel_error_estimate["total"] for sc in scenarios.values() if sc.rel_error_estimate]
    models = {sc.contact.model for sc in scenarios.values()}
    met = {} if cfg.tolerance is None else {"tolerance_met": shortfall is None, "tolerance_not_met_because": shortfall}
    return {
        "tolerance": cfg.tolerance,
        **met,
        "fea": {
            m: {
                "mesh_size_m": r.mesh_size_m,
                "order": cfg.order,
                "dofs": r.dofs,
                "stiffness_rel_error_estimate": r.stiffness_rel_error_estimate,
            }
            for m, r in fea.items()
        },
        "dynamics": {
            "solver": cfg.solver
            if "clearance" not in models
            else f"{cfg.solver} (linear chain); clearance-verlet (clearance chain)",
            "samples_per_degree": max(sc.samples_per_degree for sc in scenarios.values()),
            "metrics_rel_error_estimate": max(estimates) if estimates else None,
        },
    }


def _inputs(cfg) -> dict:
    return {
        "links": cfg.links,
        "rpm": cfg.rpm,
        "cams": list(cfg.cams),
        "materials": list(cfg.materials),
        "friction_coefficient": cfg.friction,
        "damping_ratio": cfg.damping,
        "preload_N": cfg.preload_N,
        "solver": cfg.solver,
        "preset": cfg.preset,
        "steady_state": cfg.steady_state,
        "station": cfg.station,
        "samples_per_degree": cfg.samples_per_degree,
        "hardware_mass_kg": cfg.hardware_mass_kg,
        "nest_mass_kg": cfg.nest_mass_kg,
        "fea_order": cfg.order,
        "fea_mesh_size_m": cfg.mesh_size_m,
        **_chain_model_inputs(cfg),
        **_machine_inputs(cfg),
    }


def _machine_inputs(cfg) -> dict:
    """The drive, and the wheel settings as given (None: the documented default) when it is the wheels."""
    drive = cfg.machine_drive
    if drive != "wheels":
        return {"drive": drive}
    k_theta = cfg.drive_stiffness_N_m_per_rad
    return {
        "drive": drive,
        "sprocket_teeth": cfg.sprocket_teeth,
        "sprocket_wrap_links": cfg.sprocket_wrap_links,
        "drive_stiffness_N_m_per_rad": None if k_theta is None or np.isinf(k_theta) else k_theta,
        "drive_stiffness_infinite": k_theta is not None and bool(np.isinf(k_theta)),
        "sprocket_inertia_kg_m2": cfg.sprocket_inertia_kg_m2,
        "idler_teeth": cfg.idler_teeth_used,
        "idler_wrap_links": cfg.idler_wrap_links_used,
        "idler_inertia_kg_m2": cfg.idler_inertia_kg_m2,
        "polygonal_action": cfg.polygonal_action,
        "tooth_phase": cfg.tooth_phase,
        # --tooth-stiffness as given (not given, auto: no key, the default run's record as it was)
        **(
            {}
            if cfg.tooth_stiffness_N_per_m is None
            else {"tooth_stiffness": "rigid" if np.isinf(cfg.tooth_stiffness_N_per_m) else cfg.tooth_stiffness_N_per_m}
        ),
    }


def _chain_model_inputs(cfg) -> dict:
    clearance = cfg.pin_clearance_m
    return {
        "model": cfg.model,
        "pin_clearance_m": None if np.isinf(clearance) else clearance,
        "pin_clearance_infinite": bool(np.isinf(clearance)),
        "span_damping": cfg.span_damping,
        "rayleigh_alpha_beta": None if cfg.rayleigh is None else list(cfg.rayleigh),
        "tensioner_rate_N_per_m": cfg.tensioner_rate_N_per_m,
        "tensioner_mass_kg": cfg.tensioner_mass_kg,
        "tensioner_damping_N_s_per_m": cfg.tensioner_damping_N_s_per_m,
    }


@dataclass(frozen=True)
class LinkRms:
    """RMS of one link's motion and its max |acceleration|, SI."""

    rms_displacement_m: float
    rms_velocity_m_s: float
    rms_acceleration_m_s2: float
    max_abs_acceleration_m_s2: float


def _tables(histories: dict, at_link: dict, rms_link: int, max_link: int) -> list[Table]:
    """RMS (Table 1/4 layout) and max-acceleration (Table 2) tables; at_link[(material, cam)] is a LinkRms."""
    materials = list(dict.fromkeys(m for m, _ in histories))
    cams = list(dict.fromkeys(c for _, c in histories))
    inputs = {cam: histories[materials[0], cam] for cam in cams}
    input_rms = {
        cam: {
            "displacement": float(rms(h.z_m)),
            "velocity": float(rms(h.zdot_m_s)),
            "acceleration": float(rms(h.zddot_m_s2)),
        }
        for cam, h in inputs.items()
    }
    link_rms = {
        m: {
            cam: {
                "displacement": at_link[m, cam].rms_displacement_m,
                "velocity": at_link[m, cam].rms_velocity_m_s,
                "acceleration": at_link[m, cam].rms_acceleration_m_s2,
            }
            for cam in cams
        }
        for m in materials
    }
    max_acc = {m: {cam: at_link[m, cam].max_abs_acceleration_m_s2 for cam in cams} for m in materials}
    return [rms_table(input_rms, link_rms, rms_link), max_acceleration_table(max_acc, max_link)]


def _link_rms(station) -> LinkRms:
    return LinkRms(
        station.rms_displacement_m,
        station.rms_velocity_m_s,
        station.rms_acceleration_m_s2,
        station.max_abs_acceleration_m_s2,
    )


def _ranking_table(rankings: dict, station: str) -> Table:
    rows = []
    for material, by_metric in rankings.items():
        for rank, (cam, value) in enumerate(by_metric[RANKING_METRIC], start=1):
            rows.append((material, rank, cam, value * 1e3, dict(by_metric["max_abs_acceleration_m_s2"])[cam]))
    return Table(
        f"Cam laws ranked by residual vibration in the dwell at the {station} station (best first)",
        ("material", "rank", "cam law", "residual vibration (mm)", "max |acceleration| (m/s²)"),
        tuple(rows),
    )


def _write_tables(staged: StagedOutput, tables: dict[str, Table]) -> str:
    for stem, table in tables.items():
        staged.write_text(f"{stem}.csv", table.to_csv())
        staged.write_text(f"{stem}.md", table.to_markdown())
    return "\n".join(t.to_markdown() for t in tables.values())


# The figures that share a grid of axes with another kind: drawn in one batch (the rest by kind)
_LAYOUT_BATCH = {
    "middle link, all cams": "3 x 1",
    "differences": "3 x 1",
    "dwell": "1 x 1",
    "tension": "1 x 1",
}


def _material_plots(
    staged: StagedOutput, histories: list[CamHistory], links: dict[str, int], focus: int
) -> dict[str, FigureJob]:
    """The report's figures; links = the stations whose histories exist, focus = the link they centre on."""
    m = histories[0].material
    figures = {}
    if histories[0].links is None:
        n = histories[0].x_m.shape[1]
        figures["three links"] = FigureJob(
            plots.plot_three_links, (histories, [1, links["idler-end"], n], staged.path(f"{m}_three_links.png"))
        )
        figures["middle link, all cams"] = FigureJob(
            plots.plot_three_links,
            (histories, [links["idler-end"]], staged.path(f"{m}_link{links['idler-end']}_all_cams.png")),
        )
    figures |= {
        "vs input": FigureJob(
            plots.plot_link_vs_input, (histories, focus, staged.path(f"{m}_link{focus}_vs_input.png"))
        ),
        "differences": FigureJob(
            plots.plot_differences, (histories, focus, staged.path(f"{m}_link{focus}_differences.png"))
        ),
        "dwell": FigureJob(
            plots.plot_dwell_vibration, (histories, focus, staged.path(f"{m}_link{focus}_dwell_vibration.png"))
        ),
    }
    if np.any(histories[0].tension_N):
        figures["tension"] = FigureJob(plots.plot_tension, (histories, staged.path(f"{m}_tension.png")))
    # the figures of one grid of axes drawn one after the other, each on the axes of the one before
    # (reporting.drawing, reporting.plots._subplots)
    return {label: replace(job, batch=_LAYOUT_BATCH.get(label, label)) for label, job in figures.items()}


def _drawn(figures: dict[str, dict[str, FigureJob]]) -> dict[str, dict[str, Path]]:
    """Per material, its figures drawn (side by side, reporting.drawing)."""
    paths = draw_figures({(m, label): job for m, jobs in figures.items() for label, job in jobs.items()})
    return {m: {label: paths[m, label] for label in jobs} for m, jobs in figures.items()}


def _station_table(scenarios: dict, band_m: float) -> Table:
    rows = []
    for (material, cam), sc in scenarios.items():
        for station, s in sc.stations.items():
            settle = sc.settling_time_s[sc.history.column(s.link)]
            rows.append(
                (
                    material,
                    cam,
                    station,
                    s.link,
                    s.rms_acceleration_m_s2,
                    s.max_abs_acceleration_m_s2,
                    s.residual_vibration_m * 1e3,
                    s.max_deviation_m * 1e3,
                    "not within the dwell" if np.isnan(settle) else settle * 1e3,
                )
            )
    return Table(
        f"Accelerometer stations (settling: |x − z| within {band_m * 1e3:g} mm to the dwell's end)",
        (
            "material",
            "cam law",
            "station",
            "link",
            "RMS acceleration (m/s²)",
            "max |acceleration| (m/s²)",
            "residual vibration (mm)",
            "max |x − z| (mm)",
            "settling time (ms)",
        ),
        tuple(rows),
    )


def _linear_model_cell(c: dict) -> str:
    """Whether a scenario's linear model (its minimum tension, the preload for full contact) holds:
    summary.json's linear_model_validity, "" where there is none (the single-link drive). A column of
    its own, so that the preload's column stays numbers in the CSV."""
    validity = c.get("linear_model_validity")
    return "" if validity is None else str(validity["validity"])


def _tension_table(summary_materials: dict) -> Table:
    rows = []
    for material, data in summary_materials.items():
        for cam, c in data["cams"].items():
            rows.append(
                (
                    material,
                    cam,
                    c.get("model", "linear"),
                    c["peak_tension_N"] / 1e3,
                    c["min_tension_N"] / 1e3,
                    "yes" if c.get("contact_lost") else "no",
                    100.0 * c.get("free_play_time_fraction", 0.0),
                    c.get("impacts_per_cycle", 0.0),
                    c.get("impact_force_spike_N", 0.0) / 1e3,
                    c.get("preload_for_full_contact_N", float("nan")) / 1e3,
                    _linear_model_cell(c),
                    c["peak_link_stress_Pa"] / 1e6,
                    c["yield_safety_factor"],
                )
            )
    used = "; ".join(f"{m}: {data['safety_factor_stress']}" for m, data in summary_materials.items())
    return Table(
        "Link tension, contact and stress (min tension < 0: a span pushing after its free play closed; "
        f"stress = peak tension x the FEA's {used})",
        (
            "material",
            "cam law",
            "model",
            "peak tension (kN)",
            "min tension (kN)",
            "contact lost",
            "free play (% span-time)",
            "impacts per cycle",
            "impact force spike (kN)",
            "preload for full contact (kN)",
            "linear model",
            "peak stress (MPa)",
            "safety factor on yield",
        ),
        tuple(rows),
    )


def _sweep_summary(sweep) -> dict:
    return {
        "model": sweep.model,
        "station": sweep.station,
        "link": sweep.station_link,
        "rpm": sweep.rpm.tolist(),
        "friction_coefficient": 0.0,
        "cams": {
            cam: {
                "residual_vibration_m": sweep.residual_vibration_m[i].tolist(),
                "peak_abs_acceleration_m_s2": sweep.peak_acceleration_m_s2[i].tolist(),
                # per speed, the seating the run's verdict at that speed ran (null: the link drive)
                "seating_model": None if sweep.seating_model is None else list(sweep.seating_model[i]),
            }
            for i, cam in enumerate(sweep.cam_ids)
        },
        "critical_speeds": [{"rpm": c.rpm, "mode": c.mode, "harmonic": c.harmonic} for c in sweep.critical_speeds],
        "critical_speed_definition": sweep.definition,
    }


def _sweep_table(sweeps: dict) -> Table:
    """rpm_sweep.csv: one row per material, cam law and speed; `seating_model` is the seating that point
    ran (each speed its own: dynamics.response.sweep.machine_rpm_sweep), empty on the link drive (no seats)."""
    rows = []
    for material, sweep in sweeps.items():
        for i, cam in enumerate(sweep.cam_ids):
            for j, rpm in enumerate(sweep.rpm):
                rows.append(
                    (
                        material,
                        cam,
                        float(rpm),
                        float(sweep.residual_vibration_m[i, j]),
                        float(sweep.peak_acceleration_m_s2[i, j]),
                        "" if sweep.seating_model is None else sweep.seating_model[i][j],
                    )
                )
    return Table(
        "Speed sweep",
        ("material", "cam law", "rpm", "residual_vibration_m", "peak_abs_acceleration_m_s2", "seating_model"),
        tuple(rows),
    )


def prepare_figure_workers() -> None:
    """What each figure worker (reporting.drawing, forked from this process) would do first, done
    once here before they fork: matplotlib's Agg backend imported, the text font found and loaded
    (FreeType) and a first text and ticks laid out, on a figure of its own (pyplot's figures
    untouched, nothing drawn changes). A worker's first figure (the residual vibration, drawn in a
    fork) took 0.32-0.37 CPU s without it and 0.12-0.18 with it, for 0.15-0.21 CPU s once here
    (three runs each, load 4.6-5.1, 2026-11-27); `pipeline.py` does it before the stiffness
    arrives, on the core the FEA's process leaves free."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(2.0, 1.5))
    FigureCanvasAgg(figure)  # the Agg canvas the workers draw on, attached to the figure
    axes = figure.add_subplot()
    axes.plot([0.0, 1.0], [0.0, 1.0])
    axes.set_title("title")
    axes.set_xlabel("label")
    figure.canvas.draw()


def write_default_outputs(results: RunResults, progress) -> None:
    """Write everything into --out. The figures, which need the chain only, are drawn first, while
    the FEA's stress study may still run beside (stages.fea.start_fea); it is waited for before the
    summary, the tables and the report, which give its stresses."""
    cfg, scenarios, sweeps = results.cfg, results.scenarios, results.sweeps
    materials = cfg.materials
    with StagedOutput(cfg.out) as staged:
        progress("outputs: tables, plots and report")
        links = _stations(results)
        focus = _focus(cfg)
        focus_link = links[focus]
        histories = {key: sc.history for key, sc in scenarios.items()}
        residual = {m: {c: scenarios[m, c].stations[focus].residual_vibration_m for c in cfg.cams} for m in materials}
        material_jobs = {
            m: _material_plots(staged, [histories[m, c] for c in cfg.cams], links, focus_link) for m in materials
        }
        for m, job in _tension_maps(staged, scenarios, materials, cfg.cams).items():
            material_jobs[m]["tension map"] = job
        jobs = {("material", m, label): job for m, by_label in material_jobs.items() for label, job in by_label.items()}
        jobs["residual",] = FigureJob(
            plots.plot_residual_vibration, (residual, focus, staged.path("residual_vibration.png"))
        )
        jobs |= {
            ("sweep", m): FigureJob(plots.plot_rpm_sweep, (sweep, staged.path(f"{m}_rpm_sweep.png")))
            for m, sweep in sweeps.items()
        }
        paths = draw_figures(jobs)
        results.wait_for_fea(progress)
        fea, timing = results.fea, results.timing
        at_link = {key: _link_rms(sc.stations[focus]) for key, sc in scenarios.items()}
        summary = default_summary(results)
        ranking = _ranking_table(summary["ranking"]["by_material"], focus)
        report_tables = dict(
            zip(("rms_table", "max_acceleration_table"), _tables(histories, at_link, focus_link, focus_link))
        )
        tables = {
            **report_tables,
            "ranking": ranking,
            "stations": _station_table(scenarios, cfg.settling_band_m),
            "tension": _tension_table(summary["materials"]),
        }
        staged.write_text("tables.md", _write_tables(staged, tables))
        figures = {
            m: {label: paths["material", m, label] for label in by_label} for m, by_label in material_jobs.items()
        }
        residual_png = paths["residual",]
        sweep_pngs = {m: paths["sweep", m] for m in sweeps}
        images = {}
        for m, r in fea.items():
            if r.image is not None:
                images[m] = staged.path(f"{m}_deformed.png")
                shutil.copyfile(r.image, images[m])
        if sweeps:
            staged.write_text("rpm_sweep.csv", _sweep_table(sweeps).to_csv())
            summary["rpm_sweep"] = {m: _sweep_summary(sweep) for m, sweep in sweeps.items()}
        _close_timing(timing, progress)
        staged.write_text("summary.json", json.dumps(summary, indent=1))
        report = Report(results, summary, tables, residual_png, figures, images, sweep_pngs)
        staged.write_text(
            "report.html", html.render_page("link-conveyor: chain vibration report", build_sections(report))
        )
    _announce(cfg, staged, timing, progress, ranking)


def _tension_maps(staged: StagedOutput, scenarios: dict, materials, cams) -> dict[str, FigureJob]:
    """Per material, the span x time tension map of the cam with the highest peak tension."""
    maps = {}
    for m in materials:
        worst = max(cams, key=lambda c: _tension_extremes_N(scenarios[m, c])[0])
        sc = scenarios[m, worst]
        clearance_ran = sc.contact.model == ChainModelKind.CLEARANCE
        free_play = sc.history.tension_N == 0.0 if clearance_ran else np.zeros(sc.history.tension_N.shape, bool)
        note = f"{sc.contact.model} model; highest peak tension of the cam laws"
        maps[m] = FigureJob(plots.plot_tension_map, (sc.history, free_play, staged.path(f"{m}_tension_map.png"), note))
    return maps


def replica_summary(cfg, runs: dict[str, ReplicaRun], timing: dict) -> dict:
    from dynamics.models.mqp2012 import REPORT_TABLE1, REPORT_TABLE2
    from dynamics.response.metrics import station_metrics

    materials = {}
    for name, run in runs.items():
        r = run.replica
        cams = {}
        for cam in r.cams:
            metrics = run.metrics[cam]
            x, v, a = r.table1_si()[cam]["link"]
            cams[cam] = {
                "stations": {s: _station_dict(st) for s, st in station_metrics(metrics).items()},
                "per_link": {k: getattr(metrics, k).tolist() for k in PER_LINK_KEYS},
                "table1_link": r.table_link,
                "table1_rms_displacement_m": x,
                "table1_rms_velocity_m_s": v,
                "table1_rms_acceleration_m_s2": a,
                "table2_link": r.table2_link,
                "table2_max_abs_acceleration_m_s2": r.table2_si()[cam],
                "report_table1_rms_m": [q * 1e-3 for q in REPORT_TABLE1[name][cam]],
                "report_table2_max_abs_acceleration_m_s2": REPORT_TABLE2[name][cam] * 1e-3,
            }
        materials[name] = {
            "stiffness_N_per_m": r.stiffness_N_per_m,
            "lumped_mass_kg": r.lumped_mass_kg,
            "natural_frequencies_Hz": (np.sort(r.natural_frequencies_rad_s)[:10] / (2 * np.pi)).tolist(),
            "stable": r.stable,
            "cams": cams,
        }
    first = next(iter(runs.values())).replica
    return {
        "inputs": _inputs(cfg),
        "preset": "mqp2012",
        "cams": {
            cam: {
                "input_rms_displacement_m": float(rms(c.z_m)),
                "input_rms_velocity_m_s": float(rms(c.zdot_m_s)),
                "input_rms_acceleration_m_s2": float(rms(c.zddot_m_s2)),
            }
            for cam, c in first.cams.items()
        },
        "materials": materials,
        "timing_s": timing,
    }


def _replica_comparison_table(replicas: dict) -> Table:
    from dynamics.models.mqp2012 import REPORT_TABLE1, REPORT_TABLE2

    rows = []
    quantities = (("RMS displacement (mm)", 0), ("RMS velocity (mm/s)", 1), ("RMS acceleration (mm/s²)", 2))
    for name, r in replicas.items():
        table1 = r.table1()
        for label, i in quantities:
            for cam in r.cams:
                ours, report = table1[cam]["link"][i], REPORT_TABLE1[name][cam][i]
                rows.append((name, label, cam, ours, report, round((ours - report) / report * 100, 3)))
        for cam, ours in r.table2().items():
            report = REPORT_TABLE2[name][cam]
            rows.append(
                (
                    name,
                    f"max |acceleration| link {r.table2_link} (mm/s²)",
                    cam,
                    ours,
                    report,
                    round((ours - report) / report * 100, 3),
                )
            )
    return Table(
        "Replica against the report's Tables 1 and 2",
        ("material", "quantity", "cam law", "replica", "report", "difference (%)"),
        tuple(rows),
    )


def write_replica_outputs(cfg, runs: dict[str, ReplicaRun], timing: dict, progress) -> None:
    replicas = {name: run.replica for name, run in runs.items()}
    with StagedOutput(cfg.out) as staged:
        progress("outputs: tables, plots and report (mqp2012 preset)")
        first = next(iter(replicas.values()))
        link = first.table_link
        histories, at_link = {}, {}
        for name, r in replicas.items():
            for cam, c in r.cams.items():
                histories[name, cam] = CamHistory(
                    name,
                    cam,
                    c.t_s,
                    c.z_m,
                    c.zdot_m_s,
                    c.zddot_m_s2,
                    c.x_m,
                    c.v_m_s,
                    c.a_m_s2,
                    np.zeros_like(c.x_m),
                    c.dwell_mask,
                )
                rx, rv, ra = r.table1_si()[cam]["link"]
                at_link[name, cam] = LinkRms(rx, rv, ra, r.table2_si()[cam])
        comparison = _replica_comparison_table(replicas)
        report_tables = dict(
            zip(("rms_table", "max_acceleration_table"), _tables(histories, at_link, link, first.table2_link))
        )
        tables = {**report_tables, "report_comparison": comparison}
        staged.write_text("tables.md", _write_tables(staged, tables))
        links = station_links(cfg.links)
        cams = list(first.cams)
        figures = _drawn({m: _material_plots(staged, [histories[m, c] for c in cams], links, link) for m in replicas})
        _close_timing(timing, progress)
        summary = replica_summary(cfg, runs, timing)
        staged.write_text("summary.json", json.dumps(summary, indent=1))
        page = replica_sections.PAGE.build(replica_sections.ReplicaReport(cfg, comparison, report_tables, figures))
        staged.write_text("report.html", html.render_page("link-conveyor: mqp2012 replica", page))
    _announce(cfg, staged, timing, progress, comparison)
