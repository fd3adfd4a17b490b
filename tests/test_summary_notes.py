"""The run summary's notes: where the model departs from a plain elastic rod, the summary says so
(a user checking a textbook case against a run with an assistant line gets a third of the
deflection otherwise, with nothing in the output to say why)."""

import dataclasses

import numpy as np

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



def _forced(tmp_path, step: float):
    """The default scene forced to semi-implicit Euler at ``step`` [s] (its bound: 1.74e-3 s at 168
    substeps of a 24 fps frame, the summary's figure), pushed by 1e4 N (a blow-up past the bound)."""
    text = (SCENES / "default.usda").read_text()
    text = text.replace('token warptube:integrator = "auto"', f'token warptube:integrator = "semiImplicitEuler"\n        double warptube:timeStep = {step!r}')
    text = text.replace("24: (0, 0.02, 0)", "24: (0, 1e4, 0)")
    path = tmp_path / "forced.usda"
    path.write_text(text)
    return path


def test_check_warns_of_a_time_step_beyond_the_stability_bound(tmp_path, capsys, caplog):
    from warp_tube.cli import main

    with caplog.at_level("WARNING"):
        assert main(["check", str(_forced(tmp_path, 0.01))]) == 0
    said = " ".join(r.getMessage() for r in caplog.records)
    assert "forced.usda: warptube:timeStep 0.01 s exceeds the semi-implicit Euler stability bound" in said
    caplog.clear()
    with caplog.at_level("WARNING"):
        assert main(["check", str(_forced(tmp_path, 1e-5))]) == 0  # within the bound: nothing
    assert "exceeds the semi-implicit Euler stability bound" not in " ".join(r.getMessage() for r in caplog.records)


def test_a_forced_integrator_that_fails_points_to_auto(tmp_path):
    from warp_tube import NumericalError

    sim = Simulation(load_scene(str(_forced(tmp_path, 0.01))), device="cpu", surface=False)
    with pytest.raises(NumericalError) as err:
        sim.run(frames=48)
    assert 'warptube:integrator "auto" redoes a failed frame' in str(err.value)


def test_strained_segment_on_exact_lengths():
    from warp_tube.sim.notes import strained_segment

    x = np.concatenate([[0.0], np.cumsum([1.0, 1.0, 2.5, 1.0])])
    q = np.stack([x, 0 * x, 0 * x], 1)
    rest = np.array([1.0, 1.0, 1.0, 1.0, 0.0])  # (the last node has no segment)
    assert strained_segment(q, rest) == (2, 2.5)
    x = np.concatenate([[0.0], np.cumsum([1.0, 0.4, 1.2, 1.0])])
    assert strained_segment(np.stack([x, 0 * x, 0 * x], 1), rest) == (1, pytest.approx(0.4))  # compressed 2.5x
    x = np.concatenate([[0.0], np.cumsum([1.0, 1.4, 0.72, 1.0])])
    assert strained_segment(np.stack([x, 0 * x, 0 * x], 1), rest) is None  # within 1.5x either way


@pytest.mark.parametrize("force, warned", [(31.4, True), (3.0, False)])
def test_a_tube_stretched_past_small_strains_is_warned_of(force, warned):
    """The default tube (radius 1 cm, E = 1e5 Pa: EA = 31.4 N) pulled along its axis at its free end
    without the line: static strain F / EA (Hooke), 100% at 31.4 N (warned), 10% at 3 N (not: with
    the dynamic overshoot at most 2x, 20%)."""
    scene = load_scene(str(SCENES / "default.usda"))
    push = dataclasses.replace(scene.forces[0], point=20, assistant_line=False,
                               values=np.tile([force, 0.0, 0.0], (len(scene.forces[0].times), 1)))  # fmt: skip
    sim = Simulation(dataclasses.replace(scene, forces=[push]), device="cpu", surface=False)
    sim.run(frames=24)
    assert any("its rest length: the springs are linear" in w for w in sim.warnings) == warned


def test_stretch_on_exact_lengths():
    from warp_tube.sim.notes import stretch

    x = np.concatenate([[0.0], np.cumsum([1.0, 2.0, 1.0])])
    y = np.concatenate([[0.0], np.cumsum([1.0, 0.25, 1.0])])
    q = np.stack([np.stack([x, 0 * x, 0 * x], 1), np.stack([y, 0 * y, 0 * y], 1)])  # two worlds
    rest = np.array([[1.0, 1.0, 1.0, 0.0]])  # shared by the worlds; the last node has no segment
    np.testing.assert_allclose(stretch(q, rest), [2.0, 4.0])  # stretched 2x; compressed to a quarter


def test_a_batchs_max_stretch_is_the_largest_over_its_frames(tmp_path):
    """summary.csv's max_stretch against the same figure computed from the batch's own centerline
    arrays, every frame (stage units, the scene's rest lengths): the default tube pulled along its
    axis at its tip, without its line, by 3 N and by 31.4 N (EA = 31.4 N: about 2x near rest). A
    load applied at once overshoots its static stretch (up to twice the static strain, undamped),
    so the largest stretch is well above the last frame's."""
    import csv

    from warp_tube.batch import run_batch

    from .test_batch import DEFAULT, FORCE, write_table

    table = write_table(tmp_path / "t.csv", [FORCE, "/World/Push.warptube:point", "/World/Push.warptube:assistantLine"],
                        [("(3, 0, 0)", "20", "false"), ("(31.4, 0, 0)", "20", "false")])  # fmt: skip
    out = tmp_path / "out"
    assert run_batch(str(DEFAULT), str(out), str(table), layout="arrays", frames=48, device="cpu", writers=0).ok == 2
    with open(out / "summary.csv") as f:
        got = np.array([float(r["max_stretch"]) for r in csv.DictReader(f)])
    frames = np.load(out / "centerline.npy").astype(np.float64)  # (variants, frames, points, 3), stage units
    rest = np.linalg.norm(np.diff(frames[:, 0], axis=1), axis=-1)
    ratio = np.linalg.norm(np.diff(frames[:, 1:], axis=2), axis=-1) / rest[:, None]
    expected = np.maximum(ratio, 1.0 / ratio).max(axis=(1, 2))
    np.testing.assert_allclose(got, expected, rtol=1e-5)  # (float32 positions: ~1e-7 of a length)
    last = np.maximum(ratio[:, -1], 1.0 / ratio[:, -1]).max(axis=1)
    assert got[0] < 1.5 < 1.8 < got[1]  # 10% strain, about 100% and more
    assert np.all(got > 1.05 * last)  # the overshoot, not the last frame


def test_stepping_warns_of_a_strained_segment_too():
    """A grasper's jerk through step(): the default tube's clamped end moved 40 cm (its length is
    20 cm) in one frame. The blow-up check is off once pins move (their work is not measured), so
    the frame stands; its segments are stretched far past 1.5x, which step() warns of once."""
    scene = load_scene(str(SCENES / "default.usda"))
    sim = Simulation(scene, device="cpu", surface=False)
    pins = sim.centerline_points()[0][[0, 1]].copy()
    sim.set_pin_targets(0, pins + [0.0, 40.0, 0.0])  # stage units: cm
    for _ in range(3):
        sim.step()
    said = [w for w in sim.warnings if "its rest length: the springs are linear" in w]
    assert len(said) == 1 and said[0].startswith("frame 1: ")


def test_a_frame_that_fails_leaves_the_integrator_as_it_was():
    """A pin target 1e7 stage units away: the frame fails even after auto's retries and its switch
    to implicit Euler, and is not kept; nor is the switch (the next frames ran implicit before)."""
    from warp_tube import NumericalError

    scene = load_scene(str(SCENES / "default.usda"))
    sim = Simulation(scene, device="cpu", surface=False)
    before = (sim.integrator, sim.substeps, sim.dt, sim.reason)
    pins = sim.centerline_points()[0][[0, 1]].copy()
    sim.set_pin_targets(0, pins + 1e7)
    with pytest.raises(NumericalError):
        sim.step()
    assert (sim.integrator, sim.substeps, sim.dt, sim.reason) == before and sim.frame == 0
    assert not [w for w in sim.warnings if "switched to implicit Euler" in w]
    sim.set_pin_targets(0, pins)
    sim.step()
    assert sim.frame == 1 and sim.integrator == before[0]


def test_a_batch_says_which_variants_were_strained(tmp_path):
    """The batch's summary says how many variants had a segment past 1.5x at some frame, naming the first
    (the 31.4 N pull: about 2x), as run warns; the 3 N one is not named."""
    from warp_tube.batch import run_batch

    from .test_batch import DEFAULT, FORCE, write_table

    table = write_table(tmp_path / "t.csv", [FORCE, "/World/Push.warptube:point", "/World/Push.warptube:assistantLine"],
                        [("(3, 0, 0)", "20", "false"), ("(31.4, 0, 0)", "20", "false")])  # fmt: skip
    result = run_batch(str(DEFAULT), str(tmp_path / "out"), str(table), layout="arrays", frames=48, device="cpu", writers=0)
    assert [name for name, _ in result.strained] == ["variant_00001"] and result.strained[0][1] > 1.8
    assert "strain       1 variant(s) had a segment beyond 1.5x its rest length (first variant_00001" in result.text()
