"""Cam motion: rise laws with analytic s, v, a, j; index-dwell programs; Dynacam-style SVAJ tables."""

from dynamics.cams.laws import MotionLaw, get_law, law_ids, register_law
from dynamics.cams.program import CamProgram, Segment, mqp2012_program
from dynamics.cams.svaj_io import TabulatedCam, read_svaj_table, write_svaj_table

__all__ = [
    "CamProgram",
    "MotionLaw",
    "Segment",
    "TabulatedCam",
    "get_law",
    "law_ids",
    "mqp2012_program",
    "read_svaj_table",
    "register_law",
    "write_svaj_table",
]
