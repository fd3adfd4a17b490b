"""What the user sees: no Warp noise unless asked, each warning once, the start-up (kernel
compilation) kept out of rates and estimates, long phases announced, extraction summarised, inputs
that are not tubes and forces no integrator can follow explained."""

import logging
import os
import subprocess
import sys

import numpy as np
import pytest

import warp_tube
from warp_tube.cli import main
from warp_tube.extract.command import extract_to_scene
from warp_tube.extract.tube_check import LARGE_HUBS, size_warning
from warp_tube.extract.tubelike import NOT_A_TUBE
from warp_tube.runtime.progress import Phase, format_seconds
from warp_tube import Simulation
from warp_tube.sim.simulation import LONG_RUN_SECONDS, RunSummary

from .bad_inputs import _plain_cylinder, _sphere, scene, tube_mesh
from .conftest import ROOT, SCENES

SCRIPT = (
    "import warp_tube\n"
    "sim = warp_tube.Simulation(warp_tube.load_scene(%r), device='cpu')\n"
    "sim.step()\n"
) % str(SCENES / "default.usda")


def python(args, env=None, cwd=None):
    full = {k: v for k, v in os.environ.items() if k != "WARP_TUBE_VERBOSE"}
    full.update(PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])), **(env or {}))
    return subprocess.run([sys.executable, *args], env=full, cwd=cwd, capture_output=True, text=True, timeout=300)


# -- Warp's messages ----------------------------------------------------------------------------


def test_cli_run_prints_nothing_but_what_was_asked(tmp_path):
    p = python(["-m", "warp_tube", "run", str(SCENES / "default.usda"), "-o", str(tmp_path / "o.usdc"), "--frames", "2", "--quiet"])
    assert p.returncode == 0
    assert p.stdout == "" and p.stderr == ""  # no CUDA-driver line, banner or module loads


def test_python_api_is_quiet_and_verbose_on_request():
    quiet = python(["-c", SCRIPT])
    assert quiet.returncode == 0, quiet.stderr
    assert quiet.stdout == "" and quiet.stderr == ""
    loud = python(["-c", SCRIPT], env={"WARP_TUBE_VERBOSE": "1"})
    assert loud.returncode == 0 and "Warp" in loud.stdout and "initialized" in loud.stdout


def test_cli_verbose_shows_warp(tmp_path):
    p = python(["-m", "warp_tube", "-v", "run", str(SCENES / "default.usda"), "-o", str(tmp_path / "o.usdc"), "--frames", "2", "--quiet"])
    assert p.returncode == 0 and "initialized" in p.stdout


# -- each warning once ------------------------------------------------------------------------------

# Two parallel tubes in one prim, 2.5 cm apart with 1 cm radii, clamped at one end: the second one's
# tip pushed down by 0.05 N (a cantilever's F L^3 / 3 E I = 2.1 cm), onto the first from frame 1 or 2.
TWO_TUBES = """#usda 1.0
(
    metersPerUnit = 0.01
    upAxis = "Y"
    timeCodesPerSecond = 24
    startTimeCode = 0
    endTimeCode = 12
)
def Xform "World"
{
    def BasisCurves "Pair"
    {
        uniform token type = "linear"
        int[] curveVertexCounts = [11, 11]
        point3f[] points = [%s]
        float[] widths = [2] (interpolation = "constant")
        double warptube:youngsModulus = 100000
        double warptube:density = 1050
        double warptube:damping = 2
        int[] warptube:pinnedPoints = [0, 1, 11, 12]
    }
    def Scope "Push"
    {
        rel warptube:target = </World/Pair>
        int warptube:point = 21
        float3 warptube:force = (0, -0.05, 0)
        bool warptube:assistantLine = false
    }
}
""" % ", ".join([f"({x}, 0, 0)" for x in range(11)] + [f"({x}, 2.5, 0)" for x in range(11)])


@pytest.mark.parametrize("quiet", [False, True])
def test_contact_warning_is_printed_once(quiet, tmp_cwd, capsys):
    (tmp_cwd / "pair.usda").write_text(TWO_TUBES)
    assert main(["run", "pair.usda", "-o", "o.usdc", *(["--quiet"] if quiet else [])]) == 0
    out = capsys.readouterr()
    assert (out.out + out.err).count("closer than the sum of their radii") == 1


def test_switch_to_implicit_is_reported_once_and_the_run_finishes(tmp_cwd, capsys):
    # 1e4 N, without the assistant line, on the default tube (EA = E pi r^2 = 31.4 N): semi-implicit
    # Euler fails even at 16x the substeps, implicit Euler takes over and finishes.
    (tmp_cwd / "blow.usda").write_text(scene(("24: (0, 0.02, 0)", "24: (0, 10000, 0)"), ("assistantLine = true", "assistantLine = false"),
                                             ("endTimeCode = 2", "endTimeCode = 8")))  # fmt: skip
    assert main(["run", "blow.usda", "-o", "o.usdc"]) == 0
    out = capsys.readouterr()
    text = out.out + out.err
    assert text.count("switched to implicit Euler") == 1
    assert "integrator   implicitEuler" in out.out  # the summary tells the integrator it ended with


def test_a_force_beyond_the_runaway_limit_stops_even_implicit_euler(tmp_cwd, capsys):
    # 1e6 N is 32,000 EA: it stretches the tube far beyond 1,000 tube lengths (docs/MODEL.md, "Integrators,
    # stability and failures"); the run stops with exit 3 after implicit Euler took over.
    (tmp_cwd / "blow.usda").write_text(scene(("24: (0, 0.02, 0)", "24: (0, 1e6, 0)"), ("assistantLine = true", "assistantLine = false"),
                                             ("endTimeCode = 2", "endTimeCode = 8")))  # fmt: skip
    assert main(["run", "blow.usda", "-o", "o.usdc"]) == 3
    err = capsys.readouterr().err
    assert "switched to implicit Euler" in err and "more than 1000 tube lengths from rest" in err
    assert "kept in" in err and (tmp_cwd / "o.partial.usdc").exists() and not (tmp_cwd / "o.usdc").exists()


# -- start-up out of the rates, long runs announced -----------------------------------------------


def test_rate_leaves_the_start_up_out():
    s = RunSummary(scene="s", device="cpu", frames=11, substeps=100, dt=1e-3, integrator="semiImplicitEuler",
                   reason="r", wall_time=10.0, max_displacement=0.0, frames_simulated=10, substeps_simulated=1000,
                   startup_time=9.0, startup_substeps=100)  # fmt: skip
    assert s.steps_per_second == pytest.approx(900.0)  # 900 substeps in the 1 s after the start-up
    assert "start-up 9.000 s" in s.text() and "900 substeps/s" in s.text()
    only = RunSummary(scene="s", device="cpu", frames=2, substeps=100, dt=1e-3, integrator="i", reason="r", wall_time=2.0,
                      max_displacement=0.0, frames_simulated=1, substeps_simulated=100, startup_time=2.0, startup_substeps=100)  # fmt: skip
    assert only.steps_per_second == pytest.approx(50.0) and "start-up and kernel compilation included" in only.text()


def test_progress_bar_starts_after_the_first_frame(tmp_cwd, monkeypatch):
    made = []
    real = Simulation._progress_bar

    def spy(self, total):
        made.append((self.frame, total))
        bar, beat = real(self, total)
        made.append(bar.n)
        return bar, beat

    monkeypatch.setattr(Simulation, "_progress_bar", spy)
    sim = Simulation(warp_tube.load_scene(str(SCENES / "default.usda")), device="cpu")
    sim.run(frames=5, progress=True)
    # created once, at frame 1, counting frame 1 as done: its rate and estimate leave frame 1 out
    assert made == [(1, 4), 1]


def test_a_long_run_is_announced_with_its_estimate_and_why(caplog):
    sim = Simulation(warp_tube.load_scene(str(SCENES / "default.usda")), device="cpu", surface=False)
    frames = int(np.ceil(2 * LONG_RUN_SECONDS / sim.estimated_seconds(1)))
    with caplog.at_level(logging.WARNING):
        sim._announce_long_run(frames)
    (msg,) = [r.getMessage() for r in caplog.records]
    assert msg.startswith("this run will take about") and f"{sim.substeps:,} substeps a frame" in msg
    assert sim.reason in msg and "--frames N" in msg
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        sim._announce_long_run(1)
    assert caplog.records == []


def test_a_large_output_is_announced_with_its_size(caplog):
    """Bytes per frame from the exact geometry: 12 bytes per float32 point, the centerline's 21
    points and the surface's points and normals; the warning only above the limit."""
    from warp_tube.sim.simulation import LARGE_OUTPUT_BYTES

    sim = Simulation(warp_tube.load_scene(str(SCENES / "default.usda")), device="cpu")
    vertices = sum(b.vertex_count for b in sim.surfaces)
    assert sim.output_bytes_per_frame() == 12 * (21 + 2 * vertices)
    frames = int(np.ceil(1.5 * LARGE_OUTPUT_BYTES / sim.output_bytes_per_frame()))
    with caplog.at_level(logging.WARNING):
        sim._announce_large_output(frames)
        sim._announce_large_output(10)
    (msg,) = [r.getMessage() for r in caplog.records]
    assert "the output will hold about 6.0 GB" in msg and f"{frames:,} frames" in msg and "--every K" in msg


def test_phase_status_line_appears_only_for_long_phases(capsys):
    import time

    with Phase("quick", enabled=True, after=5.0):
        pass
    with Phase("slow phase", enabled=True, after=0.05):
        time.sleep(0.6)
    err = capsys.readouterr().err
    assert "quick" not in err and "slow phase ..." in err and err.endswith("\r\033[K")
    assert format_seconds(42) == "42 s" and format_seconds(600) == "10.0 min" and format_seconds(7200) == "2.0 h"


# -- extraction ------------------------------------------------------------------------------------


def test_extraction_of_a_tube_has_no_warnings_and_a_summary(tmp_path):
    tube_mesh(tmp_path / "t.ply")
    done = extract_to_scene(tmp_path / "t.ply", tmp_path / "t.usda")
    assert done.warnings == []
    line = done.summary()
    assert "0.2 m long" in line and "ends open/open" in line and "0 side branches" in line and "surface within" in line


def test_extraction_of_a_sphere_warns_and_a_bare_cylinder_is_measured(tmp_path):
    _sphere(tmp_path / "ball.ply")
    ball = extract_to_scene(tmp_path / "ball.ply", tmp_path / "ball.usda")
    assert any(w.startswith(NOT_A_TUBE) for w in ball.warnings)
    # A cylinder with vertices at its end rings only is refined before the extraction (its long
    # edges split): its fit is measured, as a fine cylinder's is, and a few hubs match it.
    _plain_cylinder(tmp_path / "can.ply")
    can = extract_to_scene(tmp_path / "can.ply", tmp_path / "can.usda")
    assert not any("could not be measured" in w for w in can.warnings), can.warnings
    assert can.fidelity.to_surface.counted > 0 and can.tube.hubs < 50


def test_a_huge_hub_count_is_announced_with_the_size_it_writes():
    assert size_warning(LARGE_HUBS, 16) is None and size_warning(None, 16) is None
    msg = size_warning(1_000_000, 16)
    assert "16,000,000 spokes" in msg and "MB" in msg
