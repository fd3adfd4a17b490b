"""Ctrl-C (SIGINT) on `warp-tube run`, in a subprocess: during the kernel compile and mid-run.

The run is stopped at a known point by ``WARP_TUBE_PAUSE_AT`` (it prints a line and sleeps there),
so the signal arrives where the test says, not where the scheduler happens to be. A third test
interrupts a real compile: an empty kernel cache, and the signal sent as soon as Warp reports its
first compiled module (a second one is compiling then). In every case: exit status 130, the existing
output byte for byte as it was, no temporary file left, and the finished frames, if any, in a valid
``OUT.partial.usdc`` that the message names.
"""

import os
import signal
import subprocess
import sys

import pytest
from pxr import Usd, UsdGeom

from warp_tube.sim.simulation import PAUSE_ENV

from .bad_inputs import KEEP, scene
from .conftest import ROOT, check_output_problems, needs_shared

TIMEOUT = 300  # s: a whole compile on a loaded CPU fits well within this


def _default_sighup():
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


def interrupt_when(folder, marker: str, *, env=None, args=(), stream="stderr", sig=signal.SIGINT):
    """Start `warp-tube run scene.usda -o keep.usdc`, send ``sig`` once ``marker`` appears on
    ``stream``; returns (exit status, stdout, stderr)."""
    cmd = [sys.executable, "-m", "warp_tube", *args, "run", "scene.usda", "-o", "keep.usdc"]
    full_env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])), **(env or {}))
    # (the child starts with SIGHUP's default, as from a terminal, also where the tests themselves
    # run under nohup, which ignores it: a command that inherits an ignored SIGHUP keeps ignoring it)
    p = subprocess.Popen(cmd, cwd=folder, env=full_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=_default_sighup if hasattr(signal, "SIGHUP") else None)  # fmt: skip
    watched = p.stderr if stream == "stderr" else p.stdout
    seen = []
    try:
        for line in watched:
            seen.append(line)
            if marker in line:
                p.send_signal(sig)
                break
        out, err = p.communicate(timeout=TIMEOUT)
    finally:
        if p.poll() is None:
            p.kill()
    seen = "".join(seen)
    return p.returncode, (seen + out if stream == "stdout" else out), (seen + err if stream == "stderr" else err)


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "scene.usda").write_text(scene(("endTimeCode = 2", "endTimeCode = 12")))
    (tmp_path / "keep.usdc").write_bytes(KEEP)
    return tmp_path


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name not in ("scene.usda", "keep.usdc", "keep.partial.usdc"))


def test_interrupt_during_compile_keeps_the_output_and_writes_nothing(folder):
    rc, _, err = interrupt_when(folder, "paused at compile", env={PAUSE_ENV: "compile"})
    assert rc == 130, err
    assert "before any frame was finished" in err and "nothing kept" in err and "keep.usdc was left as it was" in err
    assert (folder / "keep.usdc").read_bytes() == KEEP
    assert not (folder / "keep.partial.usdc").exists() and leftovers(folder) == []
    assert "Traceback" not in err


@needs_shared
def test_interrupt_mid_run_keeps_the_output_and_the_finished_frames(folder):
    rc, _, err = interrupt_when(folder, "paused at frame:4", env={PAUSE_ENV: "frame:4"})
    assert rc == 130, err
    partial = folder / "keep.partial.usdc"
    assert f"frames 0-4 (5 frames) kept in {partial}" in err and "keep.usdc was left as it was" in err
    assert (folder / "keep.usdc").read_bytes() == KEEP and leftovers(folder) == []
    st = Usd.Stage.Open(str(partial))
    times = UsdGeom.BasisCurves(st.GetPrimAtPath("/World/Tube/Centerline")).GetPointsAttr().GetTimeSamples()
    assert list(times) == [0.0, 1.0, 2.0, 3.0, 4.0] and st.GetEndTimeCode() == 4.0
    assert check_output_problems(partial) == []
    assert "Traceback" not in err


@needs_shared
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_stop_a_run_as_ctrl_c_does(folder, sig):
    """A job scheduler's SIGTERM or a closed terminal's SIGHUP: exit status 128 + the signal, the
    finished frames kept, the output as it was, no temporary file left."""
    rc, _, err = interrupt_when(folder, "paused at frame:3", env={PAUSE_ENV: "frame:3"}, sig=sig)
    assert rc == 128 + sig, err
    assert f"terminated ({signal.Signals(sig).name})" in err
    partial = folder / "keep.partial.usdc"
    assert f"kept in {partial}" in err and (folder / "keep.usdc").read_bytes() == KEEP and leftovers(folder) == []
    assert check_output_problems(partial) == []
    assert "Traceback" not in err


@needs_shared
def test_a_partial_result_never_writes_over_a_file_there(folder):
    """A file already at the partial name (a user's, or an earlier run's partial result) is left
    alone: the finished frames go to the next free name, which the message names."""
    (folder / "keep.partial.usdc").write_bytes(b"mine")
    rc, _, err = interrupt_when(folder, "paused at frame:2", env={PAUSE_ENV: "frame:2"})
    assert rc == 130, err
    assert (folder / "keep.partial.usdc").read_bytes() == b"mine"
    second = folder / "keep.partial-2.usdc"
    assert f"kept in {second}" in err and check_output_problems(second) == []
    assert (folder / "keep.usdc").read_bytes() == KEEP


def test_interrupt_of_a_real_kernel_compile(folder, tmp_path_factory):
    # -v makes Warp print "Module ... (compiled)" after each module it compiles; with an empty cache
    # the next module is compiling when the first line appears.
    cache = tmp_path_factory.mktemp("empty_kernel_cache")
    # unbuffered: Warp prints that line to a pipe, which Python would otherwise hold back, so the
    # signal could come after the last compile (or the end of the run) instead of during the next
    env = {"WARP_CACHE_PATH": str(cache), "PYTHONUNBUFFERED": "1"}
    rc, out, err = interrupt_when(folder, "(compiled)", env=env, args=("-v",), stream="stdout")
    assert "(compiled)" in out, "no kernel was compiled: the cache was not empty"
    assert rc == 130, err
    assert (folder / "keep.usdc").read_bytes() == KEEP and leftovers(folder) == []
    partial = folder / "keep.partial.usdc"
    if partial.exists():  # frames finished before the signal landed are kept, in a valid stage
        assert f"kept in {partial}" in err
        assert Usd.Stage.Open(str(partial)) is not None
    else:
        assert "nothing" in err
    assert "Traceback" not in err


def _samples(path):
    st = Usd.Stage.Open(str(path))
    curve = UsdGeom.BasisCurves(st.GetPrimAtPath("/World/Tube/Centerline")).GetPointsAttr().GetTimeSamples()
    mesh = UsdGeom.Mesh(st.GetPrimAtPath("/World/Tube/Surface")).GetPointsAttr().GetTimeSamples()
    return list(curve), list(mesh), st.GetEndTimeCode()


@pytest.mark.parametrize("point", ["after the step", "while counting the frame"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupt_right_after_a_frame_is_simulated_keeps_that_frame(folder, monkeypatch, capsys, point, sig):
    """The signal lands where the run has just finished frame 5 and not yet handed it to the writer
    (raised there, not timed): the summary and the partial file agree, and both hold frame 5."""
    from warp_tube.cli import main
    from warp_tube.runtime.interrupts import Terminated
    from warp_tube.sim.simulation import Simulation

    name = "step" if point == "after the step" else "max_displacement"
    original = getattr(Simulation, name)
    fired = []

    def interrupted(self, *args):
        out = original(self, *args)
        if self.frame == 5 and not fired:
            fired.append(True)
            raise KeyboardInterrupt if sig == signal.SIGINT else Terminated(sig)
        return out

    monkeypatch.setattr(Simulation, name, interrupted)
    monkeypatch.chdir(folder)
    assert main(["run", "scene.usda", "-o", "keep.usdc", "--device", "cpu"]) == 128 + sig
    err = capsys.readouterr().err
    partial = folder / "keep.partial.usdc"
    assert "frames       6 written (5 simulated)" in err and "while simulating frame 6" in err, err
    assert f"frames 0-5 (6 frames) kept in {partial}" in err
    assert _samples(partial) == ([0.0, 1.0, 2.0, 3.0, 4.0, 5.0], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0], 5.0)
    assert (folder / "keep.usdc").read_bytes() == KEEP and leftovers(folder) == []
