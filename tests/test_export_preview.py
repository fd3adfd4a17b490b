"""OBJ/GLB export and PNG preview of an output-like stage (built here with pxr)."""

import numpy as np
import pytest
import trimesh
import warp as wp
from PIL import Image
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from warp_tube.io.export import export
from warp_tube.io.preview import preview
from warp_tube.scene.spec import SceneError
from warp_tube.surface.builder import SurfaceBuilder

from .conftest import SCENES

N, S, RADIUS = 8, 10, 1.0  # stage units (cm)
FRAMES = (0, 1, 2)


def tube_points(frame):
    """A straight tube along +x, 20 units long, moved by 5 units along +y per frame."""
    x = np.zeros((N, 3))
    x[:, 0] = np.linspace(0.0, 20.0, N)
    x[:, 1] = 5.0 * frame
    b = SurfaceBuilder([0, N], x, S, np.full(N, RADIUS), caps=True, device="cpu")
    b.compute(wp.array(x[None].astype(np.float32), dtype=wp.vec3, device="cpu"))
    return b


@pytest.fixture()
def stage_path(tmp_path):
    path = tmp_path / "out.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    stage.SetStartTimeCode(FRAMES[0])
    stage.SetEndTimeCode(FRAMES[-1])
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    UsdGeom.Xform.Define(stage, "/World/Tube")
    mesh = UsdGeom.Mesh.Define(stage, "/World/Tube/Surface")
    b = tube_points(0)
    mesh.CreateSubdivisionSchemeAttr().Set(UsdGeom.Tokens.none)
    mesh.CreateFaceVertexCountsAttr().Set(Vt.IntArray(b.face_vertex_counts.tolist()))
    mesh.CreateFaceVertexIndicesAttr().Set(Vt.IntArray(b.face_vertex_indices.tolist()))
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    st.Set(Vt.Vec2fArray.FromNumpy(b.st))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    for f in FRAMES:
        b = tube_points(f)
        mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(b.points_numpy()), f)
        mesh.GetNormalsAttr().Set(Vt.Vec3fArray.FromNumpy(b.normals_numpy()), f)
    stage.GetRootLayer().Save()
    return path


def test_export_obj_every_frame(stage_path, tmp_path):
    paths = export(stage_path, "obj", out=tmp_path / "obj")
    assert [p.name for p in paths] == [f"out.{f:04d}.obj" for f in FRAMES]
    for f, p in zip(FRAMES, paths):
        m = trimesh.load(p, process=False)
        expected = tube_points(f).points_numpy()
        # OBJ keeps stage units and axes; text round-trip at 1e-6 relative
        np.testing.assert_allclose(m.vertices, expected, atol=1e-5)
        assert len(m.faces) == len(tube_points(f).topology.faces)
        assert m.is_watertight  # capped tube


def test_export_glb_one_frame_in_metres_y_up(stage_path, tmp_path):
    [p] = export(stage_path, "glb", out=tmp_path / "f1.glb", frame=1)
    assert p == tmp_path / "f1.glb"
    scene = trimesh.load(p, process=False)
    verts = np.concatenate([g.vertices for g in scene.dump()])
    stage_units = tube_points(1).points_numpy().astype(np.float64)
    # glTF: metres (x 0.01) and Y-up: stage (x, y, z) Z-up -> (x, z, -y); float32 storage
    expected = 0.01 * np.stack([stage_units[:, 0], stage_units[:, 2], -stage_units[:, 1]], 1)
    np.testing.assert_allclose(np.sort(verts, axis=0), np.sort(expected, axis=0), atol=1e-6)


def test_cli_export_takes_its_format_from_the_file_named(stage_path, tmp_path):
    """``-o FILE.glb`` without ``--format`` writes glTF binary; ``--format`` given wins, and one
    that disagrees with the file's suffix is refused (exit 2, no file)."""
    import subprocess
    import sys

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "warp_tube", "export", str(stage_path), *map(str, args)],
                              capture_output=True, text=True)  # fmt: skip

    r = cli("--frame", 1, "-o", tmp_path / "f.glb")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "f.glb").read_bytes()[:4] == b"glTF"  # the binary glTF magic
    r = cli("--frame", 1, "-o", tmp_path / "g.glb", "--format", "obj")
    assert r.returncode == 2 and "expected .obj" in r.stderr and not (tmp_path / "g.glb").exists()
    r = cli("-o", tmp_path / "seq")
    assert r.returncode == 0 and sorted(p.suffix for p in (tmp_path / "seq").iterdir()) == [".obj"] * len(FRAMES)


def test_export_errors(stage_path, tmp_path):
    with pytest.raises(SceneError, match="no such file"):
        export(tmp_path / "missing.usdc", "obj")
    empty = tmp_path / "empty.usda"
    stage = Usd.Stage.CreateNew(str(empty))
    UsdGeom.Xform.Define(stage, "/World/Tube")
    stage.GetRootLayer().Save()
    with pytest.raises(SceneError, match=r"empty\.usda: no Surface mesh"):
        export(empty, "obj")
    with pytest.raises(SceneError, match="no Surface sample at frame 7"):
        export(stage_path, "obj", frame=7)
    with pytest.raises(SceneError, match="unknown export format"):
        export(stage_path, "fbx")
    with pytest.raises(SceneError, match="no Surface mesh"):
        preview(empty, tmp_path / "x.png")
    # one file named in a folder that is not there: refused as run refuses it (export made the folder)
    with pytest.raises(SceneError, match=r"x\.obj: cannot write the file: folder .*nodir does not exist"):
        export(stage_path, "obj", frame=1, out=tmp_path / "nodir" / "x.obj")
    assert not (tmp_path / "nodir").exists()


def test_preview_of_more_frames_than_the_stage_has_says_so(stage_path, tmp_path, caplog):
    """--frames 200 on a stage of fewer frames made a sheet of those without a word."""
    with caplog.at_level("WARNING"):
        preview(stage_path, tmp_path / "sheet.png", frames=200, size=32, device="cpu")
    assert any("200 frames asked for: the stage has" in r.getMessage() for r in caplog.records)


def test_preview_of_a_short_stage_without_frames_asked_says_nothing(tmp_path, caplog):
    """The default of four tiles on a stage of three frames: nothing was asked for, nothing to say."""
    from warp_tube.cli import main as cli

    stage = tmp_path / "short.usdc"
    assert cli(["run", str(SCENES / "default.usda"), "-o", str(stage), "--frames", "3", "--quiet", "--device", "cpu"]) == 0
    caplog.clear()
    with caplog.at_level("WARNING"):
        preview(stage, tmp_path / "sheet.png", size=32, device="cpu")
    assert not [r for r in caplog.records if "frames asked for" in r.getMessage()]


def test_preview_contact_sheet(stage_path, tmp_path):
    size = 64
    png = preview(stage_path, tmp_path / "sheet.png", frames=3, size=size, device="cpu")
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    assert img.shape == (size, 3 * size, 3)
    background = np.all(img == [245, 245, 242], axis=2)
    tiles = [~background[:, k * size : (k + 1) * size] for k in range(3)]
    for tile in tiles:
        assert 0.02 < tile.mean() < 0.6  # the tube covers part of each tile, not all of it
        assert not tile[0, 0] and not tile[-1, -1]  # corners are background (fitted camera)
    # the tube moves by 5 units per frame: the tiles differ, and the covered area's centre moves
    assert np.any(tiles[0] != tiles[2])
    cols = [np.nonzero(t)[1].mean() for t in tiles]
    rows = [np.nonzero(t)[0].mean() for t in tiles]
    moved = np.hypot(np.diff(cols), np.diff(rows))
    assert np.all(moved > 2.0)  # pixels; the fitted scale is ~64 px per 27 units, so ~10 px per frame


def test_preview_tiles_carry_their_frame(stage_path, tmp_path):
    """Tiles of 96 pixels or more name their time code at the bottom left (dark text on the
    background); the rest of the tile is as without it."""
    size = 128
    img = np.asarray(Image.open(preview(stage_path, tmp_path / "sheet.png", frames=2, size=size, device="cpu")).convert("RGB")).astype(int)
    for k in range(2):
        corner = img[size - 18 :, k * size : k * size + 60]
        dark = np.all(np.abs(corner - [70, 70, 70]) < 40, axis=2)
        assert dark.sum() > 10  # the label's strokes


def test_preview_of_many_frames_wraps_into_rows(stage_path, tmp_path):
    """More frames than a row holds wrap into rows of SHEET_COLUMNS tiles (a strip 49 tiles long
    is no contact sheet); the tiles left over in the last row are background."""
    from warp_tube.io import preview as module

    size = 32
    stage = module.open_output_stage(stage_path)
    n = len(module.surface_frames(module.surface_meshes(stage, stage_path)))
    del stage
    columns = 2
    assert n >= 3  # (rows to wrap, the last one part empty where n is odd)
    old = module.SHEET_COLUMNS
    module.SHEET_COLUMNS = columns
    try:
        img = np.asarray(Image.open(preview(stage_path, tmp_path / "sheet.png", frames=n, size=size, device="cpu")).convert("RGB"))
    finally:
        module.SHEET_COLUMNS = old
    rows = -(-n // columns)
    assert img.shape == (rows * size, columns * size, 3)
    if n % columns:
        empty = img[(rows - 1) * size :, (n % columns) * size :]
        assert (empty == module.BACKGROUND.astype(np.uint8)).all()


def test_export_winds_faces_outwards_under_a_mirror_and_a_left_handed_mesh(stage_path, tmp_path):
    """A USD renderer turns a mesh's front faces where its transform mirrors (a negative
    determinant) or it is authored leftHanded; OBJ and glTF know only counter-clockwise fronts, so
    export reverses the triangles there. The capped tube's signed volume (exact for a closed mesh:
    the divergence theorem) is then positive, its faces wound as its normals point."""
    mirror = tmp_path / "mirror.usda"
    stage = Usd.Stage.CreateNew(str(mirror))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    shot = UsdGeom.Xform.Define(stage, "/Shot")
    stage.SetDefaultPrim(shot.GetPrim())
    m = UsdGeom.Xform.Define(stage, "/Shot/M")
    m.GetPrim().GetReferences().AddReference(str(stage_path))
    m.AddScaleOp().Set(Gf.Vec3d(-1.0, 2.0, 1.0))
    stage.GetRootLayer().Save()

    left = Usd.Stage.Open(str(stage_path))  # the same tube, its faces listed the other way round
    surface = UsdGeom.Mesh(left.GetPrimAtPath("/World/Tube/Surface"))
    idx = np.asarray(surface.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)[:, ::-1]
    surface.GetFaceVertexIndicesAttr().Set(Vt.IntArray(idx.ravel().tolist()))
    surface.GetOrientationAttr().Set(UsdGeom.Tokens.leftHanded)
    left.GetRootLayer().Export(str(tmp_path / "left.usda"))

    for path, scale in ((mirror, 2.0), (tmp_path / "left.usda", 1.0)):
        [p] = export(path, "obj", out=tmp_path / f"{path.stem}.obj", frame=1)
        mesh = trimesh.load(p, process=False)
        tris = mesh.vertices[mesh.faces]
        volume = np.einsum("ij,ij->i", tris[:, 0], np.cross(tris[:, 1], tris[:, 2])).sum() / 6.0
        assert mesh.is_watertight
        # pi r^2 L within 5%: the 10-gon's section is 6% smaller than the circle, the caps add back
        assert volume == pytest.approx(scale * np.pi * RADIUS**2 * 20.0, rel=0.05), path
        face_normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        assert (np.einsum("ij,ij->i", face_normals, mesh.vertex_normals[mesh.faces].mean(axis=1)) > 0).all()
