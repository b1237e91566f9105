"""The machine's lowest natural frequencies, one eigensolve per machine (cached): mode 1 gives the
steady-state searches' slowest decay per index cycle (machine_shooting.slowest_decay_per_cycle) and the
summary's lowest mode (dynamics.machine_scene.machine_lowest_mode), the NEAREST_RESONANCE_MODES lowest
the mode an index harmonic drives hardest (dynamics.machine_scene.machine_nearest_resonance), and the
REPORTED_MODES lowest the frequencies the run reports (stages.chain.natural_frequencies_Hz): the
reported f1 is lowest_mode's frequency, the same number.

One solve serves all three (MachineOnWheels.lowest_natural_frequencies_Hz, SOLVED_MODES): up to
DENSE_LINK_LIMIT links the dense eigensolve, whose first frequency is the same to the bit whatever the
count; above it one shift-invert Lanczos solve for the SOLVED_MODES lowest, its mode 1 the Rayleigh
quotient of its mode shape: within 2e-16 of the exact eigenvalue in omega^2 at 450 to 10,000 links,
where the shift-invert eigenvalue itself is 2.8e-13 to 1.4e-10 off (the factorisation's rounding;
docs/performance.md, "Long clearance chains on wheels"). Modes 2 and up are the shift-invert solve's.
"""

from __future__ import annotations

import numpy as np

from dynamics.solvers import cache

# the modes searched for the nearest resonance: at 1,000 links they reach 40 Hz, past the third index
# harmonic (on the default scene mode 7, 3.5 % below the second, is driven hardest); at 10,000 links
# only 4.0 Hz, and reaching the third harmonic there would take about 130 modes, 6.5 s of CPU against
# the scenario's 80 s (docs/performance.md)
NEAREST_RESONANCE_MODES = 12
REPORTED_MODES = 10  # natural frequencies the run reports per chain (summary.json, the report, the tables)
SOLVED_MODES = max(NEAREST_RESONANCE_MODES, REPORTED_MODES)  # the one solve's, enough for both


def lowest_frequencies_Hz(machine, count: int = NEAREST_RESONANCE_MODES) -> np.ndarray:
    """The machine's `count` (at most SOLVED_MODES) lowest natural frequencies (ascending; fewer for a
    machine with fewer modes), the first of the one SOLVED_MODES solve cached per machine."""
    if not 1 <= count <= SOLVED_MODES:
        raise ValueError(f"count: expected 1 to {SOLVED_MODES} modes (machine_modes.SOLVED_MODES), got {count!r}")
    return cache.cached(("machine lowest frequencies", machine), lambda: _solved(machine))[:count]


def _solved(machine) -> np.ndarray:
    frequencies = machine.lowest_natural_frequencies_Hz(SOLVED_MODES)
    frequencies.flags.writeable = False  # shared through the cache by every caller
    return frequencies


def lowest_frequency_Hz(machine) -> float:
    """The machine's lowest natural frequency: the first of lowest_frequencies_Hz (the same solve)."""
    return float(lowest_frequencies_Hz(machine)[0])
