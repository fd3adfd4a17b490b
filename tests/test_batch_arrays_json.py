"""warp-tube batch --layout arrays: arrays.json says what the arrays' numbers mean (the stage's
units, up axis and rates), and the surface's triangles come with surface.npy."""

from __future__ import annotations

import json

import numpy as np

from tests.conftest import SCENES
from warp_tube.batch import run_batch

DEFAULT = SCENES / "default.usda"
POINTS = "@/World/Tube.points"
COUNTS = "/World/Tube.curveVertexCounts"
PUSHED = "/World/Push.warptube:point"


def _rest_points():
    from pxr import Usd

    stage = Usd.Stage.Open(str(DEFAULT))
    return np.asarray(stage.GetAttributeAtPath("/World/Tube.points").Get(), dtype=np.float64), stage


def test_arrays_json_gives_the_stage_and_surface_faces_give_each_variants_triangles(tmp_path):
    """Two variants of other point counts (21 and 11): two triangulations, each variant's as its
    USD Surface has it (faceVertexIndices), indices into its own vertices of surface.npy."""
    from pxr import UsdGeom

    pts, stage = _rest_points()
    np.save(tmp_path / "all.npy", pts)
    np.save(tmp_path / "half.npy", pts[::2])
    table = tmp_path / "t.csv"
    table.write_text(f"{POINTS},{COUNTS},{PUSHED}\nall.npy,[{len(pts)}],15\nhalf.npy,[{len(pts[::2])}],8\nall.npy,[{len(pts)}],15\n")
    arr, files = tmp_path / "arrays", tmp_path / "files"
    run_batch(str(DEFAULT), str(arr), str(table), frames=3, layout="arrays", surface=True, writers=0)
    run_batch(str(DEFAULT), str(files), str(table), frames=3, writers=0)
    meta = json.loads((arr / "arrays.json").read_text())
    # (the keys there before, kept)
    assert {"centerline.npy", "variants", "points", "time_codes", "surface.npy", "vertices"} <= meta.keys()
    assert meta["metersPerUnit"] == UsdGeom.GetStageMetersPerUnit(stage)
    assert meta["upAxis"] == UsdGeom.GetStageUpAxis(stage)
    assert meta["timeCodesPerSecond"] == stage.GetTimeCodesPerSecond()
    assert meta["framesPerSecond"] == stage.GetFramesPerSecond()
    faces = np.load(arr / "surface_faces.npy")
    assert faces.dtype == np.int32 and faces.ndim == 3 and faces.shape[2] == 3
    assert meta["topology"] == [0, 1, 0] and len(meta["faces"]) == 2 == len(faces)
    surf = np.load(arr / "surface.npy")
    for k in range(3):
        row = meta["topology"][k]
        tri = faces[row, : meta["faces"][row]]
        assert (faces[row, meta["faces"][row] :] == -1).all()
        from pxr import Usd

        out = Usd.Stage.Open(str(files / f"variant_{k:05d}.usdc"))
        usd = np.asarray(out.GetAttributeAtPath("/World/Tube/Surface.faceVertexIndices").Get())
        assert np.array_equal(tri.reshape(-1), usd)
        assert tri.max() == meta["vertices"][k] - 1 and np.isfinite(surf[k, :, : meta["vertices"][k]]).all()


def test_arrays_json_without_the_surface_has_no_faces(tmp_path):
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n1e5\n")
    out = tmp_path / "out"
    run_batch(str(DEFAULT), str(out), str(table), frames=2, layout="arrays", writers=0)
    meta = json.loads((out / "arrays.json").read_text())
    assert "metersPerUnit" in meta and "faces" not in meta and not (out / "surface_faces.npy").exists()
