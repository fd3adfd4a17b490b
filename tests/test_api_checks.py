"""The Python API checks what the USD reader checks, and says what is wrong: scene dataclasses
built in code (units, gravity, indices, repeated prim paths), and the Simulation's accessors
(force and tube by index or path, world indices, pin targets by point)."""

import numpy as np
import pytest

import warp_tube
from warp_tube import ForceSpec, Scene, SceneError, SimulationSettings, StageInfo, TubeParams, TubeSpec


def tube(path="/T", pinned=(0, 1), **kw):
    x = np.linspace(0.0, 0.2, 11)
    return TubeSpec(path, np.stack([x, 0 * x, 0 * x], 1), [11], np.full(11, 0.01), TubeParams(density=1000.0, youngs_modulus=1e5),
                    pinned=list(pinned), **kw)  # fmt: skip


@pytest.mark.parametrize("make, words", [
    (lambda: StageInfo(meters_per_unit=0.0), ["metersPerUnit 0.0", "positive"]),
    (lambda: StageInfo(time_codes_per_second=float("nan")), ["timeCodesPerSecond"]),
    (lambda: StageInfo(up_axis="X"), ["upAxis 'X'"]),
    (lambda: SimulationSettings(gravity=(0.0, float("nan"), 0.0)), ["gravity", "three finite numbers"]),
    (lambda: SimulationSettings(gravity=(0.0, -9.8)), ["gravity (0.0, -9.8)", "three finite numbers"]),
    (lambda: TubeParams(density=1000.0, youngs_modulus=1e5, spokes=8.5), ["spokes 8.5", "integer"]),
    (lambda: tube(pinned=(0.5, 1.7)), ["pinnedPoints [0.5, 1.7]", "integers"]),
    (lambda: Scene((tube(), tube())), ["two tubes have the path /T"]),
    (lambda: Scene((tube(),), (ForceSpec("/T", 0, 5, [0.0], [[0, 0.01, 0]]),)), ["a tube and a force have the path /T"]),
    (lambda: ForceSpec("/F", 0, 2, [0.0], [[0, 1e12, 0]]), ["force /F", "1e+12 N", "at most 1e9 N"]),
    (lambda: StageInfo(start_time_code=10.0, end_time_code=5.0), ["startTimeCode 10.0, endTimeCode 5.0", "end >= start"]),
    (lambda: ForceSpec("/F", 0, 2.0, [0.0], [[0, 1, 0]]), ["point 2.0", "integer"]),
    # a path the output could not make a prim at (USD would say so only when the output is written)
    (lambda: tube(path="World T"), ["tube path 'World T'", "absolute USD prim path"]),
    (lambda: ForceSpec("F", 0, 2, [0.0], [[0, 1, 0]]), ["force path 'F'"]),
    (lambda: TubeParams(density="1000", youngs_modulus=1e5), ["density '1000'", "expected a number"]),
])  # fmt: skip
def test_scene_dataclasses_refuse_what_the_reader_refuses(make, words):
    with pytest.raises(SceneError) as err:
        make()
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_one_radius_serves_every_point_and_whole_float_indices_are_indices():
    t = tube(pinned=(0.0, 1.0))
    x = np.linspace(0.0, 0.2, 11)
    one = TubeSpec("/T", np.stack([x, 0 * x, 0 * x], 1), [11], 0.01, TubeParams(density=1000.0, youngs_modulus=1e5))
    assert one.radius.shape == (11,) and (one.radius == 0.01).all()
    assert t.pinned.tolist() == [0, 1]
    assert SimulationSettings(gravity=[0, -9.81, 0]).gravity == (0.0, -9.81, 0.0)


@pytest.fixture(scope="module")
def sim():
    push = ForceSpec("/World/Push", 0, 5, [0.0], [[0.0, 0.01, 0.0]], assistant_line=False)
    scene = Scene((tube("/World/Tube", pinned=(10, 0)),), (push,), stage=StageInfo(meters_per_unit=1.0, end_time_code=4.0))
    return warp_tube.Simulation(scene, device="cpu")


def test_forces_and_tubes_by_index_or_path(sim):
    from pxr import Sdf

    sim.set_force(Sdf.Path("/World/Push"), (0.0, 0.02, 0.0))  # a path as usd-core gives it
    sim.set_force(0, (0.0, 0.01, 0.0))
    with pytest.raises(TypeError, match="force 0.7: expected an index"):
        sim.set_force(0.7, (0.0, 0.01, 0.0))
    with pytest.raises(KeyError, match="no force at /World/Pull"):
        sim.set_force("/World/Pull", (0.0, 0.01, 0.0))
    with pytest.raises(IndexError, match="force 3: the scene has 1 force"):
        sim.set_force(3, (0.0, 0.01, 0.0))


def test_world_indices_are_checked(sim):
    assert len(sim.centerline_points(0)[0]) == 11
    with pytest.raises(IndexError, match="world 1: this Simulation runs 1 world"):
        sim.centerline_points(1)
    with pytest.raises(IndexError, match="world 5"):
        sim.surface_points(world=5)


def test_pin_targets_follow_the_pinned_indices_ascending_or_a_dict(sim):
    """``pinnedPoints = [10, 0]``: rows are for points 0 then 10 (ascending); a dict names them."""
    assert sim.scene.tubes[0].pinned.tolist() == [0, 10]
    far_end = (0.2, 0.05, 0.0)
    sim.set_pin_targets("/World/Tube", {10: far_end, 0: (0.0, 0.0, 0.0)})
    sim.step()
    q = sim.centerline_points()[0]
    assert np.allclose(q[10], far_end, atol=1e-6) and np.allclose(q[0], 0.0, atol=1e-6)  # pins reach their targets
    with pytest.raises(ValueError, match="expected every pinned point once"):
        sim.set_pin_targets(0, {10: far_end})


def test_numerical_error_is_exported():
    from warp_tube.sim.simulation import NumericalError

    assert warp_tube.NumericalError is NumericalError


def test_save_scene_writes_what_load_scene_reads_back(tmp_path):
    """A tube at the path the settings prim would take, a second root, a gravity of no float32
    value: the settings prim takes a free name, every ancestor is an Xform, gravity is kept to the
    bit (before: the reload failed, the root was typeless, gravity came back as 9.8100004)."""
    from pxr import Usd

    from warp_tube.scene.usd import load_scene, save_scene

    a, b = tube(path="/W/Simulation"), tube(path="/B/Deep/T")
    settings = SimulationSettings(integrator="implicitEuler", time_step=0.002, gravity=(0.0, -9.81, 0.0))
    scene = Scene((a, b), (ForceSpec("/W/Push", 1, 5, [0.0], [[0.0, 0.01, 0.0]]),), settings=settings)
    save_scene(scene, str(tmp_path / "s.usda"))
    back = load_scene(str(tmp_path / "s.usda"))
    assert [t.path for t in back.tubes] == ["/W/Simulation", "/B/Deep/T"] and back.forces[0].tube == 1
    assert back.settings == settings
    stage = Usd.Stage.Open(str(tmp_path / "s.usda"))
    assert [stage.GetPrimAtPath(p).GetTypeName() for p in ("/W", "/B", "/B/Deep")] == ["Xform"] * 3


def test_save_scene_keeps_moving_pins(tmp_path):
    """A tube whose pinned end follows a track (one position per frame) saved and read back has
    the same track (float32 round-off of the stage's points)."""
    from warp_tube.scene.usd import load_scene, save_scene

    t = tube(pinned=(0, 10))
    frames = 5
    track = np.repeat(t.points[[0, 10]][None], frames, axis=0)
    track[:, 1, 1] = np.linspace(0.0, 0.05, frames)  # the far end rises 5 cm over the frames [m]
    moving = TubeSpec(t.path, t.points, t.curve_counts, t.radius, t.params, pinned=t.pinned, pin_track=track)
    scene = Scene((moving,), stage=StageInfo(meters_per_unit=0.01, end_time_code=float(frames - 1)))
    save_scene(scene, str(tmp_path / "moving.usda"))
    back = load_scene(str(tmp_path / "moving.usda")).tubes[0]
    assert back.pin_track is not None and back.pin_track.shape == track.shape
    np.testing.assert_allclose(back.pin_track, track, atol=1e-7)  # [m]: float32 of centimetres
    np.testing.assert_allclose(back.points, t.points, atol=1e-7)


def test_the_run_summary_counts_the_set_up_apart(tmp_path, capsys):
    """The summary's set-up holds setting up the output and what the caller spent before the run
    (the CLI: reading and building), apart from the frames' wall time."""
    from warp_tube.cli import main

    push = ForceSpec("/World/Push", 0, 5, [0.0], [[0.0, 0.01, 0.0]], assistant_line=False)
    scene = Scene((tube("/World/Tube"),), (push,), stage=StageInfo(meters_per_unit=1.0, end_time_code=2.0))
    summary = warp_tube.Simulation(scene, device="cpu").run(output=str(tmp_path / "o.usdc"), setup_time=1.5)
    assert 1.5 < summary.setup_time < 1.5 + 60.0  # the caller's 1.5 s plus the output's set-up
    assert "set-up       " in summary.text() and "s for the frames" in summary.text()
    assert main(["run", "-o", str(tmp_path / "tube.usdc"), "--frames", "2"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("set-up"))
    assert float(line.split()[1]) > 0.0


def test_a_force_on_a_pinned_point_is_warned_of_in_code_too(caplog):
    """The USD reader warns of a force on a pinned point; a scene built in code and set_force on
    such a force warn the same (it does nothing)."""
    push = ForceSpec("/World/Push", 0, 1, [0.0], [[0.0, 0.01, 0.0]], assistant_line=False)
    scene = Scene((tube("/World/Tube", pinned=(0, 1)),), (push,), stage=StageInfo(meters_per_unit=1.0, end_time_code=2.0))
    with caplog.at_level("WARNING"):
        sim = warp_tube.Simulation(scene, device="cpu", surface=False)
        sim.set_force(0, (0.0, 0.02, 0.0))
    text = " ".join(r.getMessage() for r in caplog.records)
    assert "force /World/Push: point 1 of /World/Tube is pinned: this force does nothing" in text
    assert "set_force(0): point 1 of /World/Tube is pinned" in text


def test_the_stages_are_reachable_from_the_package_without_importing_them():
    """``import warp_tube`` then ``warp_tube.batch.run_batch`` and ``warp_tube.scene.usd.save_scene``
    (the README's spelling), in a fresh interpreter; a name that is no module stays an AttributeError."""
    import subprocess
    import sys

    code = ("import warp_tube\n"
            "print(warp_tube.batch.run_batch.__name__, warp_tube.scene.usd.save_scene.__name__)\n"
            "try:\n    warp_tube.nothing\nexcept AttributeError as e:\n    print('AttributeError', e)\n")  # fmt: skip
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("\n")[:2] == ["run_batch save_scene", "AttributeError module 'warp_tube' has no attribute 'nothing'"]


def test_run_batch_says_it_takes_a_scene_file_not_a_scene(tmp_path):
    from warp_tube.batch import run_batch

    with pytest.raises(SceneError, match="run_batch: scene is a Scene: expected a path .*save_scene"):
        run_batch(Scene((tube(),)), str(tmp_path / "out"))
    assert not (tmp_path / "out").exists()
