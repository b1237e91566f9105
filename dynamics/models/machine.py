"""The linear chain on its wheels (issue #22): drive sprocket, drive compliance, idler wheel, carriage,
polygonal feed; no pin clearance. SI units; every part switchable.

Layout (0-based links, link j + 1 leads link j in the direction of travel). The drive sprocket seats
links 0 .. w_d - 1: link 0 is the last seated from the tight strand (span N - 1 joins the tight
strand's end, link N - 1, to it) and link w_d - 1 the next to leave onto the slack strand. The slack
strand follows (links w_d ..), then the idler wheel's w_i seated links, then the tight strand back
to link N - 1. The slack strand gets (N - w_d - w_i) // 2 links, the tight strand the rest. Without
an idler wheel the idler is today's: a point inside span round(N/2) - 1, where the carriage sits.

Coordinates (dynamics.models.topology), relative to the cam: a free link's y = x - z; a wheel's seated
links move with its pitch circle as one DOF u, the path displacement R_m (theta - theta_cam) of the
wheel beyond the cam's nominal angle theta_cam = z / R_m (R_m = p z / 2 pi, dynamics.models.wheels: the
indexer turns the sprocket one tooth per pitch of cam lift); the carriage's u lengthens the loop by
2u (1u on each side of an idler wheel's seated group).

Parts:
- Rigid seating: the seated links of a wheel are one body with it: mass w m + J / R_m^2 (w m R^2 / R_m^2
  + J / R_m^2 with the polygonal action, the seated pins running on the pitch circle).
- Tooth contact stiffness (`tooth_stiffness_N_per_m`, default inf = rigid seating): each seated
  link its own DOF held to its wheel's seat by a spring k_t (a coupling of the topology), every span
  elastic, each wheel a DOF of J / R_m^2; k_t -> infinity is rigid seating to first order in k / k_t
  between seat changes. Its seat change (the link seating where it is and settling into its gap over
  an index) runs in the clearance machine's compiled step (dynamics.solvers.tooth_transfer); the
  linear and DOP853 steady state here (machine_steady.transfer) refuse it (rigid seating's transfer).
- Drive compliance: a torsional spring k_theta (N m/rad) between the cam's angle and the sprocket, a
  path stiffness k_theta / R_m^2 on the sprocket's DOF; infinite: the sprocket follows the cam
  (its seated links held to the cam's motion, no DOF).
- Idler wheel: free to turn (no ground spring on its DOF), on the carriage when a tensioner is given,
  else on a fixed axle.
- Polygonal feed: the last seated pin at each end of a wheel's wrap pulls its strand at
  R sin(gamma) along the strand (dynamics.models.wheels): the span from the wheel to its first free link has
  stretch u + d(a) - y (tight end) or y - u - d(a) (slack end), with d(a) the feed's departure from
  the mean R_m a at the wheel's angle a since the dwell; the wheel feels the span tension through
  dX/dtheta = R cos(gamma). This makes the model nonlinear in u and time-varying; it is integrated by
  scipy's solve_ivp (DOP853, tight tolerances) as the reference. The wrap is taken as a whole number
  of teeth, so both ends of a wrap share gamma (two equal wheels with parallel strands: the wrap is
  z / 2 teeth). The default tooth phase (0) puts the seat change at the dwell; within an index the
  pin seated at the dwell pulls the strand, so the model integrates one index cycle at a time. A
  phase phi in (0, 1) puts the seat change inside the index, when the cam has lifted (1 - phi) p
  (`seat_change_lift_m`; both wheels at once, one phase for both): the solvers stop there, apply
  the transfer (dynamics.solvers.machine_steady.transfer, with the cam's speed at that instant)
  and go on with the angles counted one tooth back, which is the next index's frame. Without the
  polygonal action the feed is the mean one but the seats still change at that instant (the limit
  z -> infinity of the polygonal model at the same phase). Rigid seating puts the arriving link at
  its seat: inside the index, under the strands' inertial tension, that moves it by its span's
  stretch and changes the spans' elastic energy by about k e1 e2 (the transfer's energy change),
  which at the dwell is small (the residual vibration's stretches) and inside the index is not.

Damping: modal ratio zeta on every mode of the machine's (K, M) with the carriage held (or
Rayleigh alpha M + beta K on those DOFs), the carriage's dashpot c_t on its own, as the clearance
chain treats the carriage. With the polygonal action the same C acts on the velocities.

Reductions (tested): drive="link" is today's ChainModel; a one-link sprocket with k_theta = k_d R_m^2,
no inertia and no polygonal action is today's driven link 1; an infinitely stiff drive on one seated
link is today's chain with link 1 held to the cam; an idler wheel of one seated link with no inertia
on a fixed axle is a plain link; z -> infinity removes the polygonal action.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.linalg import eigh

from dynamics.errors import DynamicsError
from dynamics.models.chain import ChainModel
from dynamics.models.clearance import Tensioner
from dynamics.models.lanczos import lanczos_start
from dynamics.models.system import SecondOrderSystem
from dynamics.models.topology import ChainTopology, Span
from dynamics.models.wheels import Wheel
from dynamics.options import DRIVES
from dynamics.response.metrics import matlab_round


@dataclass(frozen=True)
class WheelEnds:
    """Where a wheel's DOF meets its strands: the span from the strand that runs onto it (behind:
    the tight strand at the sprocket, the slack strand at the idler) and the span to the strand it
    feeds (ahead)."""

    wheel: Wheel
    dof: int | None  # None: held to the cam (an infinitely stiff drive)
    behind_span: int
    ahead_span: int


@dataclass(frozen=True)
class MachineOnWheels:
    chain: ChainModel  # links, mass, k, preload, damping (friction must be 0: the linear chain)
    drive: str = "wheels"
    sprocket: Wheel | None = None  # required for drive="wheels"
    drive_torsional_stiffness_N_m_per_rad: float | None = None  # None: the report's k_d at R_m; inf: held
    idler: Wheel | None = None  # None: today's idler (a point in a span)
    tensioner: Tensioner | None = None  # None: a fixed axle
    polygonal: bool = True
    # the tooth flank's contact stiffness along the path holding each seated link to its seat; inf: rigid
    # seating (the seated links and their wheel one body, today's model)
    tooth_stiffness_N_per_m: float = np.inf

    def __post_init__(self) -> None:
        if self.drive not in DRIVES:
            raise DynamicsError(f"drive: expected one of {', '.join(DRIVES)}, got {self.drive!r} (option --drive)")
        if self.chain.friction_coefficient > 0.0:
            raise DynamicsError(
                f"friction_coefficient: got {self.chain.friction_coefficient!r}; the machine on "
                "its wheels is the linear chain (friction 0) this far"
            )
        if self.drive == "link":
            return
        if self.sprocket is None or self.sprocket.wrap_links < 1:
            raise DynamicsError(
                "sprocket: expected a Wheel with wrap_links >= 1 for drive='wheels' (option --sprocket-wrap-links)"
            )
        k_theta = self.drive_torsional_stiffness_N_m_per_rad
        if k_theta is not None and not (k_theta > 0 and not np.isnan(k_theta)):
            raise DynamicsError(
                f"drive_torsional_stiffness_N_m_per_rad: expected > 0 (inf allowed), got {k_theta!r} "
                "(option --drive-stiffness)"
            )
        wrap = self.sprocket.wrap_links + (0 if self.idler is None else self.idler.wrap_links)
        if self.chain.n_links - wrap < 2:
            raise DynamicsError(f"wrap links: {wrap} seated of {self.chain.n_links}; expected at least two free links")
        if not self.rigid_seating:
            self._check_tooth_model()
        if self.idler is not None and self.idler.tooth_phase != self.sprocket.tooth_phase:
            raise DynamicsError(
                f"tooth_phase: the idler's {self.idler.tooth_phase!r} differs from the sprocket's "
                f"{self.sprocket.tooth_phase!r}; expected one phase (the seats change on both wheels at once)"
            )

    def _check_tooth_model(self) -> None:
        k_t = self.tooth_stiffness_N_per_m
        if not (k_t > 0 and not np.isnan(k_t)):
            raise DynamicsError(f"tooth_stiffness_N_per_m: expected > 0 N/m (inf: rigid seating), got {k_t!r}")
        for name, wheel in (("sprocket", self.sprocket), ("idler", self.idler)):
            held = name == "sprocket" and self.drive_held
            if wheel is not None and wheel.wrap_links and not held and wheel.inertia_kg_m2 <= 0:
                raise DynamicsError(
                    f"{name} inertia: expected > 0 kg m^2 with a tooth stiffness (the wheel is a body of its own), "
                    f"got {wheel.inertia_kg_m2!r}"
                )

    @property
    def rigid_seating(self) -> bool:
        """Seated links and their wheel one body (an infinite tooth stiffness, today's model)."""
        return bool(np.isinf(self.tooth_stiffness_N_per_m))

    # --- layout ----------------------------------------------------------------------------------

    @property
    def n_links(self) -> int:
        return self.chain.n_links

    @property
    def drive_stiffness_N_m_per_rad(self) -> float:
        """k_theta; by default the report's drive spring k_d at the sprocket's feed radius, k_d R_m^2."""
        if self.drive_torsional_stiffness_N_m_per_rad is not None:
            return float(self.drive_torsional_stiffness_N_m_per_rad)
        return self.chain.drive_stiffness * self.sprocket.feed_radius_m**2

    @property
    def seat_change_lift_m(self) -> float | None:
        """The cam's lift since the dwell at which the seats change inside the index, (1 - phase) p
        (dynamics.models.wheels); None where they change at the dwell: tooth phase 0 or the link
        drive. Without the polygonal action the seats still change one at a time at that instant
        (the feed is the mean one, the seating is not)."""
        if self.drive != "wheels" or self.sprocket.tooth_phase == 0.0:
            return None
        return self.sprocket.seat_change_angle_rad * self.sprocket.feed_radius_m

    @property
    def drive_held(self) -> bool:
        return self.drive == "wheels" and np.isinf(self.drive_stiffness_N_m_per_rad)

    @cached_property
    def groups(self) -> tuple[tuple[int, ...], ...]:
        """Chain links per place, in link order: seated groups as one tuple, free links alone."""
        n = self.n_links
        if self.drive == "link":
            return tuple((j,) for j in range(n))
        w_d = self.sprocket.wrap_links
        w_i = 0 if self.idler is None else self.idler.wrap_links
        n_slack = (n - w_d - w_i) // 2
        out = [tuple(range(w_d))]
        out += [(j,) for j in range(w_d, w_d + n_slack)]
        if w_i:
            out.append(tuple(range(w_d + n_slack, w_d + n_slack + w_i)))
        out += [(j,) for j in range(w_d + n_slack + w_i, n)]
        return tuple(out)

    @cached_property
    def idler_place(self) -> int | None:
        """Index in `groups` of the idler wheel's seated group (None without an idler wheel)."""
        if self.drive == "link" or self.idler is None or self.idler.wrap_links == 0:
            return None
        return 1 + (self.n_links - self.sprocket.wrap_links - self.idler.wrap_links) // 2

    def stations(self) -> dict[str, int]:
        """0-based link at each station at the start of an index: the middle of the sprocket's wrap,
        of the tight strand, of the idler's wrap (the idler span's link without a wheel) and of the
        slack strand. drive='link': today's stations (dynamics.response.metrics.station_links)."""
        from dynamics.response.metrics import station_links

        if self.drive == "link":
            return {name: link - 1 for name, link in station_links(self.n_links).items()}
        g = self.groups
        w_d = self.sprocket.wrap_links
        idler = self.idler_place
        n_slack = (self.n_links - w_d - (0 if self.idler is None else self.idler.wrap_links)) // 2
        slack = list(range(w_d, w_d + n_slack))
        tight_start = w_d + n_slack + (0 if idler is None else len(g[idler]))
        tight = list(range(tight_start, self.n_links))
        idler_links = g[idler] if idler is not None else (int(matlab_round(self.n_links / 2)) - 1,)
        return {
            "drive-end": (w_d - 1) // 2,
            "tight-side": tight[(len(tight) - 1) // 2],
            "idler-end": idler_links[(len(idler_links) - 1) // 2],
            "slack-side": slack[(len(slack) - 1) // 2],
        }

    # --- topology and matrices -------------------------------------------------------------------

    @cached_property
    def topology(self) -> ChainTopology:
        if self.drive == "link":
            return self.chain.topology() if self.tensioner is None else self._ring_with_carriage()
        if not self.rigid_seating:
            return self._tooth_topology()
        c = self.chain
        places = self.groups
        held = self.drive_held
        # DOF per place (the held sprocket has none); the carriage is the last DOF
        dof_of_place, masses, links = [], [], []
        for p, carried in enumerate(places):
            if p == 0 and held:
                dof_of_place.append(None)
                continue
            dof_of_place.append(len(masses))
            wheel = self.sprocket if p == 0 else (self.idler if p == self.idler_place else None)
            masses.append(self._group_mass(wheel, len(carried)))
            links.append(carried)
        carriage = None
        if self.tensioner is not None:
            carriage = len(masses)
            masses.append(self.tensioner.mass_kg)
            links.append(())
        spans = []
        n_places = len(places)
        for p in range(n_places):  # span between place p and place p + 1 (the last closes the loop)
            behind, ahead = dof_of_place[p], dof_of_place[(p + 1) % n_places]
            gain_dof, gain = None, 0.0
            if carriage is not None:
                if self.idler_place is None and places[p][-1] == self._idler_span_link():
                    gain_dof, gain = carriage, 2.0
                elif self.idler_place is not None and self.idler_place in (p, (p + 1) % n_places):
                    gain_dof, gain = carriage, 1.0
            spans.append(Span(behind, ahead, gain_dof, gain))
        ground = []
        if not held:
            ground.append((dof_of_place[0], self.drive_stiffness_N_m_per_rad / self.sprocket.feed_radius_m**2))
        if carriage is not None:
            ground.append((carriage, self.tensioner.rate_N_per_m))
        return ChainTopology(
            tuple(masses),
            tuple(links),
            tuple(spans),
            c.stiffness_N_per_m,
            c.preload_N,
            tuple(ground),
            places[0] if held else (),
        )

    def seated_blocks(self) -> tuple[tuple[Wheel, tuple[int, ...]], ...]:
        """(wheel, its seated links) for the sprocket and the idler wheel, in `wheel_ends` order."""
        out = [(self.sprocket, self.groups[0])]
        if self.idler_place is not None:
            out.append((self.idler, self.groups[self.idler_place]))
        return tuple(out)

    def _tooth_topology(self) -> ChainTopology:
        """Seating through the tooth flanks: every link its own DOF (DOF j = link j), every span
        elastic (span j from link j to link j + 1), each wheel a DOF of its own (its inertia J / R_m^2,
        after the links) and each seated link held to its wheel's seat by a spring k_t (a coupling;
        to the cam's frame on a sprocket held to the cam). A seated link's mass is m (R / R_m)^2 with
        the polygonal action (its pin runs on the pitch circle, as in the rigid group's mass), so that
        k_t -> infinity gives the rigid group's mass and stiffness. The tensioner's carriage, where there
        is one, is the last DOF, as in the rigid topology: its u lengthens the two spans joining the
        idler wheel's seated links to the strands (2u the idler point's span without an idler wheel);
        the seats ride on the wheel, whose path coordinate the carriage does not change, so the spans
        between seated links and the tooth springs do not feel it."""
        c, k_t, n = self.chain, float(self.tooth_stiffness_N_per_m), self.n_links
        masses = [c.link_mass_kg] * n
        links = [(j,) for j in range(n)]
        ground, couplings, wheel_dofs = [], [], []
        for i, (wheel, seated) in enumerate(self.seated_blocks()):
            radius = wheel.pitch_radius_m if self.polygonal else wheel.feed_radius_m
            for j in seated:
                masses[j] = c.link_mass_kg * (radius / wheel.feed_radius_m) ** 2
            if i == 0 and self.drive_held:
                ground += [(j, k_t) for j in seated]
                continue
            dof = len(masses)
            masses.append(wheel.inertia_kg_m2 / wheel.feed_radius_m**2)
            links.append(())
            wheel_dofs.append(dof)
            couplings += [(j, dof, k_t) for j in seated]
            if i == 0:
                ground.append((dof, self.drive_stiffness_N_m_per_rad / wheel.feed_radius_m**2))
        spans = tuple(Span(j, (j + 1) % n) for j in range(n))
        if self.tensioner is not None:
            spans = self._spans_on_the_carriage(spans, len(masses))
            masses.append(self.tensioner.mass_kg)
            links.append(())
            ground.append((len(masses) - 1, self.tensioner.rate_N_per_m))
        return ChainTopology(
            tuple(masses),
            tuple(links),
            spans,
            c.stiffness_N_per_m,
            c.preload_N,
            tuple(ground),
            (),
            tuple(couplings),
            tuple(wheel_dofs),
        )

    def _spans_on_the_carriage(self, spans: tuple[Span, ...], carriage: int) -> tuple[Span, ...]:
        """The tooth topology's spans (span j from link j to link j + 1) with the carriage's gain: 1 on
        each span joining the idler wheel's seated links to a free link, 2 on the idler point's span
        without an idler wheel (the rigid topology's gains, place by place)."""
        if self.idler_place is None:
            idler_point = self._idler_span_link()
            return tuple(Span(s.behind, s.ahead, carriage, 2.0) if j == idler_point else s for j, s in enumerate(spans))
        seated = set(self.groups[self.idler_place])
        n = self.n_links
        return tuple(
            Span(s.behind, s.ahead, carriage, 1.0) if (j in seated) != ((j + 1) % n in seated) else s
            for j, s in enumerate(spans)
        )

    def _group_mass(self, wheel: Wheel | None, n_seated: int) -> float:
        m = self.chain.link_mass_kg
        if wheel is None:
            return m
        radius = wheel.pitch_radius_m if self.polygonal else wheel.feed_radius_m
        return (n_seated * m * radius**2 + wheel.inertia_kg_m2) / wheel.feed_radius_m**2

    def _idler_span_link(self) -> int:
        return int(matlab_round(self.n_links / 2)) - 1

    def _ring_with_carriage(self) -> ChainTopology:
        from dynamics.models.topology import ring_topology

        c, t = self.chain, self.tensioner
        return ring_topology(
            c.n_links,
            c.link_mass_kg,
            c.stiffness_N_per_m,
            c.preload_N,
            c.drive_stiffness,
            carriage=(self._idler_span_link(), t.rate_N_per_m, t.mass_kg),
        )

    @cached_property
    def wheel_ends(self) -> tuple[WheelEnds, ...]:
        if self.drive == "link":
            return ()
        if not self.rigid_seating:
            # span j joins link j to link j + 1; the wheels' DOFs follow the links' (none when held)
            wheel_dofs = iter(self.topology.wheel_dofs)
            out = []
            for i, (wheel, seated) in enumerate(self.seated_blocks()):
                dof = None if (i == 0 and self.drive_held) else next(wheel_dofs)
                out.append(WheelEnds(wheel, dof, (seated[0] - 1) % self.n_links, seated[-1]))
            return tuple(out)
        out = []
        n_places = len(self.groups)
        places = [(0, self.sprocket)]
        if self.idler_place is not None:
            places.append((self.idler_place, self.idler))
        held_offset = 1 if self.drive_held else 0
        for place, wheel in places:
            dof = None if (place == 0 and self.drive_held) else place - held_offset
            # span p joins place p to place p + 1: the span behind the wheel is the one ending at it
            out.append(WheelEnds(wheel, dof, (place - 1) % n_places, place))
        return tuple(out)

    @cached_property
    def _incidence_dense(self) -> np.ndarray:
        return self.topology.incidence().toarray()

    def mass_matrix(self) -> np.ndarray:
        return self.topology.mass_matrix()

    def stiffness_matrix(self) -> np.ndarray:
        return self.topology.stiffness_matrix()

    def damping_matrix(self) -> np.ndarray:
        if self.drive == "link" and self.tensioner is None:
            return self.chain.damping_matrix()
        k, m = self.stiffness_matrix(), self.mass_matrix()
        chain_dofs = np.flatnonzero(self.topology.moves_with_cam()).tolist()  # not the carriage
        ix = np.ix_(chain_dofs, chain_dofs)
        c = np.zeros_like(k)
        if self.chain.rayleigh_coefficients is not None:
            alpha, beta = self.chain.rayleigh_coefficients
            c[ix] = alpha * m[ix] + beta * k[ix]
        else:
            c[ix] = modal_damping_matrix(k[ix], m[ix], self.chain.damping_ratio)
        if self.tensioner is not None:
            c[-1, -1] = self.tensioner.damping_N_s_per_m
        return c

    def system(self) -> SecondOrderSystem:
        """M q'' + C q' + K q = f: the polygon-free (linear, time-invariant) model."""
        if self.drive == "link" and self.tensioner is None:
            return self.chain.system()
        return SecondOrderSystem(self.mass_matrix(), self.damping_matrix(), self.stiffness_matrix())

    def inertial_load(self) -> np.ndarray:
        """r with f = -r z''(t): every DOF that moves with the chain carries its mass (the carriage
        does not move with the cam; a wheel of the tooth model does)."""
        topo = self.topology
        return np.asarray(topo.masses_kg, dtype=float) * topo.moves_with_cam()

    def natural_frequencies_Hz(self) -> np.ndarray:
        lam = eigh(self.stiffness_matrix(), self.mass_matrix(), eigvals_only=True)
        return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)

    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """(natural frequencies in Hz, effective mass fractions), ascending: the modes of (K, M) (its
        places, wheels, tooth springs and carriage as built) and each mode's share (phi_j^T r)^2 /
        (r^T M^-1 r) of the cam's base excitation -r z'' (r the inertial load; the shares of all modes
        sum to 1). The frequencies are `natural_frequencies_Hz`'s."""
        m = self.mass_matrix()
        lam, shapes = eigh(self.stiffness_matrix(), m)
        load = self.inertial_load()
        participation = shapes.T @ load
        fraction = participation**2 / float(load @ np.linalg.solve(m, load))
        return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi), fraction

    def lowest_natural_frequencies_Hz(self, count: int) -> np.ndarray:
        """The `count` lowest natural frequencies: the dense eigensolve up to DENSE_LINK_LIMIT links (the
        figures as reported so far), above it shift-invert Lanczos on the sparse K and M (no N x N
        array: memory and time linear in N), shifted a hair below 0 so that a free mode would not
        make K singular. Its mode 1 is the Rayleigh quotient of its mode shape
        (ChainTopology.rayleigh_quotient): the shift-invert eigenvalue carries the factorisation's
        rounding, 2.8e-13 (450 links) to 1.4e-10 (10,000) of omega^2 from the exact eigenvalue, the
        quotient 2e-16 at every length (its error is quadratic in the shape's, whose residual is 5e-9
        at 10,000 links; docs/performance.md, "Long clearance chains on wheels")."""
        from dynamics.models.reduction import DENSE_LINK_LIMIT

        if self.n_links <= DENSE_LINK_LIMIT:
            return self.natural_frequencies_Hz()[:count]
        import scipy.sparse as sp
        from scipy.sparse.linalg import eigsh

        topo = self.topology
        k = topo.stiffness_matrix_sparse().tocsc()
        masses = np.asarray(topo.masses_kg, dtype=float)
        shift = -1e-9 * float(np.max(k.diagonal() / masses))
        count = min(count, topo.n_dof - 1)
        lam, shapes = eigsh(
            k, k=count, M=sp.diags(masses).tocsc(), sigma=shift, which="LM", v0=lanczos_start(topo.n_dof)
        )
        order = np.argsort(lam)
        lam = lam[order]
        lam[0] = topo.rayleigh_quotient(shapes[:, order[0]])
        return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)

    def link_displacements(self, q: np.ndarray) -> np.ndarray:
        """Every link's relative displacement (..., N) from DOF states (..., n_dof): a seated link
        has its wheel's u (a held one 0)."""
        q = np.asarray(q, dtype=float)
        out = np.zeros(q.shape[:-1] + (self.n_links,))
        for dof, carried in enumerate(self.topology.links):
            if carried:
                out[..., list(carried)] = q[..., dof : dof + 1]
        return out

    def stored_energy_J(self, q: np.ndarray, v: np.ndarray, zdot_m_s: float, angles_rad) -> float:
        """Kinetic + elastic energy of one state in the absolute frame: 1/2 sum M (q' + z')^2 (the
        carriage without z'), the spans' P e + k e^2 / 2 with the wheel-end stretches carrying the
        feed's departure at the wheels' nominal angles since the dwell (`angles_rad`, as
        `polygon_force` takes them), the ground springs, and -2 P u of the carriage's preload."""
        topo = self.topology
        moves = topo.moves_with_cam()
        e = self._incidence_dense @ q
        if self.polygonal:
            for ends, angle in zip(self.wheel_ends, angles_rad):
                w = ends.wheel
                u = 0.0 if ends.dof is None else q[ends.dof]
                d = float(w.feed_departure_m(angle + u / w.feed_radius_m))
                e[ends.behind_span] += d
                e[ends.ahead_span] -= d
        kinetic = 0.5 * float(np.sum(np.asarray(topo.masses_kg) * (v + moves * zdot_m_s) ** 2))
        elastic = float(np.sum(topo.preload_N * e + 0.5 * topo.span_stiffness_N_per_m * e**2))
        ground = sum(0.5 * k * q[dof] ** 2 for dof, k in topo.ground) + topo.coupling_energy_J(q)
        carriage = -2.0 * topo.preload_N * q[-1] if self.tensioner is not None else 0.0
        return kinetic + elastic + ground + carriage

    # --- the polygonal feed ----------------------------------------------------------------------

    def polygon_force(self, t_rel_angle, q: np.ndarray) -> np.ndarray:
        """The span forces' departure from the linear model's where a wheel feeds a strand: for each
        wheel, the span behind it has stretch u + d(a) - y and the span ahead y - u - d(a), the wheel's share
        through dX/du = 1 + d'(a) / R_m. `t_rel_angle` maps a wheel's index in `wheel_ends` to its
        nominal angle since the dwell (z - z_dwell) / R_m."""
        f = np.zeros(q.shape[-1])
        if not self.polygonal:
            return f
        topo = self.topology
        k, preload = topo.span_stiffness_N_per_m, topo.preload_N
        b = self._incidence_dense
        for i, ends in enumerate(self.wheel_ends):
            w = ends.wheel
            u = 0.0 if ends.dof is None else q[ends.dof]
            a = t_rel_angle[i] + u / w.feed_radius_m
            d = float(w.feed_departure_m(a))
            slope = float(w.feed_departure_slope(a)) / w.feed_radius_m  # d(d)/du
            for span, sign in ((ends.behind_span, 1.0), (ends.ahead_span, -1.0)):
                row = b[span]
                e_lin = float(row @ q)
                e = e_lin + sign * d
                grad_lin = row
                grad = row.copy()
                if ends.dof is not None:
                    grad[ends.dof] += sign * slope
                f -= (preload + k * e) * grad - (preload + k * e_lin) * grad_lin
        return f


def modal_damping_matrix(k: np.ndarray, m: np.ndarray, zeta: float) -> np.ndarray:
    """C = M Phi diag(2 zeta omega) Phi^T M on the modes of (K, M), as dynamics.models.chain builds it."""
    lam, phi = eigh(k, m)
    omega = np.sqrt(np.clip(lam, 0.0, None))
    c = m @ phi @ np.diag(2.0 * zeta * omega) @ phi.T @ m
    return 0.5 * (c + c.T)
