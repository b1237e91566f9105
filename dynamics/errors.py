"""Errors of the dynamics stage. Each message is one line naming the input and what was expected."""


class DynamicsError(ValueError):
    """Bad input to a dynamics model, cam program or solver."""


class SolverDivergedError(DynamicsError):
    """A solver became unstable or its solution grew without bound; never returned as numbers."""


class SolverFailedError(DynamicsError):
    """A solver could not reach the end of the time span (step-size underflow, iteration limit)."""
