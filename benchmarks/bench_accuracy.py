"""Default accuracy of the clearance chain (issue 24): the default run's station metrics against a
converged run, on the default scene and two others of different speed and clearance.

    python benchmarks/run.py --only accuracy

Each scene: the pipeline's output grid (180 degrees at 4 samples per degree), the clearance model,
periodic steady state where one exists. The Kelvin-Voigt scene at 240 rpm has none (the state still
changes by 2 % per cycle after 60 cycles, at every step: a chaotic response, whose state after 60
cycles no step reproduces): there the window is compared, started from the linear chain's periodic
state (steady_state=False). The default run is `simulate_chain` with nothing but the scene given
(the stability-set step: `ab2` at 0.31 of its limit, euler at 0.25 for Kelvin-Voigt); the controlled
run adds accuracy=1e-3 (the step halved until the station metrics change by at most that, at most
4 times). The converged run is the euler predictor at a fixed 1/32 of euler's quarter-limit step
(against 1/16 it differs by 9e-5 on the default scene, 6e-5 on the 300 rpm one). Error = the largest
relative difference over the four stations' eight metrics (32 numbers,
dynamics.response.fidelity.metric_values). Time: the median of interleaved runs of both.

Second table: the pipeline's default dynamics stage (stages.chain.run_dynamics: 2 materials x 5 cam
laws, the FEA from a private cache made on the first run), default against every scenario with
accuracy=1e-3 (chain_scene patched), the median of interleaved runs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import ClearanceChain
from dynamics.response.fidelity import metric_values, relative_change
from dynamics.response.metrics import link_metrics, station_metrics
from dynamics.scene import simulate_chain

PITCH_M = 0.1125
TARGET = 1e-3
CONTROLLED = {"accuracy": TARGET}  # the step halved until the station metrics change by at most TARGET
CONVERGED = {"predictor": "euler", "safety": 0.25 / 32, "accuracy": None}


@dataclass(frozen=True)
class Scene:
    label: str
    n_links: int
    rpm: float
    clearance_m: float
    span_damping: str
    steady_state: bool = True
    cam: str = "modified-sine"
    stiffness_N_per_m: float = 9.0092e7  # the default link's FEA k (aluminium) and lumped mass
    link_mass_kg: float = 2.03

    def model(self) -> ClearanceChain:
        chain = ChainModel(
            n_links=self.n_links,
            link_mass_kg=self.link_mass_kg,
            stiffness_N_per_m=self.stiffness_N_per_m,
            friction_coefficient=0.35,
        )
        return ClearanceChain(chain, self.clearance_m, span_damping=self.span_damping)

    def window(self):
        t = np.arange(721) / 4 / (6 * self.rpm)
        return CamProgram.indexing(self.cam, pitch_m=PITCH_M, rpm=self.rpm), t


SCENES = (
    Scene("default: 85 links, 180 rpm, 0.094 mm, global damping", 85, 180.0, 94e-6, "global"),
    Scene(
        "41 links, 240 rpm, 0.094 mm, Kelvin-Voigt (window: no steady state)",
        41,
        240.0,
        94e-6,
        "kelvin-voigt",
        steady_state=False,
    ),
    Scene("85 links, 300 rpm, 1 mm free play, global damping", 85, 300.0, 1e-3, "global"),
)


def station_values(scene: Scene, **options) -> tuple[np.ndarray, float, int, float | None]:
    """(station metrics, wall seconds, steps per output sample, the run's own error estimate) of one
    run of the scene; `options` go to simulate_chain."""
    model = scene.model()
    cam, t = scene.window()
    start = time.perf_counter()
    r, contact = simulate_chain(model, cam, t, steady_state=scene.steady_state, **options)
    wall = time.perf_counter() - start
    assert contact.model == "clearance", contact.reason
    lm = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, cam.dwell_mask(t))
    values = metric_values(station_metrics(lm))
    return values, wall, contact.steps_per_output, contact.step_error_estimate


def worst_error(x: np.ndarray, ref: np.ndarray) -> float:
    return relative_change(x, ref)


def scene_rows(scene: Scene, repeats: int) -> tuple[str, float]:
    ref = station_values(scene, **CONVERGED)[0]
    default, _, sub, _ = station_values(scene)
    controlled, _, controlled_sub, estimate = station_values(scene, **CONTROLLED)
    walls = [(station_values(scene)[1], station_values(scene, **CONTROLLED)[1]) for _ in range(repeats)]
    default_s, controlled_s = (float(np.median([w[i] for w in walls])) for i in (0, 1))
    err = worst_error(default, ref)
    controlled_err = worst_error(controlled, ref)
    return (
        f"| {scene.label} | {sub} | {err:.1e} | {1e3 * default_s:.0f} ms | {controlled_sub} | {estimate:.1e} | "
        f"{controlled_err:.1e} | {1e3 * controlled_s:.0f} ms |"
    ), (err, controlled_err)


def stage_rows(repeats: int) -> list[str]:
    """The default dynamics stage's time, default and controlled, with the steps per sample used."""
    import tempfile
    from dataclasses import replace

    import pipeline
    from stages import chain
    from stages.fea import run_fea
    from stages.geometry import inspect_geometry

    def quiet(*_args, **_kwargs):
        return None

    default_scene = chain.chain_scene
    with tempfile.TemporaryDirectory() as cache:
        cfg, part = inspect_geometry(pipeline.parse_cli(["--cache-dir", cache, "-q"]), quiet)
        fea = run_fea(cfg, quiet, part=part)

        def timed(accuracy):
            chain.chain_scene = lambda c: replace(default_scene(c), accuracy=accuracy)
            try:
                start = time.perf_counter()
                _, scenarios = chain.run_dynamics(cfg, fea, quiet)
                return time.perf_counter() - start, sorted({s.contact.steps_per_output for s in scenarios.values()})
            finally:
                chain.chain_scene = default_scene

        runs = [(timed(None), timed(TARGET)) for _ in range(repeats)]
    rows = []
    for label, i in (("default", 0), (f"accuracy={TARGET:g}", 1)):
        wall = float(np.median([r[i][0] for r in runs]))
        rows.append(f"| {label} | {wall:.2f} s | {runs[-1][i][1]} |")
    return [
        "",
        f"The default dynamics stage (2 materials x 5 cam laws; median of {repeats} interleaved runs)",
        "",
        "| clearance chain's step | time | steps/sample used |",
        "|---|---|---|",
        *rows,
    ]


def run(quick: bool) -> list[str]:
    repeats = 3 if quick else 7
    lines = [
        "Default accuracy of the clearance chain: the default and the controlled (accuracy=1e-3) runs' 32 "
        "station metrics against a converged run (euler at 1/32 of its quarter-limit step), worst relative "
        "error; time = median of interleaved runs (steady state + window, one scenario)",
        "",
        "| scene | steps/sample (default) | worst error | time | steps/sample (controlled) | own estimate | "
        "worst error | time |",
        "|---|---|---|---|---|---|---|---|",
    ]
    station_values(SCENES[0])  # compile / load the numba cache
    worst = np.zeros(2)
    for scene in SCENES:
        row, errors = scene_rows(scene, repeats)
        lines.append(row)
        worst = np.maximum(worst, errors)
    lines.append("")
    for label, err in zip(("default", "controlled"), worst):
        lines.append(
            f"worst error of the {label} run over the scenes: {err:.2e} (target {TARGET:g}: "
            f"{'met' if err <= TARGET else 'NOT met'})"
        )
    return lines + stage_rows(1 if quick else 3)


if __name__ == "__main__":
    print("\n".join(run(quick=False)))
