"""The run summary's notes: where the model departs from a plain elastic rod, the summary says so
(a user checking a textbook case against a run with an assistant line gets a third of the
deflection otherwise, with nothing in the output to say why)."""

import dataclasses

import pytest

from warp_tube import Simulation, load_scene

from .conftest import SCENES


def _notes(scene, **settings) -> list:
    if settings:
        scene = dataclasses.replace(scene, settings=dataclasses.replace(scene.settings, **settings))
    sim = Simulation(scene, device="cpu", surface=False)
    return sim.run(frames=2).notes


def test_an_active_assistant_line_is_noted_and_only_then():
    scene = load_scene(str(SCENES / "default.usda"))  # a push with its line, straight tube, auto: semi-implicit
    notes = _notes(scene)
    assert len(notes) == 1 and "the assistant line of /World/Push stiffens the pushed tube" in notes[0]
    off = dataclasses.replace(scene, forces=[dataclasses.replace(f, assistant_line=False) for f in scene.forces])
    assert _notes(off) == []


@pytest.mark.parametrize("integrator, noted", [("implicitEuler", True), ("semiImplicitEuler", False)])
def test_implicit_euler_on_a_curved_tube_is_noted(integrator, noted):
    scene = load_scene(str(SCENES / "intestine.usda"))  # curved
    notes = _notes(scene, integrator=integrator)
    assert any("implicit Euler on a curved tube" in n for n in notes) == noted


def test_notes_are_printed_in_the_summary():
    from warp_tube.sim.summary import RunSummary

    s = RunSummary(scene="s.usda", device="cpu", frames=1, substeps=1, dt=0.1, integrator="semiImplicitEuler",
                   reason="r", wall_time=0.1, max_displacement=0.0, notes=["n1"])  # fmt: skip
    assert "note         n1" in s.text().splitlines()

