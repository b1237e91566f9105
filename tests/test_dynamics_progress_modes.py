"""The dynamics stage's progress line names the modal solution only where a scenario's answer is the
single-link drive's linear chain solved in its lowest modes (stages.chain._modal_note): the chain on
its wheels (the default) and the clearance chain run on every link."""

from types import SimpleNamespace

from dynamics.models.reduction import MODES_FOR_LONG_CHAINS
from dynamics.scene import ChainModelKind
from settings import RunConfig
from stages.chain import _modal_note, chain_scene

PITCH_M = 0.1


def _ran(*models):
    return [SimpleNamespace(contact=SimpleNamespace(model=m)) for m in models]


def test_the_wheels_and_the_clearance_chain_are_not_said_to_run_in_modes():
    linear, clearance = ChainModelKind.LINEAR, ChainModelKind.CLEARANCE
    wheels = chain_scene(RunConfig(links=2000, drive="wheels"), PITCH_M)
    link = chain_scene(RunConfig(links=2000, drive="link"), PITCH_M)
    assert _modal_note(2000, wheels, _ran(linear, clearance)) == ""
    assert _modal_note(2000, link, _ran(clearance, clearance)) == ""
    short = chain_scene(RunConfig(links=85, drive="link"), PITCH_M)
    assert _modal_note(85, short, _ran(linear)) == ""


def test_the_link_drives_linear_chain_above_the_dense_limit_is():
    linear, clearance = ChainModelKind.LINEAR, ChainModelKind.CLEARANCE
    link = chain_scene(RunConfig(links=2000, drive="link"), PITCH_M)
    every = f", the linear chain solved in its {MODES_FOR_LONG_CHAINS} lowest modes"
    assert _modal_note(2000, link, _ran(linear, linear)) == every
    assert _modal_note(2000, link, _ran(linear, clearance)) == every + " (1 of 2 cam laws)"
