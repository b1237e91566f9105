"""Analyses of a chain response: station metrics, the cam-speed sweep, the fidelity estimate."""
