"""What the Python API is given: a Scene (not a path), a run's output name, save_scene's path; a
scene built in Python warned of as a USD stage is; its summary lists no stage fallbacks."""

import os

import numpy as np
import pytest

from warp_tube import Simulation, load_scene
from warp_tube.scene.save import save_scene
from warp_tube.scene.spec import Scene, SceneError, StageInfo, TubeParams, TubeSpec

from .conftest import SCENES


def _python_scene(width=0.02, anchors=()) -> Scene:
    x = np.linspace(0.0, 0.2, 11)
    pts = np.stack([x, 0 * x, 0 * x], 1)
    tube = TubeSpec("/W/T", pts, [11], np.full(11, 0.5 * width), TubeParams(density=1050.0, youngs_modulus=1e5),
                    pinned=[0, 1], anchors=list(anchors))  # fmt: skip
    return Scene((tube,), stage=StageInfo(end_time_code=4))


def test_a_path_given_for_a_scene_is_named():
    with pytest.raises(TypeError, match=r"a str: expected a warp_tube.Scene \(a scene file: warp_tube.load_scene"):
        Simulation(str(SCENES / "default.usda"), device="cpu")


def test_an_empty_output_name_is_refused():
    sim = Simulation(_python_scene(), device="cpu", surface=False)
    with pytest.raises(SceneError, match="output '': an empty file name"):
        sim.run(frames=2, output="")
    assert sim.frame == 0  # (refused before anything ran)


def test_a_python_scene_gets_the_rest_shape_warnings(caplog):
    """A 0.2 m tube 0.6 m wide with an anchor on a pinned point, built in Python: the warnings a
    USD stage of it gets when read (tests/test_shape_notes.py)."""
    with caplog.at_level("WARNING"):
        Simulation(_python_scene(width=0.6, anchors=[1]), device="cpu", surface=False)
    said = " ".join(r.getMessage() for r in caplog.records)
    assert "/W/T.points: curve 0 is 0.2 m long and 0.6 m wide: shorter than its diameter" in said
    assert "/W/T.anchorPoints: point 1 is pinned" in said


def test_a_python_scenes_summary_lists_no_stage_fallbacks(tmp_path):
    """A StageInfo built in Python is given, not USD's fallback; a stage read without metersPerUnit
    authored still lists USD's."""
    summary = Simulation(_python_scene(), device="cpu", surface=False).run(frames=2)
    assert summary.stage_defaults == []
    text = (SCENES / "default.usda").read_text().replace("    metersPerUnit = 0.01\n", "")
    (tmp_path / "s.usda").write_text(text)
    read = Simulation(load_scene(str(tmp_path / "s.usda")), device="cpu", surface=False).run(frames=2)
    assert "metersPerUnit 0.01" in read.stage_defaults


def test_save_scene_refuses_bad_paths_and_writes_whole_files(tmp_path):
    scene = load_scene(str(SCENES / "default.usda"))
    for path, words in (("", "an empty scene name"), (str(tmp_path), "is a folder"), (str(tmp_path / "x.txt"), "extension .txt"),
                        (str(tmp_path / "no" / "x.usda"), "does not exist"),
                        (str(SCENES / "default.usda"), "refusing to write over an input")):  # fmt: skip
        with pytest.raises(SceneError, match=words):
            save_scene(scene, path)
    out = tmp_path / "copy.usda"
    out.write_text("precious")
    save_scene(scene, str(out))
    assert os.listdir(tmp_path) == ["copy.usda"]  # (no temporary file left)
    again = load_scene(str(out))
    # forces written as double3: the values as given, to the bit (float3 rounded 0.02 N by 4.5e-10 N)
    assert np.array_equal(again.forces[0].values, scene.forces[0].values)


@pytest.mark.parametrize("change, words", [
    (dict(params=TubeParams(density=1050.0, youngs_modulus=1e20)), "params.youngs_modulus: found 1e20: expected 0.001 to 1e13 Pa"),
    (dict(params=TubeParams(density=1e9, youngs_modulus=1e5)), "params.density: found 1e9: expected 0.01 to 1e6 kg/m^3"),
    (dict(radius=np.full(11, 1e-12)), "tube /W/T: a radius of 1e-12 m: expected 1e-9 to 1000 m"),
])  # fmt: skip
def test_a_python_scene_is_held_to_the_ranges_a_stage_is(change, words):
    """A scene built in Python: the physical ranges the USD reader checks each attribute against
    (scene/ranges.py), before anything runs; the same values in a stage are refused by its reader."""
    import dataclasses

    scene = _python_scene()
    scene = dataclasses.replace(scene, tubes=(dataclasses.replace(scene.tubes[0], **change),))
    with pytest.raises(SceneError, match=words.replace("^", r"\^").replace("(", r"\(")):
        Simulation(scene, device="cpu", surface=False)


def test_python_scene_settings_are_held_to_their_ranges():
    import dataclasses

    from warp_tube.scene.spec import SimulationSettings

    scene = _python_scene()
    for changes, words in ((dict(settings=SimulationSettings(time_step=100.0)), "settings.time_step: found 100 s"),
                           (dict(settings=SimulationSettings(gravity=(0.0, -1e9, 0.0))), "settings.gravity: found a magnitude of 1e9"),
                           (dict(stage=StageInfo(meters_per_unit=1e-12, end_time_code=4)), "stage.meters_per_unit: found 1e-12")):  # fmt: skip
        with pytest.raises(SceneError, match=words):
            Simulation(dataclasses.replace(scene, **changes), device="cpu", surface=False)


@pytest.mark.parametrize("make, words", [
    (lambda t: Scene(t), "tubes: TubeSpec: expected a tuple of TubeSpec"),
    (lambda t: Scene(x for x in [t]), "tubes: generator: expected a tuple of TubeSpec"),
    (lambda t: Scene((t,), settings={"gravity": (0, -9.8, 0)}), "settings: a dict: expected a SimulationSettings"),
    (lambda t: Scene((t,), stage=None), "stage: a NoneType: expected a StageInfo"),
    (lambda t: TubeSpec("/W/T", "abc", [11], 0.01, t.params), "points: text: expected real numbers"),
    (lambda t: TubeSpec("/W/T", t.points + 1j, [11], 0.01, t.params), "points: complex numbers: expected real numbers"),
    (lambda t: TubeSpec("/W/T", t.points, [11.5], 0.01, t.params), r"curveVertexCounts \[11.5\]: expected whole numbers"),
    (lambda t: TubeParams(density=1000.0, youngs_modulus=1e5, caps="no"), "caps 'no': expected True or False"),
    (lambda t: TubeParams(density=1000.0, youngs_modulus=1e5, reference_normal=(0, 1)), r"referenceNormal \(0, 1\): expected three"),
    (lambda t: TubeParams(density=1000.0, youngs_modulus=1e5, reference_normal=(0, 0, 0)), "not all 0"),
])  # fmt: skip
def test_a_scene_built_in_python_of_the_wrong_types_is_named(make, words):
    """Each spec refuses what would fail later or mean something else (``caps="no"`` was taken as
    True, 11.5 points as 11, a complex point as its real part): a SceneError naming the field."""
    tube = _python_scene().tubes[0]
    with pytest.raises(SceneError, match=words):
        make(tube)


def test_run_and_set_force_arguments_are_named():
    from warp_tube.scene.spec import ForceSpec

    scene = _python_scene()
    scene = Scene(scene.tubes, forces=(ForceSpec("/W/F", 0, 5, [0.0], [(0.0, 0.0, 0.0)]),), stage=scene.stage)
    sim = Simulation(scene, device="cpu", surface=False)
    with pytest.raises(ValueError, match=r"set_force\(0\): vector \[1000.*\.\.\.: expected three numbers of at most 1e9 N"):
        sim.set_force(0, [10**400, 0, 0])
    with pytest.raises(TypeError, match="output 5: a int: expected a file path"):
        sim.run(frames=2, output=5)
    with pytest.raises(TypeError, match="progress 5: a int: expected None, True or False, or a function"):
        sim.run(frames=2, progress=5)
    assert sim.frame == 0  # (refused before anything ran)
    with pytest.raises(TypeError, match="save_scene: scene is a str"):
        save_scene("notascene", "x.usda")
