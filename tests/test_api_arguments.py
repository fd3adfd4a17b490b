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
