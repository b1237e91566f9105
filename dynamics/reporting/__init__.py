"""Results for people: plots, tables and the HTML report written by `pipeline.py`."""
