"""Clearance chain (issue #11): the slow reference against Exudyn on the same windows.

`python benchmarks/run.py --only clearance_reference` (about a minute; `--quick`: 20 links only).

The window: 0..180 cam degrees at 180 rpm from rest, one-degree outputs, modified-sine indexing,
the default link's order of stiffness and mass (9.27e7 N/m, 2.03 kg), preload 2224 N, free play
0.1 mm per span, span damping beta = 2e-5 s; 20 and 85 links. Every method is driven by the same
input, the cam's acceleration held linearly between the output samples and its exact integrals
(HeldCam; the reference's cam_input="held"). Damping laws
both codes build: (a) C = beta K on y' always, and (b) Kelvin-Voigt beta k in contact only.

Methods (one line each in METHODS, so the fast solver can be added beside them):
- reference: verification.clearance_reference, DOP853 at rtol 1e-10 with contact events; and at rtol
  1e-8, whose difference from 1e-10 shows the reference's own error;
- exudyn: generalized-alpha (spectral radius 1) at 40 and 160 steps per output step, limit stops.

Agreement: the largest relative difference of the four stations' RMS x, v, a from the reference's
(relative to the largest station value). Times are wall time of one run (model building included
for the reference; Exudyn's solve alone, its model building is about as long again).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dynamics.cams import CamProgram
from dynamics.models.chain import ChainModel
from dynamics.response.metrics import rms, station_links
from verification.clearance_reference import HeldCam, reference_response

K = 9.27e7
MASS = 2.03
# the reference benchmark's own fixed scenario (issue #11), not the run's defaults: a change of a
# default must not move the figures it compares across trees
PRELOAD = 2224.0
GAP = 1e-4
BETA = 2e-5
T_WINDOW = np.arange(181) / (6.0 * 180.0)
CAM = CamProgram.indexing("modified-sine")
LAWS = ("a: C = beta K", "b: Kelvin-Voigt")


@dataclass(frozen=True)
class Case:
    n_links: int
    law: str

    def chain(self) -> dict:
        return dict(
            n_links=self.n_links,
            link_mass_kg=MASS,
            stiffness_N_per_m=K,
            drive_stiffness_N_per_m=K,
            preload_N=PRELOAD,
            clearance_m=GAP,
            t_eval_s=T_WINDOW,
        )


def _reference(case: Case, rtol: float):
    if case.law == LAWS[0]:
        model = ChainModel(case.n_links, MASS, K, rayleigh_coefficients=(0.0, BETA))
        damping = dict(damping_matrix=model.damping_matrix())
    else:
        damping = dict(span_damping_beta_s=BETA)
    start = time.perf_counter()
    r = reference_response(**case.chain(), cam=CAM, cam_input="held", rtol=rtol, **damping)
    return r, time.perf_counter() - start, f"{r.n_contact_changes} contact changes"


def _exudyn(case: Case, steps: int):
    from benchmarks.exudyn_chain import exudyn_chain_response

    r = exudyn_chain_response(
        **case.chain(),
        cam=HeldCam(CAM, T_WINDOW),
        span_damping_beta_s=BETA,
        damping_law="rayleigh" if case.law == LAWS[0] else "kelvin-voigt",
        steps_per_output=steps,
    )
    return r, r.wall_time_s, f"{r.n_steps} steps"


# (label, run(case) -> (response with x_m, v_m_s, a_m_s2; seconds; note)); the first is the yardstick
METHODS: list[tuple[str, Callable]] = [
    ("reference rtol 1e-10", lambda case: _reference(case, 1e-10)),
    ("reference rtol 1e-8", lambda case: _reference(case, 1e-8)),
    ("exudyn 40 steps/output", lambda case: _exudyn(case, 40)),
    ("exudyn 160 steps/output", lambda case: _exudyn(case, 160)),
]


def station_differences(ours, reference, n_links: int) -> list[float]:
    cols = [link - 1 for link in station_links(n_links).values()]
    out = []
    for name in ("x_m", "v_m_s", "a_m_s2"):
        a, b = rms(getattr(ours, name)[:, cols]), rms(getattr(reference, name)[:, cols])
        out.append(float(np.abs(a - b).max() / np.abs(b).max()))
    return out


def run(quick: bool) -> list[str]:
    try:
        import exudyn  # noqa: F401

        methods = METHODS
        missing = []
    except ImportError:
        methods = [m for m in METHODS if not m[0].startswith("exudyn")]
        missing = ["exudyn not installed (pip install -e '.[bench]'): its rows are left out"]
    lines = missing + [
        "180-degree window from rest, 180 rpm, modified sine, k 9.27e7 N/m, m 2.03 kg, P 2224 N, free play 0.1 mm, "
        "beta 2e-5 s",
        f"{'links':>5}  {'damping':16s} {'method':26s} {'time':>8}  {'RMS x':>8} {'RMS v':>8} {'RMS a':>8}  note",
    ]
    for n_links in (20,) if quick else (20, 85):
        for law in LAWS:
            case = Case(n_links, law)
            reference = None
            for label, method in methods:
                response, seconds, note = method(case)
                if reference is None:
                    reference = response
                    diffs = "reference".rjust(26)
                else:
                    diffs = " ".join(f"{d:8.1e}" for d in station_differences(response, reference, n_links))
                lines.append(f"{n_links:5d}  {law:16s} {label:26s} {seconds:7.2f}s  {diffs}  {note}")
    return lines


if __name__ == "__main__":
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    for line in run("--quick" in sys.argv):
        print(line, flush=True)
