"""The error the FEA stage raises for bad input (unknown material, invalid mesh or options)."""


class FemError(ValueError):
    """Bad input to the FEA stage; the message names the input and what was expected."""


class FemWarning(UserWarning):
    """A result that stands but deserves a caution (poor elements, a locking-prone material)."""
