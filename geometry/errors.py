"""The geometry stage's error: bad input (file, part, bores, mesh settings)."""


class GeometryError(ValueError):
    """Bad geometry input; the one-line message names the input and what was expected."""
