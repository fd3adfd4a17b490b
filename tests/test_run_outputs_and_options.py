"""Single runs on small scenes written here: a frame count too large to
write, export's message for a frame between the samples of an ``--every`` output, mistyped
options, and the preview of a tube thinner than a pixel (CPU)."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest
from PIL import Image

from warp_tube.cli import main

from .conftest import CHECK_OUTPUT, check_output_problems, needs_shared


def _scene(path, points, width, extra="", curve_counts=None, mpu=0.01):
    """A one-prim tube scene: ``points`` (P, 3) [stage units], diameter ``width`` [stage units]."""
    pts = ", ".join(f"({x:g}, {y:g}, {z:g})" for x, y, z in points)
    counts = curve_counts or [len(points)]
    path.write_text(textwrap.dedent(f"""\
        #usda 1.0
        (
            defaultPrim = "World"
            metersPerUnit = {mpu}
            upAxis = "Y"
            timeCodesPerSecond = 24
            startTimeCode = 0
            endTimeCode = 10
        )
        def Xform "World"
        {{
            def BasisCurves "Tube"
            {{
                uniform token type = "linear"
                int[] curveVertexCounts = {counts}
                point3f[] points = [{pts}]
                float[] widths = [{width:g}]
                double warptube:youngsModulus = 100000
                double warptube:density = 1050
                int[] warptube:pinnedPoints = [0]
                EXTRA
            }}
        }}
        """).replace("EXTRA", extra))
    return path


def _straight(n, step):
    return np.c_[np.arange(n) * step, np.zeros(n), np.zeros(n)]


def test_a_frame_count_too_large_to_write_is_refused_at_once(tmp_path):
    """--frames far beyond memory: refused before the run (exit 2, nothing written), in a
    process whose memory is capped, where listing every frame to write would run out."""
    scene = _scene(tmp_path / "s.usda", _straight(3, 1.0), 1.0)
    out = tmp_path / "out.usdc"
    code = textwrap.dedent(f"""\
        import resource, sys
        from warp_tube.cli import main
        resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30))
        sys.exit(main(["run", {str(scene)!r}, "-o", {str(out)!r}, "--frames", "1000000000000", "--quiet", "--device", "cpu"]))
        """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "1,000,000,000,000 frames" in done.stderr and "--every K or --frames N" in done.stderr
    assert " TB (" in done.stderr and "e+" not in done.stderr  # a size in words, not 44400000000000.0 GB
    assert not list(tmp_path.glob("*out*"))


def test_every_output_counts_the_frames_it_writes(tmp_path):
    """Frames 0..7 every 3 write 0, 3 and 6; continuing from frame 4 writes 6 only (with a warning)."""
    import warp_tube

    scene = _scene(tmp_path / "s.usda", _straight(3, 1.0), 1.0)
    sim = warp_tube.Simulation(warp_tube.load_scene(str(scene)), device="cpu")
    s = sim.run(frames=8, output=str(tmp_path / "a.usdc"), every=3)
    assert (s.frames, s.first_frame, s.last_frame) == (3, 0, 6)
    # frame 7 is simulated, not written: said (a shot framed to the scene's end would lose it)
    assert any("every 3: frame 7 is simulated but not written (the last written is frame 6)" in w for w in s.warnings)
    sim = warp_tube.Simulation(warp_tube.load_scene(str(scene)), device="cpu")
    for _ in range(4):
        sim.step()
    s = sim.run(frames=8, output=str(tmp_path / "b.usdc"), every=3)
    assert (s.frames, s.first_frame, s.last_frame) == (1, 6, 6)
    assert any("only frame 6 is written" in w for w in s.warnings)
    with pytest.raises(warp_tube.SceneError, match=r"every 5: frame 7 is not a multiple of it: nothing to write"):
        sim.run(frames=8, output=str(tmp_path / "c.usdc"), every=5)


@pytest.mark.parametrize("stop, said", [(10, None), (35, "frames 31 to 35 are simulated but not written (the last written is frame 30)")])
def test_every_speaks_only_of_frames_simulated_when_a_run_stops(tmp_path, monkeypatch, stop, said):
    """Frames 0..39 every 15 write 0, 15 and 30: a run stopped at frame 10 never simulated 31 to 39,
    and its summary does not say it did; one stopped at frame 35 simulated 31 to 35, not written."""
    import warp_tube
    from warp_tube.sim.simulation import Simulation

    step = Simulation.step

    def interrupted(self):
        step(self)
        if self.frame == stop:
            raise KeyboardInterrupt

    monkeypatch.setattr(Simulation, "step", interrupted)
    scene = _scene(tmp_path / "s.usda", _straight(3, 1.0), 1.0)
    sim = warp_tube.Simulation(warp_tube.load_scene(str(scene)), device="cpu")
    with pytest.raises(KeyboardInterrupt):
        sim.run(frames=40, output=str(tmp_path / "a.usdc"), every=15)
    s = sim.last_summary
    unwritten = [w for w in s.warnings if "simulated but not written" in w]
    assert unwritten == ([] if said is None else [f"every 15: {said}"]), s.warnings


def test_export_of_a_frame_between_samples_names_the_step(tmp_path, capsys):
    scene = _scene(tmp_path / "s.usda", _straight(3, 1.0), 1.0)
    out = tmp_path / "out.usdc"
    assert main(["run", str(scene), "-o", str(out), "--frames", "7", "--every", "2", "--quiet", "--device", "cpu"]) == 0
    capsys.readouterr()
    assert main(["export", str(out), "--frame", "3", "-o", str(tmp_path / "f.obj")]) == 2
    err = capsys.readouterr().err
    assert "no Surface sample at frame 3 (frames 0..6 every 2)" in err
    assert not (tmp_path / "f.obj").exists()
    assert main(["export", str(out), "--frame", "4", "-o", str(tmp_path / "f.obj")]) == 0


@pytest.mark.parametrize("argv, command", [
    (["run", "SCENE", "-o", "OUT", "--frame", "3"], "run"),  # --frames, or export's --frame?
    (["preview", "OUT", "-o", "x.png", "--frame", "3"], "preview"),  # tiles, not a time code
    (["export", "OUT", "--frames", "3"], "export"),
])
def test_an_option_of_another_command_is_refused_under_this_commands_usage(tmp_path, capsys, argv, command):
    scene = _scene(tmp_path / "s.usda", _straight(3, 1.0), 1.0)
    out = tmp_path / "out.usdc"
    if command != "run":
        assert main(["run", str(scene), "-o", str(out), "--frames", "2", "--quiet", "--device", "cpu"]) == 0
        capsys.readouterr()
    argv = [str(scene) if a == "SCENE" else str(out) if a == "OUT" else str(tmp_path / a) if a == "x.png" else a for a in argv]
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert f"usage: warp-tube {command} " in err and "unrecognized arguments: --frame" in err
    assert not (tmp_path / "x.png").exists()
    if command == "run":
        assert not out.exists()


def test_preview_shows_a_tube_thinner_than_a_pixel(tmp_path):
    """A 2 m tube 0.5 mm across spans a tile; its surface is far below a pixel, so its centerline
    is drawn: a continuous line across the tile, not a few scattered hits."""
    scene = _scene(tmp_path / "thin.usda", _straight(200, 1.0), 0.05, "int warptube:spokes = 4")
    out = tmp_path / "thin.usdc"
    assert main(["run", str(scene), "-o", str(out), "--frames", "2", "--quiet", "--device", "cpu"]) == 0
    png = tmp_path / "thin.png"
    assert main(["preview", str(out), "-o", str(png), "--frames", "1"]) == 0
    tile = np.asarray(Image.open(png).convert("RGB")).astype(int)[:300]  # above the label
    drawn = np.abs(tile - tile[0, 0]).sum(-1) > 30
    columns = np.flatnonzero(drawn.any(axis=0))
    assert columns.size > 0.7 * (columns.max() - columns.min() + 1) and columns.max() - columns.min() > 200


def test_a_thick_tube_preview_is_its_surface_only(tmp_path):
    """The centerline never shows through or beside a tube wider than a pixel."""
    scene = _scene(tmp_path / "fat.usda", _straight(5, 1.0), 1.0, "bool warptube:caps = true")
    out = tmp_path / "fat.usdc"
    assert main(["run", str(scene), "-o", str(out), "--frames", "2", "--quiet", "--device", "cpu"]) == 0
    png = tmp_path / "fat.png"
    assert main(["preview", str(out), "-o", str(png), "--frames", "1"]) == 0
    tile = np.asarray(Image.open(png).convert("RGB")).astype(float)
    from warp_tube.io.preview import THIN_SHADE, TISSUE

    line = np.clip(np.round(TISSUE * THIN_SHADE), 0, 255)
    assert not (np.abs(tile - line).sum(-1) < 1).any()


@needs_shared
@pytest.mark.skipif(not CHECK_OUTPUT.is_file(), reason="no output checker")
def test_two_curves_in_one_prim_pass_the_checker_and_export_outward(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    points = np.r_[_straight(6, 1.0), _straight(5, 1.0) + [0, 5, 0]]
    scene = _scene(tmp_path / "two.usda", points, 1.0, "bool warptube:caps = true\n        int warptube:spokes = 3",
                   curve_counts=[6, 5])
    out = tmp_path / "two.usdc"
    assert main(["run", str(scene), "-o", str(out), "--frames", "3", "--quiet", "--device", "cpu"]) == 0
    assert check_output_problems(out, scene, require_surface=True) == []
    assert main(["export", str(out), "--frame", "2", "-o", str(tmp_path / "two.obj")]) == 0
    mesh = trimesh.load(str(tmp_path / "two.obj"), process=False, maintain_order=True)
    caps = 2 * 2 * (1 * 3 + 1)  # two tubes, two caps each, K - 1 = 1 ring of 3 and a pole
    assert len(mesh.vertices) == 11 * 3 + caps
    assert mesh.is_winding_consistent and mesh.volume > 0
    assert sum(b.volume > 0 for b in mesh.split(only_watertight=True)) == 2


def test_a_folder_given_as_the_output_is_named_as_a_folder(tmp_path, capsys):
    # (it was reported as an output without an extension)
    folder = tmp_path / "results"
    folder.mkdir()
    assert main(["run", "-o", str(folder), "--quiet", "--device", "cpu"]) == 2
    err = capsys.readouterr().err
    assert f"{folder}: is a folder" in err and str(folder / "out.usdc") in err and "extension" not in err
    assert list(folder.iterdir()) == []


def test_tubes_under_several_root_prims_are_said_to_leave_the_default_prim_short(tmp_path):
    """The output's defaultPrim is the first tube's root: a reference without a prim path brings in
    only the tubes under it, which the run now says where the tubes have several roots."""
    import warp_tube
    from warp_tube.scene.spec import Scene

    scene = warp_tube.load_scene(str(_scene(tmp_path / "s.usda", _straight(3, 1.0), 1.0)))
    t = scene.tubes[0]
    two = Scene((t, type(t)(path="/Other/Tube", points=t.points + [0.0, 0.1, 0.0], curve_counts=t.curve_counts, radius=t.radius,
                           params=t.params, pinned=t.pinned)), stage=scene.stage)  # fmt: skip
    s = warp_tube.Simulation(two, device="cpu").run(frames=2, output=str(tmp_path / "two.usdc"))
    root = "/" + t.path.strip("/").split("/")[0]
    assert any(f"lie under 2 root prims ({root}, /Other): the output's defaultPrim is {root}" in w for w in s.warnings), s.warnings
    one = warp_tube.Simulation(scene, device="cpu").run(frames=2, output=str(tmp_path / "one.usdc"))
    assert not any("root prims" in w for w in one.warnings)

