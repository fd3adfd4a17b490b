"""The Python API and long runs as a user meets them: arguments checked at the call with a message
naming them, a failed frame that leaves the Simulation usable, progress for a function, a log file
and a terminal that reports no width, one thread at a time, no pickling, and outputs refused up
front where the disk cannot hold them."""

import copy
import os
import pickle
import pty
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest

import warp_tube
from warp_tube import Simulation
from warp_tube.cli import main
from warp_tube.runtime.interrupts import Terminated
from warp_tube.runtime.progress import PlainProgress
from warp_tube.scene.spec import SceneError

from .bad_inputs import KEEP, scene
from .conftest import ROOT, SCENES
from .layer_proxy import LayerProxy


@pytest.fixture(scope="module")
def default_scene():
    return warp_tube.load_scene(str(SCENES / "default.usda"))


@pytest.fixture
def sim(default_scene):
    return Simulation(default_scene, device="cpu")


def _rest_pins(scene):
    """The default tube's pinned points [stage units] (points 0 and 1)."""
    return scene.tubes[0].points[scene.tubes[0].pinned] / scene.stage.meters_per_unit


# -- arguments checked at the call ------------------------------------------------------------------


@pytest.mark.parametrize("vector, words", [
    ((1e40, 0.0, 0.0), "at most 1e9 N"),  # finite in float64, infinite in the model's float32
    ((0.0, 2e9, 0.0), "at most 1e9 N"),  # a scene's warptube:force is refused beyond 1e9 N too
    ([True, False, True], "expected three numbers"),
    ((True, 0, 0), "expected three numbers"),  # a bool among numbers: an int array to NumPy (was 1 N)
])  # fmt: skip
def test_set_force_refuses_what_a_scene_refuses(sim, vector, words):
    with pytest.raises(ValueError, match=words):
        sim.set_force("/World/Push", vector)
    sim.step()  # the scene's own force still acts: nothing blew up, auto did not give up on semi-implicit Euler
    assert sim.frame == 1 and sim.integrator == "semiImplicitEuler" and sim.warnings == []


def test_pin_targets_refuse_far_targets_and_keys_that_are_not_indices(sim, default_scene):
    rest = _rest_pins(default_scene)
    with pytest.raises(ValueError, match="a coordinate of 1e\\+38 m: expected at most 1e6 m"):
        sim.set_pin_targets("/World/Tube", rest + [0.0, 1e40, 0.0])  # 1e40 cm
    with pytest.raises(ValueError, match="expected every pinned point once"):
        sim.set_pin_targets("/World/Tube", {"0": rest[0], "1": rest[1]})


def test_a_frame_that_fails_while_dragging_a_pin_leaves_the_next_frame_free_of_it(sim, default_scene):
    rest = _rest_pins(default_scene)
    sim.step()
    sim.set_pin_targets("/World/Tube", rest + [0.0, 1e7, 0.0])  # 100 km in one frame: no integrator follows
    with pytest.raises(warp_tube.NumericalError):
        sim.step()
    assert sim.frame == 1
    sim.set_pin_targets("/World/Tube", rest + [0.0, 1.0, 0.0])  # 1 cm: an easy drag
    sim.step()
    sim.step()
    assert sim.frame == 3
    # the pins are where they were asked to be; float32 positions in metres: 1e-6 stage units of round-off
    np.testing.assert_allclose(sim.centerline_points()[0][:2], rest + [0.0, 1.0, 0.0], atol=1e-6)
    assert np.isfinite(sim.centerline_points()[0]).all()


@pytest.mark.parametrize("kwargs, words", [
    ({"frames": 3.5}, "frames 3.5: expected a whole number"),
    ({"frames": "4"}, "frames '4': expected a whole number"),
    ({"frames": True}, "frames True: expected a whole number"),
    ({"frames": 4, "every": 1.5}, "every 1.5: expected a whole number"),
])  # fmt: skip
def test_run_refuses_frames_and_every_that_are_not_whole_numbers(sim, tmp_cwd, kwargs, words):
    with pytest.raises(SceneError, match=words):
        sim.run(output="out.usdc", **kwargs)
    assert sim.frame == 0 and list(tmp_cwd.iterdir()) == []


def test_run_takes_a_whole_float_as_frames(sim, tmp_cwd):
    s = sim.run(frames=3.0, every=np.int64(1), output="out.usdc")
    assert (s.first_frame, s.last_frame, s.frames) == (0, 2, 3) and (tmp_cwd / "out.usdc").is_file()


@pytest.mark.parametrize("count, words", [
    (0, "world_count 0: expected at least 1"),
    (-1, "world_count -1: expected at least 1"),
    (1.5, "world_count 1.5: expected a whole number"),
    (True, "world_count True: expected a whole number"),
])  # fmt: skip
def test_world_count_is_checked_at_the_call(default_scene, count, words):
    with pytest.raises(SceneError, match=words):
        Simulation(default_scene, device="cpu", world_count=count)


def test_a_simulation_says_it_cannot_be_pickled_or_copied(sim):
    for how in (pickle.dumps, copy.deepcopy):
        with pytest.raises(TypeError, match="cannot be pickled or copied: pickle its scene"):
            how(sim)
    assert pickle.loads(pickle.dumps(sim.scene)).tubes[0].path == "/World/Tube"  # what it says to do works


# -- progress ---------------------------------------------------------------------------------------


def test_a_progress_function_gets_frames_done_and_their_total_and_no_bar_is_drawn(sim, capsys):
    calls = []
    sim.step()
    sim.run(frames=5, progress=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 3), (2, 3), (3, 3)]  # frames 2, 3 and 4 simulated from frame 1
    assert capsys.readouterr().err == ""


def test_plain_progress_writes_a_line_per_interval_with_the_time_left():
    lines, now = [], [0.0]

    class Out:
        def write(self, text):
            lines.append(text)

        def flush(self):
            pass

    p = PlainProgress(interval=30.0, stream=Out(), clock=lambda: now[0])
    for done, t in [(1, 5.0), (100, 20.0), (301, 35.0), (400, 50.0), (601, 65.1), (1000, 100.0)]:
        now[0] = t
        p(done, 1000)
    text = "".join(lines)
    # from the first call (t = 5 s, frame 1) on: 300 frames in 30 s, 699 left at 10 frames/s; then
    # 600 in 60.1 s, 399 left; the last frame prints nothing (the summary follows)
    assert text == ("warp-tube: simulating: 301 of 1,000 frames (30%), 30 s so far, about 70 s left\n"
                    "warp-tube: simulating: 601 of 1,000 frames (60%), 60 s so far, about 40 s left\n")  # fmt: skip


def test_cli_run_to_a_log_file_prints_progress_lines(tmp_cwd, capsys, monkeypatch):
    import warp_tube.runtime.progress as progress

    monkeypatch.setattr(progress, "PLAIN_INTERVAL", 0.0)  # a line after every frame
    (tmp_cwd / "scene.usda").write_text(scene())
    assert main(["run", "scene.usda", "-o", "out.usdc", "--frames", "5"]) == 0
    err = capsys.readouterr().err  # (not a terminal under pytest: no bar)
    assert "warp-tube: simulating: 2 of 4 frames (50%)" in err and "warp-tube: simulating: 3 of 4 frames (75%)" in err
    assert "left" in err and "4 of 4" not in err


def test_the_progress_bar_is_drawn_on_a_terminal_that_reports_no_width(tmp_path):
    (tmp_path / "scene.usda").write_text(scene())
    master, slave = pty.openpty()  # a new pty reports 0 columns and 0 rows until a size is set
    assert os.get_terminal_size(slave).columns == 0
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    p = subprocess.Popen([sys.executable, "-m", "warp_tube", "run", "scene.usda", "-o", "o.usdc", "--frames", "4"],
                         cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=slave, env=env)  # fmt: skip
    os.close(slave)
    seen = bytearray()

    def read():
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO once the child has closed the terminal
                return
            if not chunk:
                return
            seen.extend(chunk)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    out, _ = p.communicate(timeout=120)
    reader.join(timeout=10)
    os.close(master)
    assert p.returncode == 0 and b"frames       4 written" in out
    assert b"simulating:" in seen and b"frame" in seen  # the bar (tqdm draws nothing at 0 columns)


def test_a_terminated_run_says_so_in_its_summary(sim, tmp_cwd, monkeypatch):
    real = Simulation.step

    def step(self):
        if self.frame == 2:
            raise Terminated(signal.SIGTERM)
        real(self)

    monkeypatch.setattr(Simulation, "step", step)
    with pytest.raises(Terminated):
        sim.run(frames=5, output="out.usdc")
    s = sim.last_summary
    assert s.stopped == "terminated (SIGTERM)" and s.partial == str(tmp_cwd / "out.partial.usdc")
    assert not (tmp_cwd / "out.usdc").exists()


# -- threads ----------------------------------------------------------------------------------------


def test_step_from_a_second_thread_waits_for_a_run_to_end(sim, tmp_cwd):
    go, inside = threading.Event(), threading.Event()

    def hold(done, total):
        if done == 1:
            inside.set()
            assert go.wait(30)

    runner = threading.Thread(target=lambda: sim.run(frames=4, output="out.usdc", progress=hold))
    runner.start()
    assert inside.wait(30)
    stepper = threading.Thread(target=sim.step)
    stepper.start()
    stepper.join(1.0)
    assert stepper.is_alive()  # held back while the run is inside its frames
    go.set()
    runner.join(30)
    stepper.join(30)
    assert sim.last_summary.output == str(tmp_cwd / "out.usdc") and sim.last_summary.frames == 4
    assert sim.frame == 4  # the run's frames 1-3, then the step


# -- disk ---------------------------------------------------------------------------------------------


def test_an_output_larger_than_the_free_disk_space_is_refused_before_it_starts(tmp_cwd, capsys, monkeypatch):
    import warp_tube.runtime.memory as memory

    (tmp_cwd / "scene.usda").write_text(scene())
    (tmp_cwd / "out.usdc").write_bytes(KEEP)
    monkeypatch.setattr(memory, "available_disk", lambda folder: 10_000)  # bytes: less than the topology alone
    assert main(["run", "scene.usda", "-o", "out.usdc"]) == 2
    err = capsys.readouterr().err
    assert f"more than the 10.0 kB free in {tmp_cwd}; free some space\n" in err and "internal error" not in err
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["out.usdc", "scene.usda"]
    assert (tmp_cwd / "out.usdc").read_bytes() == KEEP


@pytest.mark.parametrize("suffix", [".usdc", ".usda"])
def test_the_free_space_check_counts_what_an_output_holds_once(tmp_cwd, capsys, monkeypatch, suffix):
    """The topology, texture coordinates and metadata are written once (the default scene's 3
    frames: ~23 of 55 kB): a folder with less free space than the file takes is refused before
    the run, and one with twice that is not (the estimate is an upper bound, not a wild one)."""
    import warp_tube.runtime.memory as memory

    (tmp_cwd / "scene.usda").write_text(scene())
    assert main(["run", "scene.usda", "-o", "first" + suffix, "--frames", "3", "--quiet"]) == 0
    size = (tmp_cwd / ("first" + suffix)).stat().st_size
    monkeypatch.setattr(memory, "available_disk", lambda folder: size - 1)
    assert main(["run", "scene.usda", "-o", "out" + suffix, "--frames", "3", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "bytes of topology and metadata), more than the" in err and "write fewer frames" in err
    assert not (tmp_cwd / ("out" + suffix)).exists()
    monkeypatch.setattr(memory, "available_disk", lambda folder: 2 * size)
    assert main(["run", "scene.usda", "-o", "out" + suffix, "--frames", "3", "--quiet"]) == 0
    assert (tmp_cwd / ("out" + suffix)).stat().st_size == size


# -- Ctrl-C while saving ------------------------------------------------------------------------------


@pytest.fixture
def interrupted_saves(monkeypatch):
    """usd-core's Save interrupted by Ctrl-C: the signal arrives while the native save runs, so
    Python handles it as soon as the save returns."""
    from warp_tube.io.writer import StageWriter

    class Layer(LayerProxy):
        def Save(self):
            done = self._layer.Save()
            signal.raise_signal(signal.SIGINT)
            return done

    real = StageWriter._save_to

    def save_to(self, final):
        self.layer = Layer(self.layer)
        return real(self, final)

    monkeypatch.setattr(StageWriter, "_save_to", save_to)


def _times(path):
    from pxr import Usd, UsdGeom

    st = Usd.Stage.Open(str(path))
    return list(UsdGeom.BasisCurves(st.GetPrimAtPath("/World/Tube/Centerline")).GetPointsAttr().GetTimeSamples())


def test_ctrl_c_while_the_result_is_saved_keeps_the_complete_result(sim, tmp_cwd, interrupted_saves):
    s = sim.run(frames=4, output="out.usdc")
    assert s.output == str(tmp_cwd / "out.usdc") and _times(tmp_cwd / "out.usdc") == [0.0, 1.0, 2.0, 3.0]
    assert sim.warnings == ["interrupted while saving out.usdc: the save was finished: the output is complete"]
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["out.usdc"]


def test_a_second_ctrl_c_while_the_partial_is_saved_keeps_it(sim, tmp_cwd, interrupted_saves, monkeypatch):
    real = Simulation.step

    def step(self):
        if self.frame == 2:
            raise KeyboardInterrupt
        real(self)

    monkeypatch.setattr(Simulation, "step", step)
    with pytest.raises(KeyboardInterrupt):
        sim.run(frames=5, output="out.usdc")
    assert sim.last_summary.partial == str(tmp_cwd / "out.partial.usdc")
    assert _times(tmp_cwd / "out.partial.usdc") == [0.0, 1.0, 2.0]
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["out.partial.usdc"]


def test_simulations_of_one_process_stepping_in_threads_take_turns():
    """A graph capture records every launch and copy on its device, from any thread: separate
    Simulations run from four threads made Warp errors ("APIC capture does not yet support
    wp.copy() ...") in most runs and crashed the process (double free) in some. They take turns
    (one lock for all simulations and batches of a process), each ending exactly as alone."""
    scene = warp_tube.load_scene(os.path.join(SCENES, "default.usda"))
    alone = Simulation(scene, device="cpu")
    alone.run(frames=30)
    expected = alone.centerline_points()[0]
    out, errors = {}, []

    def go(k):
        try:
            sim = Simulation(scene, device="cpu")
            sim.run(frames=30)
            out[k] = sim.centerline_points()[0]
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(repr(e))

    threads = [threading.Thread(target=go, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert sorted(out) == [0, 1, 2, 3]
    for points in out.values():
        np.testing.assert_array_equal(points, expected)  # the CPU is deterministic
