"""The tidy record of one design point: its inputs and the metrics a designer compares (SI, unit
suffixes). Made on the workers from the stages' results; only these small dicts travel back."""

from __future__ import annotations

import math

# numba- and SciPy-free (dynamics.options): the study's client describes the columns without the dynamics
from dynamics.options import LINEAR_ELASTIC_STRAIN_LIMIT

#: Metric columns, in table order, with what each one is.
METRICS = {
    "stiffness_N_per_m": "link axial stiffness k (FEA, Richardson-extrapolated)",
    "stiffness_rel_error_estimate": "estimated relative discretisation error of k",
    "body_mass_kg": "link body mass (density x CAD volume)",
    "body_volume_m3": "link body volume",
    "lumped_mass_kg": "chain mass per link: body + hardware + nest",
    "peak_von_mises_converged_Pa_per_N": "peak von Mises stress per newton of pin load, converged by local refinement away from the clamped bore",
    "first_natural_frequency_Hz": "lowest natural frequency of the closed chain as it is driven (on its wheels by default)",
    "residual_vibration_m": "max |x - z| inside the dwells at the study's station",
    "max_residual_vibration_m": "the largest residual vibration over every link",
    "rms_acceleration_m_s2": "RMS acceleration at the station",
    "max_abs_acceleration_m_s2": "max |acceleration| at the station",
    "rms_velocity_m_s": "RMS velocity at the station",
    "max_deviation_m": "max |x - z| at the station over the whole cycle",
    "settling_time_s": "settling into the band after each index at the station (NaN: never)",
    "peak_tension_N": "largest link tension",
    "min_tension_N": "smallest span force (< 0: a span pushes, after its pin free play closed)",
    "loss_of_contact": "some span leaves pulling contact in the cycle (its free play is entered)",
    "free_play_time_fraction": "share of span-time in free play",
    "impacts_per_cycle": "spans closing their free play into contact, per cam cycle",
    "impact_force_spike_N": "largest span force within one impact duration (pi sqrt(m/2k)) of an impact",
    "impact_closing_speed_max_m_s": "largest closing speed of a span entering contact from free play",
    "impact_energy_per_cycle_J": "approach kinetic energy (m/4 v^2) of the impacts, per cam cycle",
    "preload_for_full_contact_N": "preload that would keep every span in pulling contact (linear chain)",
    "linear_model_valid": "the linear chain's numbers (its min tension, the preload for full contact) hold: it "
    f"deforms no span by more than {LINEAR_ELASTIC_STRAIN_LIMIT * 100:g} % of the pitch (on the wheels; empty on the "
    "single-link drive)",
    "preload_above_yield_load": "the preload for full contact is above the link's yield load (yield strength / "
    "peak stress per newton): no designer can apply it (on the wheels)",
    "peak_link_stress_Pa": "peak tension x peak von Mises stress per newton",
    "yield_safety_factor": "yield strength / peak link stress",
}


#: The metrics that are yes / no (None: not known), not numbers.
FLAGS = ("loss_of_contact", "linear_model_valid", "preload_above_yield_load")


def blank_metrics() -> dict:
    """Metrics of a point that was not computed (NaN; the slack flag unknown)."""
    return {name: (None if name in FLAGS else math.nan) for name in METRICS}


def fea_metrics(fea) -> dict:
    """The FEA's share of the metrics, from a stages.fea.MaterialFea."""
    return {
        "stiffness_N_per_m": fea.stiffness_N_per_m,
        "stiffness_rel_error_estimate": fea.stiffness_rel_error_estimate,
        "body_mass_kg": fea.body_mass_kg,
        "body_volume_m3": fea.body_volume_m3,
        "peak_von_mises_converged_Pa_per_N": fea.peak_von_mises_converged_Pa_per_N,
    }


def chain_metrics(scenario, fea, station: str, lumped_mass_kg: float, f1_Hz: float) -> dict:
    """The chain's share, from a stages.chain.Scenario at `station`."""
    at = scenario.stations[station]
    settling = float(scenario.settling_time_s[scenario.history.column(at.link)])
    from dynamics.scene import linear_validity_at_yield

    peak_stress = scenario.contact.peak_tension_N * fea.peak_von_mises_converged_Pa_per_N
    linear = linear_validity_at_yield(scenario.contact, fea.yield_strength_Pa, fea.peak_von_mises_converged_Pa_per_N)
    return {
        "lumped_mass_kg": lumped_mass_kg,
        "first_natural_frequency_Hz": f1_Hz,
        "residual_vibration_m": at.residual_vibration_m,
        "max_residual_vibration_m": float(scenario.metrics.residual_vibration_m.max()),
        "rms_acceleration_m_s2": at.rms_acceleration_m_s2,
        "max_abs_acceleration_m_s2": at.max_abs_acceleration_m_s2,
        "rms_velocity_m_s": at.rms_velocity_m_s,
        "max_deviation_m": at.max_deviation_m,
        "settling_time_s": settling,
        "peak_tension_N": scenario.contact.peak_tension_N,
        "min_tension_N": scenario.contact.min_tension_N,
        "loss_of_contact": bool(scenario.contact.contact_lost),
        "free_play_time_fraction": scenario.contact.free_play_time_fraction,
        "impacts_per_cycle": scenario.contact.impacts_per_cycle,
        "impact_force_spike_N": scenario.contact.impact_force_spike_N,
        "impact_closing_speed_max_m_s": scenario.contact.impacts.closing_speed_max_m_s,
        "impact_energy_per_cycle_J": scenario.contact.impacts.energy_per_cycle_J,
        "preload_for_full_contact_N": scenario.contact.preload_for_full_contact_N,
        "linear_model_valid": None if linear is None else linear.valid,
        "preload_above_yield_load": None if linear is None else linear.preload_above_yield_load,
        "peak_link_stress_Pa": peak_stress,
        "yield_safety_factor": fea.yield_strength_Pa / peak_stress if peak_stress > 0 else math.inf,
    }


def record(point: dict, status: str, reason: str, metrics: dict, fea_warnings: tuple[str, ...] = ()) -> dict:
    """One row of the study table: the point's identity and inputs, status, reason, the FEA's
    cautions (e.g. slivers in the mesh), metrics."""
    return {
        "point": point["index"],
        "point_id": point["point_id"],
        "geometry": point["geometry"],
        **point["inputs"],
        "status": status,
        "reason": reason,
        "fea_warnings": "; ".join(fea_warnings),
        **blank_metrics(),
        **metrics,
    }
