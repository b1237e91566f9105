"""The clearance chain built in Exudyn, an independent multibody code: the cross-check of
verification.clearance_reference (tests/test_clearance_exudyn.py, benchmarks/bench_clearance_reference.py).

Exudyn (PyPI `exudyn`, the `bench` extra) is optional: `exudyn_chain_response` raises ImportError
without it, and the tests that use it are skipped with that reason.

The model in Exudyn's terms (absolute coordinates, measured from the static preloaded state):
- every link a `Node1D` with a `Mass1D`;
- every span a `CoordinateSpringDamperExt` from link j to link j+1 with stiffness 0 and limit stops:
  its coordinate is q = x_j+1 - x_j = e, and the stops act outside [lower, upper] with force
  k (q - upper) above and k (q - lower) below. With upper = -P/k and lower = -P/k - g this is the
  issue's span law exactly: P + k e in pulling contact (the static state q = 0 sits P/k inside the
  upper stop, i.e. the span is stretched P/k from its unstressed length), 0 in the free play,
  k (e + P/k + g) in pushing contact. Each has its own `NodeGenericData` (3 data coordinates: the
  third is the contact state, initialised to the static state's P/k). g = inf is a lower stop at
  -1e30 m (never reached); g = 0 makes lower = upper, a linear spring through the preload.
- damping law "kelvin-voigt" (law (b)): `limitStopsDamping` = beta k, a dashpot that acts while the
  span is beyond a stop, i.e. in contact, as law (b). How it differs from the reference: Exudyn's
  contact state is a data variable updated after each Newton solve (its "PostNewton" discontinuous
  iteration re-solves the step with the new state), so a contact change takes effect for the whole
  step in which it happens instead of at the located instant: an O(h) error in the switching time,
  which is why Exudyn's results converge only slowly with the step where spans change contact.
  Damping law "rayleigh" (law (a) with C = beta K): the connector's own `damping` = beta k acts on
  e' always, in free play too.
- the drive: a `CoordinateSpringDamper` (k_d, beta k_d) from the ground to link 0, and the cam as
  its moving end, the coordinate load k_d z(t) + beta k_d z'(t) on link 0 (a Python user function
  of time): the same force k_d (z - x_0) + beta k_d (z' - x_0') as a prescribed cam coordinate
  joined by the drive spring, without a constraint whose velocity the integrator would have to
  differentiate.
- time integration: generalized-alpha with spectral radius 1 (no numerical damping: the trapezoidal
  rule), a fixed step of 1/steps_per_output of the output step, and sensors writing every output
  step. Friction and the tensioner are not built (the cross-check runs without them).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

DAMPING_LAWS = ("kelvin-voigt", "rayleigh")
NO_LOWER_STOP_M = -1e30  # the lower stop of a span with unbounded free play (g = inf)


@dataclass(frozen=True)
class ExudynChainResponse:
    """Absolute link motion at the output times (columns: links 0..N-1), and the run's cost."""

    t_s: np.ndarray
    x_m: np.ndarray
    v_m_s: np.ndarray
    a_m_s2: np.ndarray
    tension_N: np.ndarray  # (m, N) the span connectors' force, tension positive
    n_steps: int
    wall_time_s: float  # Exudyn's solve alone (model building excluded)


def exudyn_chain_response(
    *,
    n_links: int,
    link_mass_kg: float,
    stiffness_N_per_m: float,
    drive_stiffness_N_per_m: float,
    preload_N: float,
    clearance_m: float,
    cam,
    t_eval_s,
    span_damping_beta_s: float = 0.0,
    damping_law: str = "kelvin-voigt",
    steps_per_output: int = 10,
) -> ExudynChainResponse:
    """The chain from rest at t_eval_s[0] (every link at the cam's position, motionless), solved by
    Exudyn; t_eval_s uniform. `cam`: any cam duck type (`svaj`); pass the HeldCam of
    verification.clearance_reference to drive it with the same input as the reference's default."""
    import exudyn as exu
    from exudyn import itemInterface as ii

    if damping_law not in DAMPING_LAWS:
        raise ValueError(f"damping_law: expected one of {', '.join(DAMPING_LAWS)}, got {damping_law!r}")
    t = np.asarray(t_eval_s, dtype=float)
    h_out = float(t[1] - t[0])
    if t.ndim != 1 or t.size < 2 or not np.allclose(np.diff(t), h_out, rtol=1e-9, atol=0):
        raise ValueError("t_eval_s: expected uniformly spaced output times (Exudyn's sensors write periodically)")
    if not (isinstance(steps_per_output, int) and steps_per_output >= 1):
        raise ValueError(f"steps_per_output: expected an integer >= 1, got {steps_per_output!r}")
    n, m, k, kd, p = n_links, link_mass_kg, stiffness_N_per_m, drive_stiffness_N_per_m, preload_N
    beta = span_damping_beta_s
    upper = -p / k
    lower = NO_LOWER_STOP_M if np.isinf(clearance_m) else upper - clearance_m
    z0 = float(np.asarray(cam.svaj(t[:1])[0])[0])

    system = exu.SystemContainer()
    mbs = system.AddSystem()
    ground = mbs.AddNode(ii.NodePointGround())
    ground_marker = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=ground, coordinate=0))
    nodes, markers = [], []
    for _ in range(n):
        node = mbs.AddNode(ii.Node1D(referenceCoordinates=[0.0], initialCoordinates=[z0], initialVelocities=[0.0]))
        mbs.AddObject(ii.Mass1D(nodeNumber=node, mass=m))
        nodes.append(node)
        markers.append(mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=node, coordinate=0)))
    static_state = max(0.0 - upper, 0.0)  # penetration of the upper stop at q = 0: P/k
    spans = []
    for j in range(n):
        data = mbs.AddNode(ii.NodeGenericData(numberOfDataCoordinates=3, initialCoordinates=[0.0, 0.0, static_state]))
        spans.append(
            mbs.AddObject(
                ii.CoordinateSpringDamperExt(
                    markerNumbers=[markers[j], markers[(j + 1) % n]],
                    nodeNumber=data,
                    stiffness=0.0,
                    damping=beta * k if damping_law == "rayleigh" else 0.0,
                    useLimitStops=True,
                    limitStopsStiffness=k,
                    limitStopsUpper=upper,
                    limitStopsLower=lower,
                    limitStopsDamping=beta * k if damping_law == "kelvin-voigt" else 0.0,
                )
            )
        )
    mbs.AddObject(ii.CoordinateSpringDamper(markerNumbers=[ground_marker, markers[0]], stiffness=kd, damping=beta * kd))

    def cam_load(mbs_, t_s, load):
        z, zd = _z_and_zdot(cam, t_s)
        return kd * z + beta * kd * zd

    mbs.AddLoad(ii.LoadCoordinate(markerNumber=markers[0], load=0.0, loadUserFunction=cam_load))
    kinds = (
        exu.OutputVariableType.Coordinates,
        exu.OutputVariableType.Coordinates_t,
        exu.OutputVariableType.Coordinates_tt,
    )
    sensors = [
        [
            mbs.AddSensor(
                ii.SensorNode(nodeNumber=node, storeInternal=True, writeToFile=False, outputVariableType=kind)
            )
            for node in nodes
        ]
        for kind in kinds
    ]
    sensors.append(
        [
            mbs.AddSensor(
                ii.SensorObject(
                    objectNumber=span,
                    storeInternal=True,
                    writeToFile=False,
                    outputVariableType=exu.OutputVariableType.Force,
                )
            )
            for span in spans
        ]
    )
    mbs.Assemble()

    settings = exu.SimulationSettings()
    n_steps = (t.size - 1) * steps_per_output
    ti = settings.timeIntegration
    ti.startTime = float(t[0])
    ti.endTime = float(t[-1])
    ti.numberOfSteps = n_steps
    ti.adaptiveStep = False
    ti.verboseMode = 0
    ti.generalizedAlpha.spectralRadius = 1.0
    ti.generalizedAlpha.computeInitialAccelerations = True
    ti.discontinuous.maxIterations = 20
    ti.discontinuous.iterationTolerance = 1e-6 * max(p, 1.0)
    settings.solution.file.write = False
    settings.solution.sensors.writePeriod = h_out
    settings.show.computationTime = False
    settings.show.statistics = False
    start = time.perf_counter()
    mbs.SolveDynamic(settings, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    wall = time.perf_counter() - start

    histories = []
    for group in sensors:
        columns = []
        for sensor in group:
            data = np.asarray(mbs.GetSensorStoredData(sensor))
            columns.append(_at_output_times(data, t))
        histories.append(np.column_stack(columns))
    return ExudynChainResponse(t, *histories, n_steps, wall)


def _z_and_zdot(cam, t_s: float) -> tuple[float, float]:
    fast = getattr(cam, "z_and_zdot", None)
    if fast is not None:
        return fast(t_s)
    s, v, _, _ = cam.svaj(np.array([t_s]))
    return float(s[0]), float(v[0])


def _at_output_times(data: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The sensor's samples (time, value rows) at the output times; refuses a missing one."""
    times, values = data[:, 0], data[:, 1]
    idx = np.clip(np.searchsorted(times, t - 1e-9 * (t[1] - t[0])), 0, times.size - 1)
    if not np.allclose(times[idx], t, rtol=0, atol=1e-6 * (t[1] - t[0])):
        raise RuntimeError("Exudyn sensors did not write at every output time")
    return values[idx]
