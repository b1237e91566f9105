"""`python -m fem`: axial stiffness, mass and peak stress of a link from a STEP file or the default."""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from pathlib import Path

from geometry.options import (
    add_part_arguments,
    hardware_densities,
    hardware_masses_kg,
    link_source,
    signed_values_attached,
)
from geometry.part import resolve_part
from settings import DEFAULT_MATERIALS, RunConfig
from settings.registries import ELEMENT_ORDERS

from .budget import DEFAULT_MAX_MEMORY_GB
from .errors import FemError
from .materials import get_material, load_materials
from .settings import LEVEL_RATIO, FeaSettings
from .study import StiffnessEstimate, stiffness_study

DESCRIPTION = """\
Axial stiffness k (N/m), mass (kg) and peak von Mises stress per newton (Pa/N) of one chain link.
The fixed bore is clamped; the other carries a cosine bearing pressure pulling the link apart.
k is Richardson-extrapolated from two meshes sized relative to the part, with a bound on its
discretisation error for any convergence rate between h^1 and h^5 (h = DOFs^-1/3).
Output is in SI units (the text report adds mm and MPa for reading)."""


class _OneLineParser(argparse.ArgumentParser):
    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(
        prog="python -m fem", description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "step", nargs="?", help="STEP file of one link (any unit the file declares); default: the built-in link"
    )
    parser.add_argument(
        "--material", default=DEFAULT_MATERIALS[0], help="material id from the materials table (default: %(default)s)"
    )
    parser.add_argument(
        "--materials-file",
        help="TOML file of extra materials (SI units: youngs_modulus_Pa, poisson_ratio, density_kg_per_m3)",
    )
    parser.add_argument(
        "--mesh-size",
        type=str,
        metavar="MM",
        help=f"finest element size in millimetres; one coarser level (x{LEVEL_RATIO:.4g}) is added (default: relative "
        "to the part, the smaller of pitch/25 and 0.52 x bore radius: 4.5 and 6 mm on the built-in link)",
    )
    parser.add_argument(
        "--order",
        type=int,
        choices=ELEMENT_ORDERS,
        default=RunConfig.order,
        help="element order: 1 = linear, 2 = quadratic (default)",
    )
    parser.add_argument(
        "--load",
        type=str,
        default="1000",
        metavar="N",
        help="pin load in newtons for the image and fields (default: %(default)s); k is linear",
    )
    parser.add_argument(
        "--solver", default="auto", help="linear solver: auto, pardiso, amg or spsolve (default: %(default)s)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object (SI units) instead of text")
    parser.add_argument("--image", metavar="PNG", help="write an off-screen picture of the deformed link to this .png")
    parser.add_argument(
        "--vtu",
        metavar="VTU",
        help="write the finest level's mesh with displacement (m) and von Mises stress (Pa) at --load, for ParaView",
    )
    parser.add_argument(
        "--converge-stress",
        action="store_true",
        help="converge the peak von Mises stress in a sub-model around the stress hot spots, driven by the "
        "finest k level, until it changes by <= 5 %% (fem.stress; a few small solves); without it the peak "
        "is the k mesh's, not converged",
    )
    parser.add_argument(
        "--full-model",
        action="store_true",
        help="solve the whole link even where it is mirror symmetric about the plane through its bore "
        "axes (default: solve that half, the same k and stresses at about half the unknowns)",
    )
    parser.add_argument(
        "--max-memory",
        type=str,
        default=str(DEFAULT_MAX_MEMORY_GB),
        metavar="GB",
        help="memory budget of the solves in GB, checked before solving: default sizes are coarsened to "
        "fit it, a --mesh-size that does not fit is refused (default: %(default)s, for a 2-core 24 GB "
        "machine shared with other work)",
    )
    parser.add_argument(
        "--scalar",
        choices=("von_mises", "displacement"),
        default="von_mises",
        help="colouring of --image (default: %(default)s)",
    )
    add_part_arguments(parser)
    return parser


def _number(text: str, what: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise FemError(f"{what}: expected a number, got {text!r}") from None


def _positive(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise FemError(f"{what}: expected a positive number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise FemError(f"{what}: expected a positive number, got {text!r}")
    return value


def report(estimate: StiffnessEstimate) -> dict:
    """The JSON-able summary of a stiffness study (SI units)."""
    s = estimate.finest
    return {
        "source": s.link.source,
        "material": s.material.name,
        "order": s.order,
        "curved_elements": s.curved,
        "stiffness_N_per_m": estimate.stiffness_N_per_m,
        "stiffness_rel_error_estimate": estimate.stiffness_rel_error_estimate,
        "stiffness_finest_N_per_m": estimate.stiffness_finest_N_per_m,
        "finest_rel_error_estimate": estimate.finest_rel_error_estimate,
        "rate_bracket": list(estimate.rate_bracket),
        "observed_convergence_rate": estimate.observed_convergence_rate,
        "levels": [{"mesh_size_m": h, "dofs": n, "stiffness_N_per_m": k} for h, n, k in estimate.levels],
        "volume_m3": s.volume_m3,
        "mass_kg": s.mass_kg,
        "density_kg_per_m3": s.material.density_kg_per_m3,
        "pitch_m": s.pitch_m,
        "bore_radius_m": s.bore_radius_m,
        "peak_von_mises_Pa_per_N": s.peak_von_mises_Pa_per_N,
        "peak_von_mises_away_from_clamp_Pa_per_N": s.peak_von_mises_away_from_clamp_Pa_per_N,
        "peak_von_mises_location_m": s.peak_von_mises_location_m,
        "clamp_exclusion_radius_m": s.clamp_exclusion_radius_m,
        "mirror_plane": s.link.mirror_plane.name if s.mirrored else None,
        "mesh_size_m": s.mesh_size_m,
        "tets": s.n_tets,
        "dofs": s.dofs,
        "solver": s.solver,
        "solver_fallback": s.solver_fallback,
        "timing_s": estimate.timing_s,
    }


def _mm(point_m: list[float]) -> str:
    return "(" + ", ".join(f"{x * 1e3:.1f}" for x in point_m) + ")"


def _model_line(r: dict) -> str:
    if r["mirror_plane"] is None:
        return "model           whole link"
    return (
        f"model           half link: mirror symmetric about {r['mirror_plane']}, the plane through both bore "
        "axes (mesh and DOFs below are the half's; --full-model solves the whole)"
    )


def _text(r: dict) -> str:
    levels = "; ".join(
        f"{lv['mesh_size_m'] * 1e3:g} mm: {lv['dofs']} DOFs, k = {lv['stiffness_N_per_m']:.5e}" for lv in r["levels"]
    )
    t = r["timing_s"]
    lines = [
        f"link            {r['source']}",
        f"material        {r['material']} (rho = {r['density_kg_per_m3']:g} kg/m^3)",
        f"pitch           {r['pitch_m'] * 1e3:.3f} mm",
        f"bore radius     {r['bore_radius_m'] * 1e3:.3f} mm",
        f"volume          {r['volume_m3'] * 1e6:.3f} cm^3",
        f"mass            {r['mass_kg']:.4f} kg (link body only)",
        f"stiffness k     {r['stiffness_N_per_m']:.5e} N/m  (estimated discretisation error {r['stiffness_rel_error_estimate'] * 100:.2f} %)",
        f"  finest mesh   {r['stiffness_finest_N_per_m']:.5e} N/m  ({r['finest_rel_error_estimate'] * 100:.2f} % above k; k bracketed for rates h^{r['rate_bracket'][0]:g} to h^{r['rate_bracket'][1]:g})",
        f"peak von Mises  {r['peak_von_mises_Pa_per_N'] * 1e-3:.4g} MPa per kN overall, at {_mm(r['peak_von_mises_location_m'])} mm",
        f"  away from clamp {r['peak_von_mises_away_from_clamp_Pa_per_N'] * 1e-3:.4g} MPa per kN "
        f"(beyond {r['clamp_exclusion_radius_m'] * 1e3:.2f} mm of the clamped bore's rims)",
        _model_line(r),
        f"mesh            finest {r['mesh_size_m'] * 1e3:g} mm, {r['tets']} tets, P{r['order']}{' curved' if r['curved_elements'] else ''}, {r['dofs']} DOFs, solver {r['solver']}",
        f"levels          {levels}",
        "timing          "
        + ", ".join(f"{k} {v:.2f} s" for k, v in t.items() if k != "wall")
        + (f"; wall {t['wall']:.2f} s (levels solved side by side: stage times overlap)" if "wall" in t else ""),
    ]
    if "peak_von_mises_converged_Pa_per_N" in r:
        lines.insert(
            10,
            f"  converged     {r['peak_von_mises_converged_Pa_per_N'] * 1e-3:.4g} MPa per kN at "
            f"{_mm(r['peak_von_mises_converged_location_m'])} mm: {r['stress_description']}",
        )
    else:
        lines.insert(10, "  (the k mesh's peaks, not converged under refinement: --converge-stress converges them)")
    if "image" in r:
        lines.append(f"image           {r['image']} (deformation x{r['exaggeration']:g})")
    if "vtu" in r:
        lines.append(f"vtu             {r['vtu']} (displacement m, von Mises Pa)")
    return "\n".join(lines)


def run(argv: list[str] | None = None) -> dict:
    args = build_parser().parse_args(signed_values_attached(argv))
    materials = load_materials(args.materials_file)
    material = get_material(args.material, materials)
    load_N = _positive(args.load, "--load")
    finest_m = None if args.mesh_size is None else _positive(args.mesh_size, "--mesh-size") * 1e-3
    if args.image is not None and Path(args.image).suffix.lower() != ".png":
        raise FemError(f"--image {args.image!r}: expected a .png path")
    if args.vtu is not None and Path(args.vtu).suffix.lower() != ".vtu":
        raise FemError(f"--vtu {args.vtu!r}: expected a .vtu path")
    source = link_source(args.step, args)
    if source is None and args.hardware_material is not None:
        raise FemError("--hardware-material: only for a STEP file with hardware solids; expected a STEP path with it")
    # resolved once (body and pin bores chosen): refuses a part that cannot be a link before any meshing
    settings = FeaSettings.with_finest(
        finest_m,
        order=args.order,
        load_N=load_N,
        solver=args.solver,
        mirror_symmetry=not args.full_model,
        max_memory_gb=_number(args.max_memory, "--max-memory"),  # its range: settings.LIMITS, via FeaSettings
    )
    part = resolve_part(source, symmetry=settings.mirror_symmetry)
    record = _inspect(part.summary, args, materials) if part.is_step else None
    estimate = stiffness_study(part, material, settings)
    result = report(estimate)
    if record is not None:
        result["part"] = record
    if args.converge_stress:
        from .stress import stress_study

        stress = stress_study(
            part,
            [material],
            settings,
            base_mesh_size_m=estimate.finest.mesh_size_m,
            base={material.name: estimate.finest},
        )[material.name]
        result |= {
            "peak_von_mises_converged_Pa_per_N": stress.peak_Pa_per_N,
            "peak_von_mises_converged_rel_change": stress.rel_change,
            "peak_von_mises_converged_location_m": list(stress.location_m),
            "stress_converged": stress.converged,
            "stress_description": stress.description,
            "stress_seconds": stress.timing_s,
        }
    if args.image is not None:
        from .render import render_deformed

        title = (
            f"{material.name}: k = {estimate.stiffness_N_per_m:.4g} N/m "
            f"(+/- {estimate.stiffness_rel_error_estimate * 100:.1f} %), P{args.order}"
        )
        result["exaggeration"] = render_deformed(estimate.finest, args.image, scalar=args.scalar, title=title)
        result["image"] = str(args.image)
    if args.vtu is not None:
        from .export import write_solution_vtu

        result["vtu"] = str(write_solution_vtu(estimate.finest, args.vtu))
    print(json.dumps(result, indent=2) if args.json else _text(result))
    return result


def _inspect(summary, args, materials) -> dict:
    """The part's pin bores, ignored holes and hardware (JSON-able); printed at once in text mode."""
    part = summary.as_dict()
    lines = summary.lines()
    densities = hardware_densities(
        args.hardware_material, summary, lambda name: get_material(name, materials).density_kg_per_m3
    )
    if densities is not None:
        for record, density, mass in zip(part["hardware"], densities, hardware_masses_kg(summary, densities)):
            record.update(density_kg_per_m3=density, mass_kg=mass)
        part["hardware_mass_kg"] = sum(r["mass_kg"] for r in part["hardware"])
        lines.append(
            f"hardware mass   {part['hardware_mass_kg']:.4f} kg ({len(summary.hardware)} solids, --hardware-material "
            f"{args.hardware_material})"
        )
    if not args.json:
        print("\n".join(lines), flush=True)
    return part


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"python -m fem: warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    warnings.showwarning = _one_line_warning
    try:
        run(argv)
    except (ValueError, OSError) as exc:  # FemError, GeometryError and file-system errors
        message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"python -m fem: error: {message}", file=sys.stderr)
        return 2
    return 0
