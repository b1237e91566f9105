"""Design studies: many designs of the link and the drive through the same stages as pipeline.py,
sampled or optimised, on a Dask cluster (see study.cli)."""
