"""Errors of the dynamics stage. Each message is one line naming the input and what was expected."""


class DynamicsError(ValueError):
    """Bad input to a dynamics model, cam program or solver."""
