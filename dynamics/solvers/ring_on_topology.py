"""The single-link drive's clearance chain (the ring, dynamics.models.clearance.ClearanceChain) stepped by
the machine's compiled step (dynamics.solvers.machine_verlet) on the ring's topology (the layout
dynamics.models.layout.LINK_DRIVE), behind clearance_verlet.integrate's call and its `Run`: the kernel
dynamics.scene.simulate_chain runs with `kernel="topology"` (issue #22, Architecture: the ring as one
more description of the topology, not a kernel of its own).

What it gives (tests/test_ring_on_topology.py): the ring's trajectories, tensions, contact counts,
free-play fraction, tension extremes, energy terms and impact measurements (closing speeds, approach
energies, force spike and Kelvin-Voigt dissipation, all at the crossing interpolated within the step,
and the largest force over each whole contact begun by an impact) to 1e-12; the global law's C w in
the two blocks of the loop's mirror symmetry about link 1, as the ring's kernel takes it
(`RingMachine`, the ring's own clearance_verlet._mirror_product). Above DENSE_LINK_LIMIT links the global law is
the machine's O(N) form (dynamics.models.machine_damping, each mode's ratio to 1e-5), not the ring's
(dynamics.models.reduced_damping, to 1e-4): closer to the dense C than the ring's (tested at 401
links); the ring's `damping_tolerance`, which names the ring's form, is refused. What keeps it from
being the ring's only kernel (docs/architecture.md, "The ring on the topology kernel"): the machine's
step costs more per step than the ring's outside the damping product (its span and impact loops over
the packed topology: benchmarks/bench_ring_on_topology.py), and there is no numpy path.
"""

from __future__ import annotations

import dataclasses
from functools import cached_property

import numpy as np

from dynamics.errors import DynamicsError
from dynamics.models.clearance_machine import ClearanceMachine
from dynamics.models.layout import LINK_DRIVE
from dynamics.solvers import cache, machine_verlet
from dynamics.solvers import clearance_verlet as verlet

KERNELS = ("ring", "topology")


@dataclasses.dataclass(frozen=True)
class RingMachine(ClearanceMachine):
    """The clearance machine on the single-link drive's topology, its global law's C w taken in the
    two blocks of the loop's mirror symmetry about link 1 (machine_verlet.mirror_packed: about half
    the multiply-adds of the whole C, as the ring's own kernel), the carriage's c_t as its own dashpot."""

    @cached_property
    def arrays(self):
        arr = ClearanceMachine.arrays.func(self)
        if self.span_damping != "global" or self.reduced_damping:
            return arr
        n = self.n_links
        mirror = machine_verlet.mirror_packed(self.damping_matrix, arr.par, n)
        if mirror is None:
            return arr
        dof_float = arr.dof_float.copy()
        dof_float[n:, 3] += np.diag(self.damping_matrix)[n:]  # the carriage's c_t (its row and column are 0 else)
        return dataclasses.replace(arr, cmat=mirror[0], par=mirror[1], dof_float=dof_float)


def machine_of(model) -> ClearanceMachine:
    """The ring `model` (a ClearanceChain) as the clearance machine on the single-link drive's
    topology (computed once per model: the solvers' cache)."""
    if model.damping_tolerance is not None and model.span_damping == "global":
        raise DynamicsError(
            f"kernel 'topology': damping_tolerance {model.damping_tolerance:g} is the ring's O(N) damping's; "
            "the machine's takes its own (machine_damping.default_tolerance above DENSE_LINK_LIMIT links, "
            "the dense C below); use kernel='ring' or damping_tolerance=None"
        )
    return cache.cached(
        ("ring on topology", model),
        lambda: RingMachine.of(
            model.chain, LINK_DRIVE, model.tensioner, model.clearance_m, model.span_damping, model.kv_beta_s
        ),
    )


@dataclasses.dataclass(frozen=True)
class RingRun(verlet.Run):
    """clearance_verlet's Run with the station peaks the machine kernel tracked at every step
    (machine_verlet.MachineRun.station_peaks; None: no stations asked)."""

    station_peaks: np.ndarray | None = None


def integrate(
    model,
    zd_nodes,
    zdd_nodes,
    step_s: float,
    y0,
    w0,
    *,
    u0: float = 0.0,
    ud0: float = 0.0,
    out_every: int = 1,
    record_from: int = 0,
    track_energy: bool = False,
    predictor: str = "euler",
    stations=None,
    node_flags=None,
) -> RingRun:
    """clearance_verlet.integrate's call and result, stepped by machine_verlet on the ring's topology
    (the carriage, when a tensioner is modelled, is its last DOF). The cam's lift is not needed: the
    link drive has no wheel whose feed angle it sets, so the lift nodes are zeros. `stations` (0-based
    links, the ring's DOFs) and `node_flags`: their peaks over every step, as the machine on its
    wheels gets them (machine_verlet.integrate)."""
    machine = machine_of(model)
    zd = np.ascontiguousarray(zd_nodes, dtype=float)
    n = model.n_links
    carriage = model.tensioner is not None
    q0 = np.r_[np.asarray(y0, dtype=float).reshape(n), [float(u0)] if carriage else []]
    v0 = np.r_[np.asarray(w0, dtype=float).reshape(n), [float(ud0)] if carriage else []]
    run = machine_verlet.integrate(
        machine,
        np.zeros_like(zd),
        zd,
        zdd_nodes,
        step_s,
        q0,
        v0,
        out_every=out_every,
        record_from=record_from,
        predictor=predictor,
        track_energy=track_energy,
        stations=stations,
        node_flags=node_flags,
    )
    rows = run.q.shape[0]
    return RingRun(
        run.q[:, :n],
        run.v[:, :n],
        run.a[:, :n],
        run.q[:, n] if carriage else np.zeros(rows),
        run.v[:, n] if carriage else np.zeros(rows),
        impacts=run.impacts,
        free_play_fraction=run.free_play_fraction,
        peak_tension_N=run.peak_tension_N,
        min_tension_N=run.min_tension_N,
        peak_force_in_impact_contact_N=run.peak_force_in_impact_contact_N,
        cam_work_J=run.cam_work_J,
        dissipated_damping_J=run.dissipated_damping_J,
        dissipated_friction_J=run.dissipated_friction_J,
        step_s=run.step_s,
        n_steps=zd.size - 1,
        impact_force_spike_N=run.impact_force_spike_N,
        impact_speeds_m_s=run.impact_speeds_m_s,
        impact_max_speed_m_s=run.impact_max_speed_m_s,
        impact_kinetic_energy_J=run.impact_kinetic_energy_J,
        impact_dissipated_J=run.impact_dissipated_J,
        station_peaks=run.station_peaks,
    )
