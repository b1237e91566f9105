"""The machine on its wheels as a planar multibody model in Exudyn: an independent cross-check of the
1-D model (dynamics.models.machine, integrated by dynamics.solvers.machine_ivp) over one index cycle
in which no link changes seats, and over cycles with the seat change at each dwell (`seat_change`,
in places as the 1-D model's transfer) (tests/test_machine_exudyn.py, benchmarks/machine_exudyn.py).

The planar model (SI, the plane of the chain loop, no gravity):
- every free pin a point mass (`NodePoint2D` + `MassPoint2D`, the link's mass: the 1-D model's
  lumping, each link's mass at its pin);
- every link a spring-damper between its two pins along the line joining them
  (`ConnectorSpringDamper`: stiffness k, damping beta k, reference length p - P/k, so the chain
  assembled at its pitch carries the preload P);
- each wheel a rigid body (`NodeRigidBody2D` + `RigidBody2D`) on a fixed axle (its x and y held by
  `CoordinateConstraint`s), its seated pins rigidly on it at the pitch radius R = p / (2 sin(pi/z))
  (their mass in its inertia, J + w m R^2; the links joining two seated pins do not stretch and are
  left out), the links from a strand to the wheel attached at the seat (`MarkerBodyPosition`);
- the drive: a torsional spring-damper k_theta, beta k_theta from the ground to the sprocket's
  angle and the cam's angle theta_cam = z / R_m as its moving end (the load k_theta theta_cam +
  beta k_theta theta_cam' on the angle, as benchmarks/exudyn_chain.py drives link 1); the idler
  turns freely;
- optionally the guide (`guide_damping_N_s_per_m`, `guide_stiffness_N_per_m`): on every free pin a
  dashpot and a spring across its strand (`CoordinateSpringDamper` on the pin's y against the
  ground), towards the strand's straight line at the dwell; the machine's chain runs in guides
  (field notes), which take the strands' transverse vibration. Default none: free strands.
Layout at the dwell, tooth phase 0 (dynamics.models.wheels): two equal z-tooth wheels, sprocket at the
origin, idler at (L, 0), both turning counter-clockwise; w = z/2 + 1 pins seated on each (a wrap of
z/2 teeth: the 1-D model's group of w links whose end pins share gamma), the strands straight at
y = +-R cos(pi/z) between the wheels' end pins, which stand at gamma = -pi/z from the tangent
points; n_s free pins in each strand, L = (n_s + 1) p. Links are numbered as in the 1-D model: the
sprocket's pins 0..w-1 (0 the last seated from the tight strand, the upper one), the slack strand
(lower), the idler's pins, the tight strand back to link N-1.

What it has that the 1-D model leaves out: the strands' transverse motion (the chordal rise and fall
of R (1 - cos(pi/z)) at each wheel moves the strands' ends across the strand; the strand follows
as a string under its tension) and the exact geometry of the links at the wheels (the 1-D model
keeps the along-strand projection R sin(gamma)); the damping acts on the true stretch rates (the
1-D model's C = beta K on the linear stretches). Time integration: generalized-alpha with spectral
radius 1 (the trapezoidal rule), fixed step, sensors at the output times.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dynamics.models.chain import ChainModel
from dynamics.models.machine import MachineOnWheels
from dynamics.models.wheels import Wheel, pitch_radius_m
from dynamics.solvers.machine_ivp import integrate_cycle
from dynamics.solvers.machine_steady import transfer
from verification.machine_energy import polygonal_stretches_m


@dataclass(frozen=True)
class PlanarMachine:
    """Two equal wheels and a chain of n_links pins; SI units."""

    n_links: int
    link_mass_kg: float
    stiffness_N_per_m: float
    preload_N: float
    pitch_m: float
    teeth: int
    drive_stiffness_N_m_per_rad: float
    sprocket_inertia_kg_m2: float = 0.0
    idler_inertia_kg_m2: float = 0.0
    beta_s: float = 0.0  # span and drive damping beta k
    # the guide: on every free pin a dashpot and a spring across its strand, towards the strand's
    # straight line at the dwell (0, 0: free strands)
    guide_damping_N_s_per_m: float = 0.0
    guide_stiffness_N_per_m: float = 0.0

    def __post_init__(self) -> None:
        if self.guide_damping_N_s_per_m < 0 or self.guide_stiffness_N_per_m < 0:
            raise ValueError(
                "guide_damping_N_s_per_m, guide_stiffness_N_per_m: expected >= 0, got "
                f"{self.guide_damping_N_s_per_m}, {self.guide_stiffness_N_per_m}"
            )
        if self.teeth % 2:
            raise ValueError(f"teeth: expected an even number (parallel strands wrap z/2 teeth), got {self.teeth}")
        if (self.n_links - 2 * self.wrap_links) % 2 or self.n_links - 2 * self.wrap_links < 2:
            raise ValueError(f"n_links: expected 2 wrap_links + an even number >= 2, got {self.n_links}")

    @property
    def wrap_links(self) -> int:
        return self.teeth // 2 + 1

    @property
    def strand_links(self) -> int:
        return (self.n_links - 2 * self.wrap_links) // 2

    @property
    def pitch_radius_m(self) -> float:
        return pitch_radius_m(self.pitch_m, self.teeth)

    @property
    def feed_radius_m(self) -> float:
        return self.pitch_m * self.teeth / (2.0 * np.pi)

    @property
    def centre_distance_m(self) -> float:
        return (self.strand_links + 1) * self.pitch_m

    def seat_angles_rad(self) -> np.ndarray:
        """Angles on their wheels of the seated pins at the dwell: sprocket's w, then the idler's w."""
        tooth = 2.0 * np.pi / self.teeth
        j = np.arange(self.wrap_links)
        entry_sprocket = 0.5 * np.pi - np.pi / self.teeth
        entry_idler = 1.5 * np.pi - np.pi / self.teeth
        return np.concatenate([entry_sprocket + j * tooth, entry_idler + j * tooth])

    def pin_positions_m(self) -> np.ndarray:
        """(N, 2) every pin at the dwell, in link order."""
        r, w, n_s, lc = self.pitch_radius_m, self.wrap_links, self.strand_links, self.centre_distance_m
        angles = self.seat_angles_rad()
        sprocket = np.column_stack([r * np.cos(angles[:w]), r * np.sin(angles[:w])])
        idler = np.column_stack([lc + r * np.cos(angles[w:]), r * np.sin(angles[w:])])
        h, s = r * np.cos(np.pi / self.teeth), r * np.sin(np.pi / self.teeth)
        j = np.arange(1, n_s + 1)
        slack = np.column_stack([-s + j * self.pitch_m, np.full(n_s, -h)])
        tight = np.column_stack([lc + s - j * self.pitch_m, np.full(n_s, h)])
        return np.vstack([sprocket, slack, idler, tight])

    def wheel_of_link(self) -> np.ndarray:
        """Per link: 0 seated on the sprocket, 1 on the idler, -1 free."""
        w, n_s = self.wrap_links, self.strand_links
        out = np.full(self.n_links, -1)
        out[:w] = 0
        out[w + n_s : 2 * w + n_s] = 1
        return out


@dataclass(frozen=True)
class PlanarResponse:
    """At the output times: free pins' positions, velocities, accelerations (m, N, 2; NaN for seated
    pins), the wheels' angles and their derivatives (m, 2: sprocket, idler), every link's tension
    (m, N; link j joins pin j to pin j+1, NaN between two seated pins), and the run's cost."""

    t_s: np.ndarray
    pin_m: np.ndarray
    pin_m_s: np.ndarray
    pin_m_s2: np.ndarray
    angle_rad: np.ndarray
    angle_rad_s: np.ndarray
    angle_rad_s2: np.ndarray
    tension_N: np.ndarray
    n_steps: int
    wall_time_s: float


@dataclass(frozen=True)
class PlanarState:
    """The planar machine at a dwell: every pin's position and velocity (N, 2; seated pins' rows are
    not read), the wheels' angles from their dwell layout and their rates (2,: sprocket, idler)."""

    pin_m: np.ndarray
    pin_m_s: np.ndarray
    angle_rad: np.ndarray
    angle_rad_s: np.ndarray


def planar_response(
    machine: PlanarMachine, cam, t_eval_s, *, steps_per_output: int = 20, initial: PlanarState | None = None
) -> PlanarResponse:
    """The machine from `initial` (default: rest in its preloaded dwell layout) at t_eval_s[0], a
    dwell's end (the cam's lift there is the sprocket's angle 0), solved by Exudyn over uniform
    t_eval_s; the same pins stay seated (one index cycle; `seat_change` moves them on)."""
    import exudyn as exu
    from exudyn import itemInterface as ii

    t = np.asarray(t_eval_s, dtype=float)
    h_out = float(t[1] - t[0])
    if t.ndim != 1 or t.size < 2 or not np.allclose(np.diff(t), h_out, rtol=1e-9, atol=0):
        raise ValueError("t_eval_s: expected uniformly spaced output times")
    mc = machine
    n, w, m, k, r = mc.n_links, mc.wrap_links, mc.link_mass_kg, mc.stiffness_N_per_m, mc.pitch_radius_m
    beta, k_theta, r_m = mc.beta_s, mc.drive_stiffness_N_m_per_rad, mc.feed_radius_m
    z0 = float(np.asarray(cam.svaj(t[:1])[0])[0])
    pins = mc.pin_positions_m()
    wheel_of = mc.wheel_of_link()
    seat_angles = mc.seat_angles_rad()
    start = initial if initial is not None else PlanarState(pins, np.zeros_like(pins), np.zeros(2), np.zeros(2))

    system = exu.SystemContainer()
    mbs = system.AddSystem()
    ground = mbs.AddNode(ii.NodePointGround())
    ground_coordinate = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=ground, coordinate=0))
    wheel_nodes, wheel_bodies, angle_markers = [], [], []
    for centre, inertia in (
        ((0.0, 0.0), mc.sprocket_inertia_kg_m2),
        ((mc.centre_distance_m, 0.0), mc.idler_inertia_kg_m2),
    ):
        i = len(wheel_nodes)
        node = mbs.AddNode(
            ii.NodeRigidBody2D(
                referenceCoordinates=[centre[0], centre[1], 0.0],
                initialCoordinates=[0.0, 0.0, float(start.angle_rad[i])],
                initialVelocities=[0.0, 0.0, float(start.angle_rad_s[i])],
            )
        )
        body = mbs.AddObject(ii.ObjectRigidBody2D(nodeNumber=node, mass=10.0, inertia=inertia + w * m * r**2))
        for coordinate in (0, 1):  # the fixed axle
            marker = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=node, coordinate=coordinate))
            mbs.AddObject(ii.CoordinateConstraint(markerNumbers=[ground_coordinate, marker]))
        wheel_nodes.append(node)
        wheel_bodies.append(body)
        angle_markers.append(mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=node, coordinate=2)))

    pin_nodes = {}
    pin_markers = []
    for j in range(n):
        if wheel_of[j] >= 0:
            seat = seat_angles[j if wheel_of[j] == 0 else j - mc.strand_links]  # the idler's follow the sprocket's
            local = [r * np.cos(seat), r * np.sin(seat), 0.0]
            pin_markers.append(
                mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=wheel_bodies[wheel_of[j]], localPosition=local))
            )
            continue
        node = mbs.AddNode(
            ii.NodePoint2D(
                referenceCoordinates=list(pins[j]),
                initialCoordinates=list(start.pin_m[j] - pins[j]),
                initialVelocities=list(start.pin_m_s[j]),
            )
        )
        mbs.AddObject(ii.MassPoint2D(nodeNumber=node, mass=m))
        pin_nodes[j] = node
        pin_markers.append(mbs.AddMarker(ii.MarkerNodePosition(nodeNumber=node)))
        if mc.guide_damping_N_s_per_m or mc.guide_stiffness_N_per_m:
            # the node's y coordinate is the pin's displacement across its strand from the strand's line
            across = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=node, coordinate=1))
            mbs.AddObject(
                ii.CoordinateSpringDamper(
                    markerNumbers=[ground_coordinate, across],
                    stiffness=mc.guide_stiffness_N_per_m,
                    damping=mc.guide_damping_N_s_per_m,
                )
            )
    links = {}
    for j in range(n):
        ahead = (j + 1) % n
        if wheel_of[j] >= 0 and wheel_of[j] == wheel_of[ahead]:
            continue
        links[j] = mbs.AddObject(
            ii.SpringDamper(
                markerNumbers=[pin_markers[j], pin_markers[ahead]],
                referenceLength=mc.pitch_m - mc.preload_N / k,
                stiffness=k,
                damping=beta * k,
            )
        )
    mbs.AddObject(
        ii.CoordinateSpringDamper(
            markerNumbers=[ground_coordinate, angle_markers[0]], stiffness=k_theta, damping=beta * k_theta
        )
    )

    def cam_load(mbs_, t_s, load):
        s, v, _, _ = cam.svaj(np.array([t_s]))
        return k_theta * (float(s[0]) - z0) / r_m + beta * k_theta * float(v[0]) / r_m

    mbs.AddLoad(ii.LoadCoordinate(markerNumber=angle_markers[0], load=0.0, loadUserFunction=cam_load))

    kinds = (exu.OutputVariableType.Position, exu.OutputVariableType.Velocity, exu.OutputVariableType.Acceleration)
    free = sorted(pin_nodes)
    pin_sensors = [
        [
            mbs.AddSensor(
                ii.SensorNode(nodeNumber=pin_nodes[j], storeInternal=True, writeToFile=False, outputVariableType=kind)
            )
            for j in free
        ]
        for kind in kinds
    ]
    wheel_kinds = (
        exu.OutputVariableType.Coordinates,
        exu.OutputVariableType.Coordinates_t,
        exu.OutputVariableType.Coordinates_tt,
    )
    wheel_sensors = [
        [
            mbs.AddSensor(
                ii.SensorNode(nodeNumber=node, storeInternal=True, writeToFile=False, outputVariableType=kind)
            )
            for node in wheel_nodes
        ]
        for kind in wheel_kinds
    ]
    link_sensors = {
        j: mbs.AddSensor(
            ii.SensorObject(
                objectNumber=obj, storeInternal=True, writeToFile=False, outputVariableType=exu.OutputVariableType.Force
            )
        )
        for j, obj in links.items()
    }
    mbs.Assemble()

    settings = exu.SimulationSettings()
    n_steps = (t.size - 1) * steps_per_output
    ti = settings.timeIntegration
    ti.startTime, ti.endTime, ti.numberOfSteps = float(t[0]), float(t[-1]), n_steps
    ti.adaptiveStep = False
    ti.verboseMode = 0
    ti.generalizedAlpha.spectralRadius = 1.0
    ti.generalizedAlpha.computeInitialAccelerations = True
    ti.newton.relativeTolerance = 1e-10
    ti.newton.absoluteTolerance = 1e-10
    settings.solution.file.write = False
    settings.solution.sensors.writePeriod = h_out
    settings.show.computationTime = False
    settings.show.statistics = False
    start = time.perf_counter()
    mbs.SolveDynamic(settings, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    wall = time.perf_counter() - start

    def history(sensor, columns):
        data = np.asarray(mbs.GetSensorStoredData(sensor))
        return _at_output_times(data, t)[:, columns]

    pin_hist = []
    for group in pin_sensors:
        out = np.full((t.size, n, 2), np.nan)
        for j, sensor in zip(free, group):
            out[:, j, :] = history(sensor, [1, 2])
        pin_hist.append(out)
    wheel_hist = [np.column_stack([history(s, [3])[:, 0] for s in group]) for group in wheel_sensors]
    tension = np.full((t.size, n), np.nan)
    for j, sensor in link_sensors.items():
        force = history(sensor, [1, 2])  # the connector's force vector; tension: its size, signed
        along = pins[(j + 1) % n] - pins[j]  # by the link's direction at the dwell (it turns < 90 deg)
        tension[:, j] = np.linalg.norm(force, axis=1) * np.sign(force @ along)
    return PlanarResponse(t, *pin_hist, *wheel_hist, tension, n_steps, wall)


def _at_output_times(data: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The sensor's rows (time, values...) at the output times; refuses a missing one."""
    times = data[:, 0]
    idx = np.clip(np.searchsorted(times, t - 1e-9 * (t[1] - t[0])), 0, times.size - 1)
    if not np.allclose(times[idx], t, rtol=0, atol=1e-6 * (t[1] - t[0])):
        raise RuntimeError("Exudyn sensors did not write at every output time")
    return data[idx]


STATIONS = ("drive-end", "tight-side", "idler-end", "slack-side")


@dataclass(frozen=True)
class StationHistory:
    """One station over the window: path displacement relative to the cam (m) and absolute path
    acceleration (m/s^2)."""

    y_m: np.ndarray
    a_m_s2: np.ndarray


def one_d_machine(machine: PlanarMachine) -> MachineOnWheels:
    """The project's 1-D model of the same machine: w = z/2 + 1 links seated on each wheel (their
    end pins at the same gamma), the same drive, inertias and beta (C = beta K), polygonal feed."""
    mc = machine
    chain = ChainModel(
        mc.n_links,
        mc.link_mass_kg,
        mc.stiffness_N_per_m,
        preload_N=mc.preload_N,
        rayleigh_coefficients=(0.0, mc.beta_s),
    )
    return MachineOnWheels(
        chain,
        sprocket=Wheel(mc.teeth, mc.pitch_m, mc.wrap_links, inertia_kg_m2=mc.sprocket_inertia_kg_m2),
        idler=Wheel(mc.teeth, mc.pitch_m, mc.wrap_links, inertia_kg_m2=mc.idler_inertia_kg_m2),
        drive_torsional_stiffness_N_m_per_rad=mc.drive_stiffness_N_m_per_rad,
    )


def one_d_response(machine: PlanarMachine, cam, t_eval_s, q0=None, v0=None):
    """The 1-D model over the window from (q0, v0) (default rest; dynamics.solvers.machine_ivp, the
    cam's law exact, t_eval_s[0] a dwell's end): per station a StationHistory, the tension into the
    sprocket, and the run."""
    t = np.asarray(t_eval_s, dtype=float)
    model = one_d_machine(machine)
    n = model.topology.n_dof

    def cam_at(x, i):
        return float(cam.svaj(np.array([x]))[i][0])

    q0 = np.zeros(n) if q0 is None else q0
    v0 = np.zeros(n) if v0 is None else v0
    run = integrate_cycle(model, lambda x: cam_at(x, 2), lambda x: cam_at(x, 0), t, q0, v0)
    s, _, a, _ = cam.svaj(t)
    m = np.diag(model.mass_matrix())
    k_mat, c_mat, load = model.stiffness_matrix(), model.damping_matrix(), model.inertial_load()
    radii = np.array([e.wheel.feed_radius_m for e in model.wheel_ends])
    angles = (s - s[0])[:, None] / radii[None, :]
    force = np.array([model.polygon_force(ang, q) for ang, q in zip(angles, run.q_m)])
    acc = (-(run.q_m @ k_mat.T) - (run.v_m_s @ c_mat.T) - np.outer(a, load) + force) / m
    dof = model.topology.link_dof()
    stations = model.stations()
    out = {name: StationHistory(run.q_m[:, dof[stations[name]]], acc[:, dof[stations[name]]] + a) for name in STATIONS}
    behind = model.wheel_ends[0].behind_span
    stretch = np.array([polygonal_stretches_m(model, q, ang)[behind] for ang, q in zip(angles, run.q_m)])
    return out, model.chain.preload_N + model.chain.stiffness_N_per_m * stretch, run


def planar_stations(machine: PlanarMachine, response: PlanarResponse, cam):
    """The planar model's stations (the 1-D model's links): a wheel's group by its angle, R_m
    (theta - theta_cam); a strand's pin by its displacement along its strand (the tight strand runs
    towards -x, the slack strand towards +x); and the tension into the sprocket (link N - 1)."""
    s = np.asarray(cam.svaj(response.t_s)[0])
    s = s - s[0]
    stations = one_d_machine(machine).stations()
    wheel_of = machine.wheel_of_link()
    tight_start = 2 * machine.wrap_links + machine.strand_links
    x0 = machine.pin_positions_m()[:, 0]
    out = {}
    for name in STATIONS:
        j = stations[name]
        if wheel_of[j] >= 0:
            theta = response.angle_rad[:, wheel_of[j]]
            out[name] = StationHistory(
                machine.feed_radius_m * theta - s, machine.feed_radius_m * response.angle_rad_s2[:, wheel_of[j]]
            )
            continue
        sign = -1.0 if j >= tight_start else 1.0
        out[name] = StationHistory(sign * (response.pin_m[:, j, 0] - x0[j]) - s, sign * response.pin_m_s2[:, j, 0])
    return out, response.tension_N[:, machine.n_links - 1]


def strand_transverse(machine: PlanarMachine, response: PlanarResponse) -> tuple[float, float]:
    """Largest transverse displacement of a strand pin (m) and largest geometric shortening of a
    strand, sum over its links of p (1 - cos(alpha)) (alpha the link's angle to the strand's line):
    what the 1-D model leaves out."""
    pins = response.pin_m
    y0 = machine.pin_positions_m()[:, 1]
    free = machine.wheel_of_link() < 0
    transverse = float(np.nanmax(np.abs(pins[:, free, 1] - y0[free])))
    w, n_s = machine.wrap_links, machine.strand_links
    shortening = 0.0
    for first in (w - 1, 2 * w + n_s - 1):  # each strand from its wheel's last seated pin
        idx = list(range(first, first + n_s + 2))
        ys = np.column_stack(
            [
                _seat_y(machine, response, i)
                if machine.wheel_of_link()[i % machine.n_links] >= 0
                else pins[:, i % machine.n_links, 1]
                for i in idx
            ]
        )
        rise = np.diff(ys, axis=1)
        shortening = max(
            shortening, float(np.max(np.sum(machine.pitch_m - np.sqrt(machine.pitch_m**2 - rise**2), axis=1)))
        )
    return transverse, shortening


def _seat_y(machine: PlanarMachine, response: PlanarResponse, link: int) -> np.ndarray:
    """y of a seated pin over the window from its wheel's angle."""
    link = link % machine.n_links
    wheel = machine.wheel_of_link()[link]
    seat = machine.seat_angles_rad()[link if wheel == 0 else link - machine.strand_links]
    return machine.pitch_radius_m * np.sin(seat + response.angle_rad[:, wheel])


def station_metrics(histories: dict, tension_N: np.ndarray, cam, t_s: np.ndarray) -> dict:
    """Per station: residual vibration max |y| over the dwell (m), peak |a| (m/s^2); and the peak
    tension into the sprocket (N)."""
    dwell = cam.dwell_mask(t_s)
    out = {
        name: (float(np.max(np.abs(h.y_m[dwell]))), float(np.max(np.abs(h.a_m_s2)))) for name, h in histories.items()
    }
    out["tension"] = float(np.max(tension_N))
    return out


def end_state(machine: PlanarMachine, response: PlanarResponse) -> PlanarState:
    """The state at the window's end (seated pins placed on their wheels)."""
    pins = response.pin_m[-1].copy()
    vel = response.pin_m_s[-1].copy()
    theta, omega = response.angle_rad[-1], response.angle_rad_s[-1]
    for j in np.flatnonzero(machine.wheel_of_link() >= 0):
        pins[j], vel[j] = _seat_motion(machine, j, theta, omega)
    return PlanarState(pins, vel, theta.copy(), omega.copy())


def _seat_motion(machine: PlanarMachine, link: int, theta, omega):
    """Position and velocity of the seat of `link` (a seated place) at the wheels' angles and rates."""
    wheel = machine.wheel_of_link()[link]
    seat = machine.seat_angles_rad()[link if wheel == 0 else link - machine.strand_links]
    r = machine.pitch_radius_m
    centre = np.array([0.0 if wheel == 0 else machine.centre_distance_m, 0.0])
    phi = seat + theta[wheel]
    return centre + r * np.array([np.cos(phi), np.sin(phi)]), r * omega[wheel] * np.array([-np.sin(phi), np.cos(phi)])


def seat_change(machine: PlanarMachine, state: PlanarState) -> PlanarState:
    """The seat change at the dwell, in places as the 1-D model's transfer: every free place takes the
    pin one place behind it; the pin arriving at a wheel (the last of the strand running onto it) seats
    in a plastic impact that keeps the angular momentum about the axle, (J_w + m R^2) omega' = J_w omega
    + m (r x v), J_w the wheel's inertia with its seated pins, and moves to its seat (the snap); the
    pin leaving the wheel (its last seated place) starts at its seat with the seat's velocity; each
    wheel's angle goes back one tooth, so its seats stand at the places' angles again."""
    n, w, n_s = machine.n_links, machine.wrap_links, machine.strand_links
    m, r = machine.link_mass_kg, machine.pitch_radius_m
    theta = state.angle_rad - 2.0 * np.pi / machine.teeth
    omega = state.angle_rad_s.copy()
    for wheel, arriving, inertia in (
        (0, n - 1, machine.sprocket_inertia_kg_m2),
        (1, w + n_s - 1, machine.idler_inertia_kg_m2),
    ):
        centre = np.array([0.0 if wheel == 0 else machine.centre_distance_m, 0.0])
        arm = state.pin_m[arriving] - centre
        moment = float(arm[0] * state.pin_m_s[arriving, 1] - arm[1] * state.pin_m_s[arriving, 0])
        j_wheel = inertia + w * m * r**2
        omega[wheel] = (j_wheel * omega[wheel] + m * moment) / (j_wheel + m * r**2)
    pins = np.roll(state.pin_m, 1, axis=0)
    vel = np.roll(state.pin_m_s, 1, axis=0)
    for j in np.flatnonzero(machine.wheel_of_link() >= 0):
        pins[j], vel[j] = _seat_motion(machine, j, theta, omega)
    for leaving in (w, 2 * w + n_s):  # first free place after each wheel: at its seat one tooth back
        wheel = 0 if leaving == w else 1
        previous = leaving - 1
        ahead_theta = theta.copy()
        ahead_theta[wheel] += 2.0 * np.pi / machine.teeth
        pins[leaving], vel[leaving] = _seat_motion(machine, previous, ahead_theta, omega)
    return PlanarState(pins, vel, theta, omega)


def relabelled_windows(machine: PlanarMachine, cam, n_cycles: int, *, samples: int = 360, steps_per_output: int = 20):
    """Both models over n_cycles index cycles from rest with the seat change at each dwell (the 1-D
    model's transfer, the planar model's `seat_change`): per cycle the station metrics of each, the
    planar one's with "across_m_s", the free pins' largest speed across their strand at the cycle's
    end (what its seating impact passes into the wheels' rotation and the 1-D model has not)."""
    model = one_d_machine(machine)
    n = model.topology.n_dof
    q, v = np.zeros(n), np.zeros(n)
    state = None
    out = []
    for i in range(n_cycles):
        t = cam.cycle_s * (i + np.arange(samples + 1) / samples)
        histories, tension, run = one_d_response(machine, cam, t, q, v)
        response = planar_response(machine, cam, t, steps_per_output=steps_per_output, initial=state)
        h_planar, t_planar = planar_stations(machine, response, cam)
        planar = station_metrics(h_planar, t_planar, cam, t)
        planar["across_m_s"] = float(np.nanmax(np.abs(response.pin_m_s[-1, :, 1])))
        out.append((station_metrics(histories, tension, cam, t), planar))
        q, v, _, _ = transfer(model, run.q_m[-1], run.v_m_s[-1])
        state = seat_change(machine, end_state(machine, response))
    return out
