"""No command loses a user's file: inputs survive byte for byte, an existing output survives a
numerical failure and an exception, the finished frames of a stopped run are kept beside it in a
valid stage named in the message, and files honour the umask. (Interrupts: test_interrupts.py.)"""

import os
import stat

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

import warp_tube
from warp_tube.cli import main
from warp_tube.scene.files import default_run_output, output_path, partial_path, same_file, temp_path, write_atomically
from warp_tube.scene.spec import SceneError
from warp_tube import Simulation

from .bad_inputs import FORCED_BLOWUP, KEEP, scene, tube_mesh
from .conftest import SCENES, check_output_problems, needs_shared


def samples(path, prim="/World/Tube"):
    st = Usd.Stage.Open(str(path))
    return list(UsdGeom.BasisCurves(st.GetPrimAtPath(prim + "/Centerline")).GetPointsAttr().GetTimeSamples()), st


def no_hidden_temporaries(folder):
    return [p.name for p in folder.iterdir() if ".tmp-" in p.name]


# -- inputs survive ------------------------------------------------------------------------------


def test_run_of_a_usdc_scene_in_its_folder_without_o_keeps_the_scene(tmp_cwd):
    Sdf.Layer.FindOrOpen(str(SCENES / "default.usda")).Export(str(tmp_cwd / "scene.usdc"))
    before = (tmp_cwd / "scene.usdc").read_bytes()
    assert main(["run", "scene.usdc", "--frames", "2", "--quiet"]) == 0
    assert (tmp_cwd / "scene.usdc").read_bytes() == before
    assert samples(tmp_cwd / "scene.out.usdc")[0] == [0.0, 1.0]


def test_default_output_name_never_is_the_scene():
    for name in ("scene.usdc", "scene.usda", "a/b/scene.usd", "x.out.usdc", "noext"):
        out = default_run_output(name)
        assert os.path.basename(out) != os.path.basename(name) and out.endswith(".usdc")
    assert default_run_output(None) == "tube.usdc"


@pytest.mark.parametrize("how", ["same name", "relative detour", "symbolic link", "hard link", "partial name"])
def test_run_refuses_an_output_that_is_its_input(how, tmp_cwd, capsys):
    (tmp_cwd / "sub").mkdir()
    src = tmp_cwd / ("x.partial.usda" if how == "partial name" else "scene.usda")
    src.write_text(scene())
    out = {"same name": "scene.usda", "relative detour": "sub/../scene.usda", "symbolic link": "link.usda",
           "hard link": "hard.usda", "partial name": "x.usda"}[how]  # fmt: skip
    if how == "symbolic link":
        os.symlink("scene.usda", tmp_cwd / "link.usda")
    if how == "hard link":
        os.link(src, tmp_cwd / "hard.usda")
    before = src.read_bytes()
    assert main(["run", src.name, "-o", out, "--frames", "2"]) == 2
    assert "refusing to write over an input" in capsys.readouterr().err
    assert src.read_bytes() == before


def test_run_refuses_to_write_over_a_layer_the_scene_references(tmp_cwd, capsys):
    (tmp_cwd / "tube.usda").write_text(scene())
    (tmp_cwd / "shot.usda").write_text('#usda 1.0\n(\n    subLayers = [@tube.usda@]\n)\n')
    before = (tmp_cwd / "tube.usda").read_bytes()
    assert main(["run", "shot.usda", "-o", "tube.usda"]) == 2
    assert "is the input" in capsys.readouterr().err and (tmp_cwd / "tube.usda").read_bytes() == before


def test_run_onto_a_link_replaces_the_link_and_keeps_the_file_it_named(tmp_cwd):
    """A pipeline's ``latest.usdc -> v001.usdc``: the result replaces the link (made atomically
    under a temporary name), and v001.usdc is left byte for byte as it was (README)."""
    assert main(["run", "--frames", "2", "-o", "v001.usdc", "--quiet"]) == 0
    before = (tmp_cwd / "v001.usdc").read_bytes()
    os.symlink("v001.usdc", tmp_cwd / "latest.usdc")
    assert main(["run", "--frames", "3", "-o", "latest.usdc", "--quiet"]) == 0
    assert not (tmp_cwd / "latest.usdc").is_symlink() and (tmp_cwd / "v001.usdc").read_bytes() == before
    assert samples(tmp_cwd / "latest.usdc")[0] == [0.0, 1.0, 2.0] and samples(tmp_cwd / "v001.usdc")[0] == [0.0, 1.0]


def test_api_run_refuses_the_scene_as_output(tmp_cwd):
    (tmp_cwd / "scene.usda").write_text(scene())
    before = (tmp_cwd / "scene.usda").read_bytes()
    sim = Simulation(warp_tube.load_scene("scene.usda"), device="cpu")
    with pytest.raises(SceneError, match="refusing to write over an input"):
        sim.run(frames=2, output="./scene.usda")
    assert (tmp_cwd / "scene.usda").read_bytes() == before


def test_extract_refuses_its_mesh_and_a_link_to_it(tmp_cwd):
    tube_mesh(tmp_cwd / "mesh.ply")
    os.symlink("mesh.ply", tmp_cwd / "alias.usda")
    before = (tmp_cwd / "mesh.ply").read_bytes()
    assert main(["extract", "mesh.ply", "-o", "mesh.ply"]) == 2
    assert main(["extract", "mesh.ply", "-o", "alias.usda"]) == 2
    assert (tmp_cwd / "mesh.ply").read_bytes() == before and os.path.islink(tmp_cwd / "alias.usda")


def test_preview_and_export_refuse_their_stage(tmp_cwd):
    assert main(["run", str(SCENES / "default.usda"), "-o", "out.usdc", "--frames", "2", "--quiet"]) == 0
    before = (tmp_cwd / "out.usdc").read_bytes()
    os.symlink("out.usdc", tmp_cwd / "alias.png")
    assert main(["preview", "out.usdc", "-o", "alias.png"]) == 2
    assert main(["export", "out.usdc", "--frame", "0", "-o", "out.usdc"]) == 2
    assert (tmp_cwd / "out.usdc").read_bytes() == before


def test_output_path_checks():
    with pytest.raises(SceneError, match="expected .usdc"):
        output_path("a.txt", (".usdc",))
    assert partial_path("/x/out.usdc") == "/x/out.partial.usdc"
    assert os.path.dirname(temp_path("/x/out.usdc")) == "/x" and temp_path("/x/out.usdc").endswith(".usdc")
    assert same_file(".", os.getcwd()) and not same_file("missing-a", "missing-b")


# -- an existing output survives ---------------------------------------------------------------


@needs_shared
def test_existing_output_survives_a_numerical_failure_and_the_partial_is_valid(tmp_cwd, capsys):
    (tmp_cwd / "stiff.usda").write_text(FORCED_BLOWUP.replace("endTimeCode = 2", "endTimeCode = 96"))
    (tmp_cwd / "keep.usdc").write_bytes(KEEP)
    assert main(["run", "stiff.usda", "-o", "keep.usdc"]) == 3
    err = capsys.readouterr().err
    partial = tmp_cwd / "keep.partial.usdc"
    assert (tmp_cwd / "keep.usdc").read_bytes() == KEEP
    assert f"kept in {partial}" in err and "keep.usdc was left as it was" in err
    times, st = samples(partial)
    assert times and st.GetEndTimeCode() == times[-1]
    assert check_output_problems(partial) == []
    assert no_hidden_temporaries(tmp_cwd) == []


class Boom(RuntimeError):
    pass


def _step_then_raise(monkeypatch, after: int, exc):
    real = Simulation.step
    calls = {"n": 0}

    def step(self):
        calls["n"] += 1
        if calls["n"] > after:
            raise exc
        real(self)

    monkeypatch.setattr(Simulation, "step", step)


@needs_shared
def test_existing_output_survives_an_exception_mid_run(tmp_cwd, capsys, monkeypatch):
    (tmp_cwd / "scene.usda").write_text(scene(("endTimeCode = 2", "endTimeCode = 10")))
    (tmp_cwd / "keep.usdc").write_bytes(KEEP)
    _step_then_raise(monkeypatch, 3, Boom("disk on fire"))
    assert main(["run", "scene.usda", "-o", "keep.usdc"]) == 1
    err = capsys.readouterr().err
    assert "internal error (Boom: disk on fire)" in err and "frames 0-3 (4 frames) kept in" in err
    assert (tmp_cwd / "keep.usdc").read_bytes() == KEEP
    times, _ = samples(tmp_cwd / "keep.partial.usdc")
    assert times == [0.0, 1.0, 2.0, 3.0]
    assert check_output_problems(tmp_cwd / "keep.partial.usdc") == []


def test_api_run_keeps_partial_frames_on_interrupt_and_says_where(tmp_cwd, monkeypatch):
    (tmp_cwd / "scene.usda").write_text(scene(("endTimeCode = 2", "endTimeCode = 10")))
    (tmp_cwd / "keep.usdc").write_bytes(KEEP)
    _step_then_raise(monkeypatch, 2, KeyboardInterrupt())
    sim = Simulation(warp_tube.load_scene("scene.usda"), device="cpu")
    with pytest.raises(KeyboardInterrupt):
        sim.run(output="keep.usdc")
    s = sim.last_summary
    assert s.partial == str(tmp_cwd / "keep.partial.usdc") and s.output is None and s.stopped == "interrupted"
    assert (tmp_cwd / "keep.usdc").read_bytes() == KEEP
    assert samples(tmp_cwd / "keep.partial.usdc")[0] == [0.0, 1.0, 2.0]


def test_no_partial_file_when_no_frame_was_finished(tmp_cwd, monkeypatch):
    (tmp_cwd / "scene.usda").write_text(scene())
    (tmp_cwd / "keep.usdc").write_bytes(KEEP)
    from warp_tube.io.writer import StageWriter

    def fail(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(StageWriter, "write_frame", fail)
    sim = Simulation(warp_tube.load_scene("scene.usda"), device="cpu")
    with pytest.raises(KeyboardInterrupt):
        sim.run(output="keep.usdc")
    assert sim.last_summary.partial is None and sim.last_summary.frames_written_text() == "no frame"
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["keep.usdc", "scene.usda"]
    assert (tmp_cwd / "keep.usdc").read_bytes() == KEEP


def test_write_atomically_leaves_the_target_alone_on_failure(tmp_path):
    target = tmp_path / "t.bin"
    target.write_bytes(KEEP)

    def half(tmp):
        with open(tmp, "wb") as f:
            f.write(b"half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomically(target, half)
    assert target.read_bytes() == KEEP and sorted(p.name for p in tmp_path.iterdir()) == ["t.bin"]


# -- extract writes real files with the umask's permissions ---------------------------------------


@pytest.mark.parametrize("ext", [".usdc", ".usda", ".usd"])
def test_extract_writes_the_format_its_extension_names_with_the_umask(ext, tmp_cwd, capsys):
    tube_mesh(tmp_cwd / "mesh.ply")
    old = os.umask(0o027)
    try:
        assert main(["extract", "mesh.ply", "-o", f"s{ext}"]) == 0
    finally:
        os.umask(old)
    out = tmp_cwd / f"s{ext}"
    head = out.read_bytes()[:8]
    assert head == (b"#usda 1." if ext == ".usda" else b"PXR-USDC")
    assert stat.S_IMODE(out.stat().st_mode) == 0o640  # 0666 & ~0027
    scene_ = warp_tube.load_scene(str(out))
    assert len(scene_.tubes) == 1
    # the one-line summary, without -v
    line = capsys.readouterr().out.strip()
    assert line.startswith(f"s{ext}: ") and "hubs x 16 spokes" in line and "ends open/open" in line and "surface within" in line


def test_run_output_honours_the_umask(tmp_cwd):
    old = os.umask(0o077)
    try:
        assert main(["run", str(SCENES / "default.usda"), "-o", "o.usdc", "--frames", "2", "--quiet"]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_cwd / "o.usdc").stat().st_mode) == 0o600


# -- export and preview --------------------------------------------------------------------------


def test_export_without_o_fills_one_new_folder_and_never_overwrites_without_force(tmp_cwd, capsys):
    assert main(["run", str(SCENES / "default.usda"), "-o", "out.usdc", "--frames", "3", "--quiet"]) == 0
    assert main(["export", "out.usdc"]) == 0
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["out.usdc", "out_obj"]
    files = sorted(p.name for p in (tmp_cwd / "out_obj").iterdir())
    assert files == ["out.0000.obj", "out.0001.obj", "out.0002.obj"]
    (tmp_cwd / "out_obj" / "out.0001.obj").write_bytes(KEEP)
    assert main(["export", "out.usdc"]) == 2
    assert "out.0000.obj: exists" in capsys.readouterr().err
    assert (tmp_cwd / "out_obj" / "out.0001.obj").read_bytes() == KEEP
    assert main(["export", "out.usdc", "--force"]) == 0
    assert (tmp_cwd / "out_obj" / "out.0001.obj").read_bytes() != KEEP
    # one frame without -o: one file beside the stage
    assert main(["export", "out.usdc", "--frame", "2", "--format", "glb"]) == 0
    assert (tmp_cwd / "out.0002.glb").is_file()


def test_preview_failure_leaves_an_existing_png(tmp_cwd):
    assert main(["run", str(SCENES / "default.usda"), "-o", "n.usdc", "--frames", "2", "--quiet", "--no-surface"]) == 0
    (tmp_cwd / "p.png").write_bytes(KEEP)
    assert main(["preview", "n.usdc", "-o", "p.png"]) == 2
    assert (tmp_cwd / "p.png").read_bytes() == KEEP and no_hidden_temporaries(tmp_cwd) == []


# -- run() after step() ----------------------------------------------------------------------------


def test_run_after_step_continues_from_the_current_frame(tmp_cwd):
    (tmp_cwd / "scene.usda").write_text(scene(("endTimeCode = 2", "endTimeCode = 8")))
    sc = warp_tube.load_scene("scene.usda")
    stepped = Simulation(sc, device="cpu")
    for _ in range(3):
        stepped.step()
    at3 = stepped.centerline_points()[0]
    summary = stepped.run(frames=6, output="cont.usdc")
    assert summary.frames == 3 and summary.frames_simulated == 2
    times, st = samples(tmp_cwd / "cont.usdc")
    assert times == [3.0, 4.0, 5.0] and st.GetStartTimeCode() == 3.0 and st.GetEndTimeCode() == 5.0
    cl = UsdGeom.BasisCurves(st.GetPrimAtPath("/World/Tube/Centerline")).GetPointsAttr()
    np.testing.assert_array_equal(np.asarray(cl.Get(3.0)), at3.astype(np.float32))
    # the same frames as a fresh run from the rest state (CPU runs are deterministic)
    fresh = Simulation(sc, device="cpu")
    fresh.run(frames=6, output="fresh.usdc")
    _, st2 = samples(tmp_cwd / "fresh.usdc")
    cl2 = UsdGeom.BasisCurves(st2.GetPrimAtPath("/World/Tube/Centerline")).GetPointsAttr()
    for t in (3.0, 4.0, 5.0):
        np.testing.assert_array_equal(np.asarray(cl.Get(t)), np.asarray(cl2.Get(t)))
    # a fresh run's frame 0 is the rest state: the scene's points, through float32 metres and back to
    # centimetres (1 ulp of float32)
    src = Usd.Stage.Open(str(tmp_cwd / "scene.usda"))
    rest = UsdGeom.BasisCurves(src.GetPrimAtPath("/World/Tube")).GetPointsAttr().Get()
    np.testing.assert_allclose(np.asarray(cl2.Get(0.0)), np.asarray(rest), rtol=2e-7, atol=1e-12)
    # run(frames=6) ended at frame 5: a later run continues from there, so frames must exceed 5
    assert fresh.frame == 5
    with pytest.raises(SceneError, match="already at frame 5"):
        fresh.run(frames=5)


def test_run_does_not_write_over_a_file_an_asset_attribute_names(tmp_path, capsys):
    """A scene whose tube carries an asset-valued attribute (a file it links, as a DCC tool writes a
    texture's): run -o onto that file is refused as onto the scene's own layers, the file untouched."""
    text = (SCENES / "default.usda").read_text().replace(
        "double warptube:density = 1050", 'double warptube:density = 1050\n        asset info:linked = @linked.usda@')
    (tmp_path / "s.usda").write_text(text)
    linked = tmp_path / "linked.usda"
    linked.write_text("#usda 1.0\n")
    assert main(["run", str(tmp_path / "s.usda"), "-o", str(linked), "--frames", "2", "--quiet", "--device", "cpu"]) == 2
    assert "refusing to write over an input" in capsys.readouterr().err
    assert linked.read_text() == "#usda 1.0\n"
