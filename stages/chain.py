"""The chain stage: every material x cam law simulated, and the optional speed sweep."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from settings import RunConfig
from stages.fea import FeaInProgress, MaterialFea, MaterialStiffness
from stages.progress import Progress

if TYPE_CHECKING:  # numpy, scipy and the dynamics load when a stage runs, not when it is imported
    import numpy as np

    from dynamics.models.chain import ChainModel
    from dynamics.response.metrics import LinkMetrics, StationMetrics, TensionExtremes
    from dynamics.response.sweep import SweepResult
    from dynamics.scene import ContactSummary, Scene
    from dynamics.search_progress import SearchProgress
    from reporting.history import CamHistory
    from stages.machine import MachineCycle, MachineParts

CYCLE_DEG = 90.0  # one index cycle (index and dwell) of the cam programs the stage runs, in cam degrees
K_PROBES = 8  # k errors stiffness_error_allowed tries below the FEA's (each a run of the scenario)


@dataclass(frozen=True)
class Scenario:
    """One material x cam law: its histories (for plots), its metrics and their error estimate."""

    history: CamHistory
    metrics: LinkMetrics
    stations: dict[str, StationMetrics]  # station name -> its link's metrics
    tension: TensionExtremes
    samples_per_degree: int
    rel_error_estimate: dict[str, float] | None  # {"time_step", "stiffness", "total"} when --tolerance is given
    settling_time_s: np.ndarray  # per link, the longest settling into --settling-band over the dwells (NaN: never)
    contact: ContactSummary  # which model ran, why and whether it holds; free play, impacts
    machine: MachineCycle | None = None  # the seat changes of an index on the wheels (None: the link drive)


@dataclass(frozen=True)
class MaterialChain:
    """One material's chain as the dynamics stage made it, with the lowest natural frequencies of the
    model its scenarios ran (the tooth model's where they switched to it: `scene_that_ran`)."""

    model: ChainModel
    # the lowest machine_modes.REPORTED_MODES of the machine (fewer for a shorter chain)
    natural_frequencies_Hz: np.ndarray
    machine: MachineParts  # which parts of the machine ran, and the stations


@dataclass
class RunResults:
    """Everything one run computed, for the outputs: they format it and compute no physics of their own.
    `fea_run` may still be under way beside the run (stages.fea.start_fea: the stress study and the
    images); the chain's results, which the figures need, are complete."""

    cfg: RunConfig
    fea_run: FeaInProgress
    chains: dict[str, MaterialChain]
    scenarios: dict[tuple[str, str], Scenario]  # (material, cam law) -> its scenario
    sweeps: dict[str, SweepResult]  # material -> its speed sweep (empty without --rpm-sweep)
    timing: dict[str, float]  # wall seconds per stage; the outputs add theirs
    tolerance_shortfall: str | None = None  # --tolerance: why it is not met (None: met, or no --tolerance)

    @property
    def fea(self) -> dict[str, MaterialFea]:
        """Each material's complete FEA (waits for the FEA beside, see `wait_for_fea`)."""
        return self.fea_run.result()

    def wait_for_fea(self, progress: Progress) -> None:
        """Wait for the FEA's stress study and images where they run beside; the wait is booked to the FEA."""
        start = progress.elapsed()
        self.fea_run.result()
        self.timing["fea"] = self.timing.get("fea", 0.0) + progress.elapsed() - start
        if self.fea_run.beside:
            progress(f"FEA stress study and images: done, waited {progress.elapsed() - start:.1f} s for them")


def output_times_s(rpm: float, samples_per_degree: int, window_deg: float = 180.0) -> np.ndarray:
    """Output samples over the report's 180 deg window (two index cycles)."""
    import numpy as np

    degrees = np.arange(int(round(window_deg * samples_per_degree)) + 1) / samples_per_degree
    return degrees / (6.0 * rpm)


def chain_scene(cfg: RunConfig, pitch_m: float) -> Scene:
    """The chain beyond its linear model, as the dynamics take it (the settings are checked already);
    `pitch_m` is the link's (the FEA's), which the wheels are sized on."""
    from dynamics.models.tensioner import tensioner_from
    from dynamics.scene import Scene
    from stages.machine import machine_layout

    return Scene(
        cfg.pin_clearance_m,
        cfg.span_damping,
        tensioner_from(cfg.tensioner_rate_N_per_m, cfg.tensioner_mass_kg, cfg.tensioner_damping_N_s_per_m),
        cfg.model,
        cfg.steady_state,
        cfg.solver,
        machine_layout(cfg, pitch_m),
        # --tolerance: a quarter of it to the clearance chain's step, a quarter to the output sampling
        accuracy=None if cfg.tolerance is None or cfg.model == "linear" else cfg.tolerance / 4,
    )


def natural_frequencies_Hz(scene: Scene, model: ChainModel, count: int | None = None) -> np.ndarray:
    """The lowest `count` (None: machine_modes.REPORTED_MODES) natural frequencies of the chain as the
    scene carries it (the link drive's chain, or the machine on its wheels), with the idler tensioner's
    carriage where there is one. A machine's come from its one cached eigensolve
    (dynamics.solvers.machine_modes), which its scenarios' lowest_mode and nearest_resonance came from:
    the reported f1 is lowest_mode's frequency."""
    from dynamics.models.reduction import lowest_natural_frequencies_Hz
    from dynamics.solvers.machine_modes import REPORTED_MODES, lowest_frequencies_Hz
    from stages.machine import scene_machine

    count = REPORTED_MODES if count is None else count
    if not scene.layout.on_wheels and scene.tensioner is None:
        return lowest_natural_frequencies_Hz(model, count)
    # the carriage is a DOF of the chain's topology; the link drive's machine carries it too
    return lowest_frequencies_Hz(scene_machine(scene, model), count)


def chain_model(cfg: RunConfig, result: MaterialStiffness, stiffness_N_per_m: float | None = None) -> ChainModel:
    from dynamics.models.chain import ChainModel

    return ChainModel(
        n_links=cfg.links,
        link_mass_kg=result.body_mass_kg + cfg.hardware_mass_kg + cfg.nest_mass_kg,
        stiffness_N_per_m=result.stiffness_N_per_m if stiffness_N_per_m is None else stiffness_N_per_m,
        damping_ratio=cfg.damping,
        rayleigh_coefficients=cfg.rayleigh,
        preload_N=cfg.preload_N,
        friction_coefficient=cfg.friction,
    )


def simulate_scenario(
    cfg: RunConfig,
    model,
    material: str,
    cam_id: str,
    pitch_m: float,
    samples_per_degree: int,
    search_progress: SearchProgress | None = None,
) -> Scenario:
    """One material x cam law at `samples_per_degree`; `search_progress` told how a long chain's
    steady-state search goes (dynamics.search_progress)."""
    from dataclasses import replace

    import numpy as np

    from dynamics.cams import CamProgram
    from dynamics.machine_scene import every_step_metrics
    from dynamics.models.reduction import modes_to_keep
    from dynamics.response.metrics import link_metrics, settling_times, tension_extremes
    from dynamics.scene import simulate_scene
    from reporting.history import CamHistory
    from stages.machine import machine_cycle, machine_parts, seating_that_runs

    t = output_times_s(cfg.rpm, samples_per_degree)
    cam = CamProgram.indexing(cam_id, pitch_m=pitch_m, rpm=cfg.rpm)
    scene = chain_scene(cfg, pitch_m)
    places = machine_parts(scene, model).stations
    # a one-station question keeps one link's history (the spring tensions are kept whole: they are
    # what the slack check and the stress need)
    kept = None if cfg.station is None else (places[cfg.station],)

    # left: rigid seating's verdict where the run leaves it for the tooth model (decided before the run)
    scene, left = seating_that_runs(cfg, scene, model, cam, t)
    r, contact = simulate_scene(
        scene,
        model,
        cam,
        t,
        links=None if kept is None else [link - 1 for link in kept],
        n_modes=modes_to_keep(cfg.links),
        progress=search_progress,
    )
    history = CamHistory(
        material,
        cam_id,
        t,
        r.z_m,
        r.zdot_m_s,
        r.zddot_m_s2,
        r.x_m,
        r.v_m_s,
        r.a_m_s2,
        r.tension_N,
        cam.dwell_mask(t),
        kept,
    )
    metrics = link_metrics(r.x_m, r.v_m_s, r.a_m_s2, r.z_m, r.zdot_m_s, r.zddot_m_s2, history.dwell_mask)
    if kept is None:
        stations = {name: metrics.at_link(link) for name, link in places.items()}
    else:
        stations = {cfg.station: replace(metrics.at_link(1), link=kept[0])}
    # the machine kernel's peaks and RMS over every step (ContactSummary.peak_sampling), where it took them
    every_step = every_step_metrics(r)
    stations = {name: replace(s, **every_step.get(name, {})) for name, s in stations.items()}
    settling = settling_times(t, r.x_m, r.z_m, history.dwell_mask, cfg.settling_band_m).settling_time_s
    # a link that stays outside the band in any dwell has not settled: NaN wins over the maximum
    worst = np.where(np.isnan(settling).any(axis=0), np.nan, np.nanmax(settling, axis=0, initial=0.0))
    seats = None
    if contact.seating is not None:
        seats = machine_cycle(contact.seating, scene.steady_state, *_cam_peaks(r), scene.layout, left)
    return Scenario(
        history, metrics, stations, tension_extremes(r.tension_N), samples_per_degree, None, worst, contact, seats
    )


def _cam_peaks(response) -> tuple[float, float]:
    """The cam's largest speed and acceleration over the window (the scale of its state at a seat change)."""
    import numpy as np

    return float(np.max(np.abs(response.zdot_m_s))), float(np.max(np.abs(response.zddot_m_s2)))


def scenario_to_tolerance(
    cfg: RunConfig,
    result: MaterialStiffness,
    material: str,
    cam_id: str,
    search_progress: SearchProgress | None = None,
) -> Scenario:
    """Finest sampling the tolerance needs, with the error estimate from the step and from k;
    `search_progress` as simulate_scenario's."""
    from dataclasses import replace

    from dynamics.response.fidelity import choose_samples_per_degree, stiffness_sensitivity

    model = chain_model(cfg, result)
    runs: dict[int, Scenario] = {}

    def stations_at(spd: int):
        runs[spd] = simulate_scenario(cfg, model, material, cam_id, result.pitch_m, spd, search_progress)
        return runs[spd].stations

    # the time step's half of the tolerance: the output sampling's, less the clearance chain step's share
    integrator_share = chain_scene(cfg, result.pitch_m).accuracy or 0.0
    choice, stations = choose_samples_per_degree(stations_at, cfg.tolerance / 2 - integrator_share)
    spd = choice.samples_per_degree
    k_error = stiffness_sensitivity(
        lambda k: (
            simulate_scenario(
                cfg, chain_model(cfg, result, k), material, cam_id, result.pitch_m, spd, search_progress
            ).stations
        ),
        result.stiffness_N_per_m,
        result.stiffness_rel_error_estimate,
        stations,
    )
    # the clearance chain's own step error (its halvings' last change, at most tolerance / 4: chain_scene)
    # adds to the output sampling's (at most the other quarter)
    integrator = runs[spd].contact.step_error_estimate or 0.0
    estimate = {
        "time_step": choice.rel_error_estimate + integrator,
        "stiffness": k_error,
        "total": choice.rel_error_estimate + integrator + k_error,
    }
    return replace(runs[spd], rel_error_estimate=estimate)


def run_dynamics(
    cfg: RunConfig, fea: dict[str, MaterialStiffness], progress: Progress
) -> tuple[dict[str, MaterialChain], dict[tuple[str, str], Scenario]]:
    """Simulate every material x cam law; returns each material's chain and the scenarios. The
    chain needs the FEA's stiffness, mass and pitch only (a `MaterialFea` is one too)."""
    from stages.machine import machine_parts

    models = {name: chain_model(cfg, result) for name, result in fea.items()}
    tasks = [(name, cam_id) for name in fea for cam_id in cfg.cams]
    if _in_workers(cfg, len(tasks)):
        scenarios = _scenarios_in_workers(cfg, fea, models, tasks, progress)
    else:
        scenarios = {}
        for name, cam_id in tasks:
            scenarios[name, cam_id] = _scenario(cfg, fea[name], models[name], name, cam_id, progress)
            _say_scenario(cfg, scenarios[name, cam_id], name, cam_id, (len(scenarios), len(tasks)), progress)
    chains = {}
    for name, result in fea.items():
        ran = [scenarios[name, cam_id] for cam_id in cfg.cams]
        scene = scene_that_ran(chain_scene(cfg, result.pitch_m), ran)
        chains[name] = MaterialChain(
            models[name], natural_frequencies_Hz(scene, models[name]), machine_parts(scene, models[name])
        )
        progress(
            f"dynamics {name}: {len(cfg.cams)} cam laws, N = {cfg.links}, "
            f"f1 = {chains[name].natural_frequencies_Hz[0]:.1f} Hz" + _modal_note(cfg.links, scene, ran)
        )
    return chains, scenarios


def _scenario(cfg: RunConfig, result: MaterialStiffness, model, name: str, cam_id: str, progress: Progress) -> Scenario:
    """One material x cam law: at the default samples per degree, or to --tolerance; a long search's
    progress lines (dynamics.search_progress) named by the scenario."""
    from dynamics.search_progress import SearchProgress

    search_progress = SearchProgress(lambda line: progress(f"dynamics {name} / {cam_id}: {line}"))
    if cfg.tolerance is None:
        return simulate_scenario(cfg, model, name, cam_id, result.pitch_m, cfg.samples_per_degree, search_progress)
    return scenario_to_tolerance(cfg, result, name, cam_id, search_progress)


def _say_scenario(
    cfg: RunConfig, sc: Scenario, name: str, cam_id: str, count: tuple[int, int], progress: Progress
) -> None:
    """A scenario's progress lines: on a long chain (above SCENARIO_WORKERS_ABOVE_LINKS links, seconds
    to minutes a scenario) that it is done, `count` = (scenarios done, of); its estimated error
    (--tolerance); its seating switch."""
    if cfg.links > SCENARIO_WORKERS_ABOVE_LINKS:
        progress(f"dynamics {name} / {cam_id}: done ({count[0]} of {count[1]} scenarios)")
    if cfg.tolerance is not None:
        progress(
            f"dynamics {name} / {cam_id}: {sc.samples_per_degree} samples per degree, "
            f"estimated error {100 * sc.rel_error_estimate['total']:.2g} % (time step "
            f"{100 * sc.rel_error_estimate['time_step']:.2g} %, k {100 * sc.rel_error_estimate['stiffness']:.2g} %)"
        )
    _say_seating_switch(sc, f"{name} / {cam_id}", progress)


# Above this many links (the O(N) damping's range) the dynamics stage runs its scenarios in worker
# processes forked from the run, one per core (`_scenarios_in_workers`): a scenario there takes from
# about 0.8 s (500 links) to minutes (10,000), the fork and its result's pickling hundredths of a
# second; the dynamics stage 5.6 against 8.2 s at 500 links, 12.8 against 20.3 s at 1,000 (docs/
# performance.md, "The pipeline at long lengths: a scenario per core"). Shorter chains gain too where
# the FEA is cached (the dynamics stage 1.0 against 1.6 s at 85 links, 9.2 against 15.5 s at 400), but
# not the default job from an empty cache, whose stress study and images take the other core beside
# the dynamics (9.67 against 9.19 s, everything in workers against this rule): they run here.
SCENARIO_WORKERS_ABOVE_LINKS = 400


def _in_workers(cfg: RunConfig, scenarios: int) -> bool:
    """Whether the scenarios run in worker processes: a long chain, more than one scenario, more than
    one core, --serial not given, and a process that may fork children (not a Dask worker)."""
    from processes import may_fork_children, usable_cores

    return (
        cfg.scenario_workers
        and cfg.links > SCENARIO_WORKERS_ABOVE_LINKS
        and scenarios > 1
        and usable_cores() > 1
        and may_fork_children()
    )


def _scenarios_in_workers(cfg: RunConfig, fea, models, tasks, progress: Progress) -> dict:
    """{(material, cam law): Scenario} of every task, each in a worker process forked from this one
    (processes.forked_map: the kernels and modules loaded here, nothing imported again), one worker
    per core; each scenario's progress lines as it ends, with how many have; the dict in the tasks'
    order, as the serial loop makes it. The workers run the same code on the same inputs: the same
    results to the bit."""
    from concurrent.futures.process import BrokenProcessPool

    from dynamics.errors import DynamicsError
    from processes import forked_map, usable_cores

    ended = []

    def say(i: int, scenario: Scenario) -> None:
        ended.append(i)
        _say_scenario(cfg, scenario, *tasks[i], (len(ended), len(tasks)), progress)

    try:
        scenarios = forked_map(
            _scenario_of_task,
            [(cfg, fea[name], models[name], name, cam_id, progress) for name, cam_id in tasks],
            min(usable_cores(), len(tasks)),
            on_each=say,
        )
    except BrokenProcessPool as e:
        raise DynamicsError(
            f"the dynamics: a scenario's worker process ended early ({e}); rerun with --serial to run the "
            "scenarios one after the other in one process (less memory at once)"
        ) from None
    return dict(zip(tasks, scenarios))


def _scenario_of_task(task: tuple) -> Scenario:
    """In a forked worker: one scenario of _scenarios_in_workers, (cfg, FEA result, model, material, cam,
    progress: its lines written from the worker)."""
    return _scenario(*task)


def _modal_note(links: int, scene: Scene, scenarios: list[Scenario]) -> str:
    """The progress line's note on the scenarios whose answer is the linear chain solved in its lowest
    modes (the single-link drive above DENSE_LINK_LIMIT links, where the linear chain is the answer:
    the chain on its wheels and the clearance chain are not solved in modes), "" where none is."""
    from dynamics.models.reduction import modes_to_keep
    from dynamics.scene import ChainModelKind

    modes = modes_to_keep(links)
    modal = sum(sc.contact.model == ChainModelKind.LINEAR for sc in scenarios)
    if modes is None or scene.layout.on_wheels or not modal:
        return ""
    which = "" if modal == len(scenarios) else f" ({modal} of {len(scenarios)} cam laws)"
    return f", the linear chain solved in its {modes} lowest modes{which}"


def scene_that_ran(scene: Scene, scenarios: list[Scenario]) -> Scene:
    """The scene as the material's scenarios ran it, for the modes reported beside them: with their
    tooth contact stiffness where they switched to it (--tooth-stiffness auto, rigid seating invalid;
    the switch is the tooth phase's, the same for every cam law but within 1e-3 of a dwell, where a
    law that switched wins: the modes are then the tooth model's)."""
    from dataclasses import replace

    ran = [
        sc.machine.seating_validity.tooth_stiffness_N_per_m
        for sc in scenarios
        if sc.machine is not None and sc.machine.seating_validity.switched_from is not None
    ]
    if not ran:
        return scene
    return replace(scene, layout=replace(scene.layout, tooth_stiffness_N_per_m=ran[0]))


def _say_seating_switch(scenario: Scenario, name: str, progress: Progress) -> None:
    """The progress line of a scenario that left rigid seating for the tooth contact stiffness."""
    validity = None if scenario.machine is None else scenario.machine.seating_validity
    if validity is not None and validity.switched_from is not None:
        progress(
            f"dynamics {name}: rigid seating does not hold (the seats change inside the index, with the cam "
            f"moving): switched to seating through a tooth contact stiffness of "
            f"{validity.tooth_stiffness_N_per_m:.3g} N/m (--tooth-stiffness rigid keeps rigid seating)"
        )


def run_rpm_sweeps(cfg: RunConfig, fea: dict[str, MaterialStiffness], progress: Progress) -> dict[str, SweepResult]:
    """Speed sweep per material on the model the run uses, without friction: on the wheels the linear
    machine at each speed on the run's output grid (dynamics.response.sweep.machine_rpm_sweep), on
    the link drive its linear chain's modal sweep (the fast modal path cannot carry friction)."""
    from dataclasses import replace

    from dynamics.machine_scene import machine_model
    from dynamics.models.reduction import modes_to_keep
    from dynamics.response.sweep import machine_rpm_sweep, parse_rpm_range, rpm_sweep

    rpms = parse_rpm_range(cfg.rpm_sweep)
    sweeps = {}
    for name, result in fea.items():
        model = replace(chain_model(cfg, result), friction_coefficient=0.0)
        scene = chain_scene(cfg, result.pitch_m)
        if scene.layout.on_wheels:
            sweeps[name] = machine_rpm_sweep(
                machine_model(scene, model),
                cfg.cams,
                rpms,
                pitch_m=result.pitch_m,
                station=cfg.focus_station,
                samples_per_cycle=int(round(CYCLE_DEG * cfg.samples_per_degree)),
                done=lambda cam_id, name=name: progress(
                    f"speed sweep {name} / {cam_id}: {rpms.size} speeds on the linear machine, done"
                ),
                model_at=_seating_at_each_speed(cfg, scene, model),
            )
        else:
            sweeps[name] = rpm_sweep(
                model,
                cfg.cams,
                rpms,
                pitch_m=result.pitch_m,
                station=cfg.focus_station,
                n_modes=modes_to_keep(cfg.links),
            )
        progress(
            f"speed sweep {name}: {rpms.size} speeds x {len(cfg.cams)} cam laws on {sweeps[name].model}, "
            f"{len(sweeps[name].critical_speeds)} critical speeds in range"
            + (" (friction left out of the sweep)" if cfg.friction > 0 else "")
            + _sweep_seating_words(sweeps[name])
        )
    return sweeps


def _sweep_seating_words(sweep: SweepResult) -> str:
    """The sweep's progress line's note on the seating its points ran (none on the link drive)."""
    from dynamics.response.sweep import seating_note

    note = seating_note(sweep)
    return "" if note is None else f"; {note}"


def _seating_at_each_speed(cfg: RunConfig, scene: Scene, model: ChainModel):
    """The sweep's machine at one speed: the seating the run's verdict gives at that speed
    (stages.machine.seating_that_runs, decided before the run as the dynamics stage decides it), so a
    speed where rigid seating does not hold runs the tooth model as the run at that speed would."""
    from dynamics.machine_scene import machine_model
    from stages.machine import seating_that_runs

    machines = {}

    def model_at(cam, t_s):
        ran, _ = seating_that_runs(cfg, scene, model, cam, t_s)
        if ran not in machines:  # one machine per seating: its matrices are built once
            machines[ran] = machine_model(ran, model)
        return machines[ran]

    return model_at


def stiffness_error_allowed(
    cfg: RunConfig, result: MaterialStiffness, scenario: Scenario, budget: float, probes: int = K_PROBES
) -> float:
    """The k error whose effect on `scenario`'s metrics is within `budget`, measured: from the FEA's
    error estimate, each probe moves k by the larger of half the last probe's error and the linear
    scaling of its effect to 0.9 of the budget, and re-runs the metrics at the scenario's sampling,
    until they move by at most `budget`. Halving, because the effect is not linear in the k error on
    the wheels (impacts: on the default machine 3.3x the k error at 1e-4, 3.9x at 1e-3, 8.7x at
    3.2e-3), so the linear scaling of a large probe asks for a finer k than needed; the scaling
    where it is the larger, as a chain linear in k meets the budget at it in one probe. Past
    `probes` the last probe's scaling is returned, unverified."""
    from dynamics.response.fidelity import stiffness_sensitivity

    material, cam_id = scenario.history.material, scenario.history.cam

    def effect_of(k_error: float) -> float:
        def stations_with_k(k: float):
            model = chain_model(cfg, result, k)
            return simulate_scenario(cfg, model, material, cam_id, result.pitch_m, scenario.samples_per_degree).stations

        return stiffness_sensitivity(stations_with_k, result.stiffness_N_per_m, k_error, scenario.stations)

    k_error = result.stiffness_rel_error_estimate
    effect = effect_of(k_error)
    for _ in range(probes):
        if effect <= budget:
            return k_error
        k_error = max(k_error / 2, 0.9 * k_error * budget / effect)
        effect = effect_of(k_error)
    return k_error if effect <= budget else 0.9 * k_error * budget / effect
