"""One design through the stages geometry -> fem -> dynamics, as functions of a RunConfig.

The two orchestrators, `pipeline.py` (one design, from the command line) and the study runner
(many designs), both call these; neither holds stage logic of its own.
"""
