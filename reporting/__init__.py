"""Results for people: tables, plots and the HTML page, shared by the orchestrators (`pipeline.py` and the study runner)."""
