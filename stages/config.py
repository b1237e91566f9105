"""Kept while the branches of issue #21 merge: RunConfig now lives in the settings package."""

from settings.run import RunConfig

__all__ = ["RunConfig"]
