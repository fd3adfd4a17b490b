"""Export all or nothing: a read-only folder, a full disk, a failing rename or an interrupt gives a
one-line message (exit status 2, or the interrupt's), leaves no file or folder of the export, and
leaves the files that were there before as they were."""

import builtins
import errno
import io
import os

import pytest
from pxr import Usd, UsdGeom, Vt

from warp_tube.cli import main

from .bad_inputs import KEEP

FRAMES = (0, 1, 2)


@pytest.fixture()
def stage(tmp_cwd):
    """``out.usda`` in the current folder: one tetrahedron ``Surface`` moving along x, 3 frames."""
    st = Usd.Stage.CreateNew("out.usda")
    st.SetStartTimeCode(FRAMES[0])
    st.SetEndTimeCode(FRAMES[-1])
    UsdGeom.Xform.Define(st, "/World")
    UsdGeom.Xform.Define(st, "/World/Tube")
    mesh = UsdGeom.Mesh.Define(st, "/World/Tube/Surface")
    mesh.CreateFaceVertexCountsAttr().Set(Vt.IntArray([3, 3, 3, 3]))
    mesh.CreateFaceVertexIndicesAttr().Set(Vt.IntArray([0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2]))
    for f in FRAMES:
        pts = [(f, 0, 0), (f + 1, 0, 0), (f, 1, 0), (f, 0, 1)]
        mesh.GetPointsAttr().Set(Vt.Vec3fArray(pts), f)
    st.GetRootLayer().Save()
    return tmp_cwd


def tree(folder):
    """Every file and folder under ``folder``, relative, sorted (hidden ones included)."""
    found = []
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            found.append(os.path.relpath(os.path.join(root, name), folder))
    return sorted(found)


def one_line(err):
    """The one line a failed command printed; fails the test if it printed more or an internal error."""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "internal error" not in lines[0]
    return lines[0]


class FullDisk(io.FileIO):
    """A file on a disk that fills up after a few bytes of it."""

    def write(self, b):
        super().write(bytes(b)[:16])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def fill_disk_at(monkeypatch, marker):
    """Writing a file whose name holds ``marker`` fails as on a full disk, part of it written."""
    real_open = builtins.open

    def open_(file, mode="r", *args, **kwargs):
        if isinstance(file, (str, os.PathLike)) and marker in os.path.basename(file) and set(mode) & set("wxa"):
            return FullDisk(file, mode.replace("b", ""))
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", open_)


def read_only(monkeypatch):
    """Creating a folder or a file fails as on a read-only file system."""
    real_open = builtins.open

    def refuse(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    def open_(file, mode="r", *args, **kwargs):
        if set(mode) & set("wxa"):
            refuse()
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr("pathlib.Path.mkdir", refuse)
    monkeypatch.setattr(os, "mkdir", refuse)
    monkeypatch.setattr(builtins, "open", open_)


@pytest.mark.parametrize("fmt", ["obj", "glb"])
def test_export_into_a_read_only_folder_says_so_in_one_line(stage, fmt, monkeypatch, capsys):
    (stage / "ro").mkdir()
    before = tree(stage)
    read_only(monkeypatch)
    assert main(["export", "out.usda", "--format", fmt, "-o", "ro/sub"]) == 2
    line = one_line(capsys.readouterr().err)
    assert "ro/sub: cannot create the folder" in line and "Read-only file system" in line
    assert tree(stage) == before


def test_export_of_one_glb_file_to_a_read_only_folder_keeps_the_old_file(stage, monkeypatch, capsys):
    (stage / "x.glb").write_bytes(KEEP)
    read_only(monkeypatch)
    assert main(["export", "out.usda", "--format", "glb", "--frame", "1", "-o", "x.glb", "--force"]) == 2
    line = one_line(capsys.readouterr().err)
    assert "x.glb: cannot write" in line and "Read-only file system" in line
    assert tree(stage) == ["out.usda", "x.glb"] and (stage / "x.glb").read_bytes() == KEEP


@pytest.mark.parametrize("fmt", ["obj", "glb"])
def test_export_on_a_full_disk_leaves_no_file_and_no_folder(stage, fmt, monkeypatch, capsys):
    fill_disk_at(monkeypatch, ".0002.")
    assert main(["export", "out.usda", "--format", fmt, "-o", "frames"]) == 2
    line = one_line(capsys.readouterr().err)
    assert f"frames/out.0002.{fmt}: cannot write" in line and "No space left on device" in line
    assert tree(stage) == ["out.usda"]


def test_forced_export_on_a_full_disk_keeps_the_files_that_were_there(stage, monkeypatch, capsys):
    (stage / "frames").mkdir()
    (stage / "frames" / "out.0000.obj").write_bytes(KEEP)
    (stage / "frames" / "mine.txt").write_bytes(KEEP)
    fill_disk_at(monkeypatch, ".0002.")
    assert main(["export", "out.usda", "-o", "frames", "--force"]) == 2
    assert "No space left on device" in one_line(capsys.readouterr().err)
    assert tree(stage / "frames") == ["mine.txt", "out.0000.obj"]
    assert (stage / "frames" / "out.0000.obj").read_bytes() == KEEP


@pytest.mark.parametrize("existing", [False, True])
def test_one_glb_file_on_a_full_disk_is_not_left_half_written(stage, existing, monkeypatch, capsys):
    if existing:
        (stage / "x.glb").write_bytes(KEEP)
    fill_disk_at(monkeypatch, "x.")
    assert main(["export", "out.usda", "--format", "glb", "--frame", "2", "-o", "x.glb", "--force"]) == 2
    assert "x.glb: cannot write (No space left on device)" in one_line(capsys.readouterr().err)
    assert tree(stage) == (["out.usda", "x.glb"] if existing else ["out.usda"])
    if existing:
        assert (stage / "x.glb").read_bytes() == KEEP


def test_a_failing_rename_puts_back_the_files_already_replaced(stage, monkeypatch, capsys):
    (stage / "frames").mkdir()
    for f in ("0000", "0001"):
        (stage / "frames" / f"out.{f}.obj").write_bytes(KEEP)
    real_replace = os.replace

    def replace(src, dst, *args, **kwargs):
        if ".tmp-" in os.fspath(src) and ".0002." in os.fspath(dst):
            raise OSError(errno.EIO, os.strerror(errno.EIO))
        return real_replace(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", replace)
    assert main(["export", "out.usda", "-o", "frames", "--force"]) == 2
    assert "frames/out.0002.obj: cannot write (Input/output error)" in one_line(capsys.readouterr().err)
    assert tree(stage / "frames") == ["out.0000.obj", "out.0001.obj"]
    assert all((stage / "frames" / f"out.{f}.obj").read_bytes() == KEEP for f in ("0000", "0001"))


def test_an_interrupted_export_leaves_nothing(stage, monkeypatch, capsys):
    import warp_tube.io.export as export_module

    real_surface_at = export_module.surface_at

    def surface_at(mesh, time, *args):
        if time == 1:
            raise KeyboardInterrupt
        return real_surface_at(mesh, time, *args)

    monkeypatch.setattr(export_module, "surface_at", surface_at)
    assert main(["export", "out.usda", "-o", "frames"]) == 130
    assert "nothing was written" in one_line(capsys.readouterr().err)
    assert tree(stage) == ["out.usda"]


def test_a_forced_export_replaces_every_file_and_leaves_no_hidden_one(stage, capsys):
    (stage / "frames").mkdir()
    (stage / "frames" / "out.0001.obj").write_bytes(KEEP)
    assert main(["export", "out.usda", "-o", "frames", "--force"]) == 0
    assert tree(stage / "frames") == [f"out.{f:04d}.obj" for f in FRAMES]
    assert (stage / "frames" / "out.0001.obj").read_bytes() != KEEP
    assert capsys.readouterr().out.split() == [f"frames/out.{f:04d}.obj" for f in FRAMES]


def test_one_frame_to_a_file_of_another_format_is_refused_not_made_a_folder(stage, capsys):
    """``-o f.gltf --frame T`` asks for a file: export writes .obj or .glb only, so it says so
    (exit 2, nothing made) rather than make a folder ``f.gltf/`` holding an OBJ."""
    before = tree(stage)
    assert main(["export", "out.usda", "-o", "f.gltf", "--frame", str(FRAMES[1])]) == 2
    assert "f.gltf: extension .gltf: export writes .obj or .glb" in one_line(capsys.readouterr().err)
    assert tree(stage) == before
