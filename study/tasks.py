"""What runs on the workers: one FEA per geometry (one mesh per level, shared by its materials), a
batch of chain runs per FEA result, and the full pipeline report of a chosen design.

Each task takes and returns small picklable values, so workers need no shared disk; each returns
its own wall time and worker so the client can keep per-task timings.
"""

from __future__ import annotations

import contextlib
import io
import os
import socket
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from settings import RunConfig
from study.records import chain_metrics, fea_metrics, record
from study.spec import Settings
from study.variables import GEOMETRY_TARGETS, VARIABLES, link_dimensions, run_fields
from study.worker_malloc import keep_large_arrays_on_heap


def base_config(settings: Settings, cache_dir: Path | None = None) -> RunConfig:
    """The default run (RunConfig()) with the study's settings (quiet, no images)."""
    cfg = RunConfig()
    return replace(
        cfg,
        quiet=True,
        images=False,
        mesh_size_m=settings.mesh_size_m,
        order=settings.order,
        samples_per_degree=settings.samples_per_degree,
        solver=settings.solver,
        settling_band_m=settings.settling_band_m,
        steady_state=settings.steady_state,
        drive=settings.drive,
        cache_dir=cfg.cache_dir if cache_dir is None else cache_dir,
    )


def point_config(settings: Settings, inputs: dict, cache_dir: Path | None = None) -> RunConfig:
    """The RunConfig of one design point."""
    geometry_values = {
        n: v
        for n, v in inputs.items()
        if n in VARIABLES and VARIABLES[n].target in GEOMETRY_TARGETS and n != "rail_width_m"
    }
    return replace(
        base_config(settings, cache_dir),
        link=link_dimensions(geometry_values),
        **run_fields(
            {n: v for n, v in inputs.items() if n in VARIABLES and VARIABLES[n].target not in GEOMETRY_TARGETS}
        ),
    )


def _worker() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def _timing(start: float, cpu_start: float) -> dict:
    """Wall seconds, CPU seconds of the worker process (CPU < wall: the task waited for a core)."""
    return {"seconds": time.perf_counter() - start, "cpu_seconds": time.process_time() - cpu_start, "worker": _worker()}


def _one_thread():
    """Parallelism comes from the workers: each task keeps BLAS/MKL to one thread."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1)


def part_payload(part, options: dict) -> dict:
    """What an FEA task of a STEP link takes along (study.spec.PartFile and the part options): the
    file's bytes, so the worker needs no shared disk."""
    return {"name": part.name, "data": part.data, "options": dict(options)}


def part_payloads(spec) -> dict:
    """part_payload of every STEP file of a study (study.spec.StudySpec), by geometry_file name."""
    return {name: part_payload(part, spec.part_options) for name, part in spec.parts.items()}


def _on_part(cfg, part: dict | None, scratch: Path):
    """(cfg, geometry.part.Part) on the STEP file that came with the task (written into the task's
    scratch folder under its own file name), with the part options, its body and bores chosen:
    pipeline.py's geometry stage. The FEA cache is keyed by the file's contents, so the scratch path
    does not matter. (cfg, None) for the built-in link: run_fea resolves it."""
    if part is None:
        return cfg, None
    from stages.geometry import inspect_geometry
    from stages.progress import Progress
    from study.spec import part_source

    folder = scratch / "part"
    folder.mkdir()
    path = folder / Path(part["name"]).name
    path.write_bytes(part["data"])
    options = part["options"]
    cfg = replace(
        cfg,
        geometry=path,
        link_source=part_source(path, options),
        hardware_material=options.get("hardware_material"),
        hardware_from_step=bool(options.get("hardware_from_step", False)),
    )
    return inspect_geometry(cfg, Progress(True))


def fea_task(inputs: dict, materials: tuple[str, ...], settings: Settings, part: dict | None = None) -> dict:
    """k, mass and stress of one geometry for each material, or why the link cannot be built (a STEP
    part refused: no bore pair, an ambiguous choice...); `part`: part_payload of a STEP link."""
    from dynamics.errors import DynamicsError
    from fem.errors import FemError
    from geometry.errors import GeometryError
    from stages.fea import run_fea
    from stages.progress import Progress

    keep_large_arrays_on_heap()
    start, cpu_start = time.perf_counter(), time.process_time()
    reason, fea, hardware_mass_kg = None, None, None
    with tempfile.TemporaryDirectory(prefix="study-fea-") as scratch, _one_thread():
        try:
            cfg = replace(
                point_config(settings, inputs, None if settings.fea_cache else Path(scratch)),
                materials=tuple(materials),
            )
            with contextlib.redirect_stderr(io.StringIO()):  # the cautions travel in the records instead
                cfg, resolved = _on_part(cfg, part, Path(scratch))
                fea = run_fea(cfg, Progress(True), concurrent_levels=False, part=resolved)  # one task per core already
            hardware_mass_kg = cfg.hardware_mass_kg if cfg.hardware_from_step else None
        except (GeometryError, FemError, DynamicsError) as e:
            reason = f"geometry: {e}" if isinstance(e, GeometryError) else f"FEA: {e}"
            if part is not None:  # name the study's file, not the worker's scratch copy
                reason = reason.replace(str(Path(scratch) / "part" / Path(part["name"]).name), part["name"])
            reason = " ".join(reason.split())
    return {"fea": fea, "reason": reason, "hardware_mass_kg": hardware_mass_kg, **_timing(start, cpu_start)}


def chain_task(fea_outcome: dict, material: str, points: list[dict], settings: Settings) -> dict:
    """The chain of every point in the batch, on one FEA result; one record per point."""
    from dynamics.errors import DynamicsError
    from stages.chain import chain_model, chain_scene, natural_frequencies_Hz, scene_that_ran, simulate_scenario

    start, cpu_start = time.perf_counter(), time.process_time()
    rows = []
    if fea_outcome["reason"] is not None:
        rows = [record(p, "infeasible", fea_outcome["reason"], {}) for p in points]
        return {"rows": rows, **_timing(start, cpu_start)}
    fea = fea_outcome["fea"][material]
    frequencies: dict = {}
    measured_hardware_kg = fea_outcome.get("hardware_mass_kg")  # hardware_from_step: the STEP file's solids
    with _one_thread():
        for p in points:
            if measured_hardware_kg is not None:
                p = {**p, "inputs": {**p["inputs"], "hardware_mass_kg": measured_hardware_kg}}
            cfg = point_config(settings, p["inputs"])
            model = chain_model(cfg, fea)
            try:
                scenario = simulate_scenario(
                    cfg, model, material, p["inputs"]["cam"], fea.pitch_m, settings.samples_per_degree
                )
                # f1 of the model that ran: the tooth model's where the point switched to it (as the pipeline)
                scene = scene_that_ran(chain_scene(cfg, fea.pitch_m), [scenario])
                if (model, scene) not in frequencies:
                    frequencies[model, scene] = float(natural_frequencies_Hz(scene, model, 1)[0])
            except DynamicsError as e:
                rows.append(record(p, "infeasible", f"chain: {e}", fea_metrics(fea), fea.warnings))
                continue
            metrics = {
                **fea_metrics(fea),
                **chain_metrics(scenario, fea, settings.station, model.link_mass_kg, frequencies[model, scene]),
            }
            rows.append(record(p, "ok", "", metrics, fea.warnings))
    return {"rows": rows, **_timing(start, cpu_start)}


def report_task(inputs: dict, cams: tuple[str, ...], settings: Settings, part: dict | None = None) -> dict[str, bytes]:
    """pipeline.py's full report of one design (its material, the study's cam laws): the files'
    bytes, so the client writes them and the worker needs no shared disk (nor for the STEP `part`)."""
    from reporting.outputs import write_default_outputs
    from stages.chain import RunResults, run_dynamics
    from stages.fea import FeaInProgress, run_fea
    from stages.progress import Progress

    keep_large_arrays_on_heap()
    with tempfile.TemporaryDirectory(prefix="study-report-") as scratch, _one_thread():
        out = Path(scratch) / "report"
        out.mkdir()
        cfg = replace(point_config(settings, inputs), cams=tuple(cams), out=out, station=None, images=True)
        cfg, resolved = _on_part(cfg, part, Path(scratch))
        progress = Progress(True)
        fea = run_fea(cfg, progress, part=resolved)
        chains, scenarios = run_dynamics(cfg, fea, progress)
        write_default_outputs(RunResults(cfg, FeaInProgress.done(fea), chains, scenarios, {}, {}), progress)
        return {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.is_file()}
