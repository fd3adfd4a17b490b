"""preview and export of an output stage whose Surface or Centerline is not sound: an index beyond
the points (or negative), fewer points than the faces use, no points, a point that is not finite, a
face of fewer than 3 vertices, counts that do not sum to the indices, a Centerline whose counts do
not split its points, an unusable metersPerUnit, and an empty ``-o``. Each is one line naming the
stage, the prim and the time code (exit status 2), with nothing written."""

import math

import pytest
from pxr import Usd, UsdGeom, Vt

from warp_tube.cli import main

from .test_export_safety import FRAMES, one_line, stage, tree  # noqa: F401 (stage: a fixture)


def edit(path, change):
    """Apply ``change(mesh, stage)`` to the Surface of the stage at ``path``, and save it."""
    st = Usd.Stage.Open(str(path))
    change(UsdGeom.Mesh(st.GetPrimAtPath("/World/Tube/Surface")), st)
    st.GetRootLayer().Save()


def _indices(values):
    return lambda m, st: m.GetFaceVertexIndicesAttr().Set(Vt.IntArray(values))


def _points(make):
    def change(m, st):
        for f in FRAMES:
            m.GetPointsAttr().Set(Vt.Vec3fArray(make(f)), f)

    return change


def _mpu(value):
    return lambda m, st: UsdGeom.SetStageMetersPerUnit(st, value)


def _centerline(points, counts):
    def change(m, st):
        c = UsdGeom.BasisCurves.Define(st, "/World/Tube/Centerline")
        c.CreateTypeAttr().Set(UsdGeom.Tokens.linear)
        c.CreateCurveVertexCountsAttr().Set(Vt.IntArray(counts))
        for f in FRAMES:
            c.GetPointsAttr().Set(Vt.Vec3fArray(points), f)

    return change


GOOD_INDICES = [0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2]
NAN = math.nan
CASES = {
    "index beyond the points": (_indices([99999] + GOOD_INDICES[1:]),
                                "/World/Tube/Surface at time 0: faceVertexIndices[0] = 99999: expected 0 to 3"),
    "negative index": (_indices(GOOD_INDICES[:4] + [-1] + GOOD_INDICES[5:]),
                       "/World/Tube/Surface at time 0: faceVertexIndices[4] = -1: expected 0 to 3"),
    "fewer points than the faces use": (_points(lambda f: [(f, 0, 0), (f + 1, 0, 0), (f, 1, 0)]),
                                        "faceVertexIndices[5] = 3: expected 0 to 2 (the mesh has 3 points"),
    "no points": (_points(lambda f: []), "/World/Tube/Surface at time 0: no points"),
    "a point that is not finite": (_points(lambda f: [(f, 0, 0), (NAN, 0, 0), (f, 1, 0), (f, 0, 1)]),
                                   "at time 0: 1 of its 4 points is not finite (point 1: nan, 0, 0)"),
    "a face of two vertices": (lambda m, st: m.GetFaceVertexCountsAttr().Set(Vt.IntArray([2, 4, 3, 3])),
                               "faceVertexCounts[0] = 2: a face needs at least 3 vertices"),
    "counts that do not sum to the indices": (lambda m, st: m.GetFaceVertexCountsAttr().Set(Vt.IntArray([3, 3, 3])),
                                              "faceVertexCounts sum to 9, but faceVertexIndices holds 12 indices"),
    "metersPerUnit NaN": (_mpu(NAN), "out.usda: metersPerUnit nan: expected a finite number > 0"),
    "metersPerUnit negative": (_mpu(-1.0), "out.usda: metersPerUnit -1: expected a finite number > 0"),
}  # fmt: skip
CENTERLINE_CASES = {
    "Centerline counts that do not split its points": (
        _centerline([(0, 0, 0), (1, 0, 0), (2, 0, 0)], [5]),
        "out.usda: /World/Tube/Centerline at time 0: curveVertexCounts [5] do not split its 3 points"),
    "a Centerline point that is not finite": (
        _centerline([(0, 0, 0), (NAN, 0, 0), (2, 0, 0)], [3]),
        "out.usda: /World/Tube/Centerline at time 0: 1 of its 3 points is not finite"),
}  # fmt: skip


def _refused(args, words, capsys, before):
    assert main(args) == 2
    line = one_line(capsys.readouterr().err)
    assert words in line, line
    assert line.startswith("warp-tube: out.usda: "), line
    assert tree(".") == before  # (nothing written: no file, no folder, no temporary file)


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("command", ["preview", "export obj", "export glb", "export one frame"])
def test_an_unsound_surface_is_refused_naming_file_prim_and_time(case, command, stage, capsys):
    change, words = CASES[case]
    edit("out.usda", change)
    before = tree(".")
    args = {"preview": ["preview", "out.usda", "-o", "p.png", "--frames", "3"], "export obj": ["export", "out.usda", "-o", "objs"],
            "export glb": ["export", "out.usda", "--format", "glb"],
            "export one frame": ["export", "out.usda", "--frame", "0", "-o", "f.obj"]}[command]  # fmt: skip
    _refused(args, words, capsys, before)


@pytest.mark.parametrize("case", list(CENTERLINE_CASES))
def test_an_unsound_centerline_is_refused_by_preview(case, stage, capsys):
    change, words = CENTERLINE_CASES[case]
    edit("out.usda", change)
    _refused(["preview", "out.usda", "-o", "p.png", "--frames", "3"], words, capsys, tree("."))


def test_a_bad_frame_after_good_ones_is_refused_before_any_file(stage, capsys):
    """Frame 2's points only: export checks every frame before it writes the first."""
    edit("out.usda", lambda m, st: m.GetPointsAttr().Set(Vt.Vec3fArray([(0, 0, 0), (1, 0, 0), (NAN, 1, 0), (0, 0, 1)]), 2))
    before = tree(".")
    _refused(["export", "out.usda", "-o", "objs"], "/World/Tube/Surface at time 2: 1 of its 4 points", capsys, before)


def test_a_mesh_without_topology_names_the_file(stage, capsys):
    edit("out.usda", lambda m, st: m.GetFaceVertexIndicesAttr().Block())
    _refused(["preview", "out.usda", "-o", "p.png", "--frames", "3"], "out.usda: /World/Tube/Surface at time 0: Surface mesh without points "
             "or topology", capsys, tree("."))  # fmt: skip


def test_export_refuses_an_empty_output_name(stage, capsys):
    before = tree(".")
    assert main(["export", "out.usda", "-o", ""]) == 2
    assert "an empty output name: expected a folder, or one .obj or .glb file with --frame" in one_line(capsys.readouterr().err)
    assert tree(".") == before


def test_a_sound_stage_still_exports_and_previews(stage, capsys):
    assert main(["export", "out.usda", "-o", "objs"]) == 0
    assert main(["preview", "out.usda", "-o", "p.png", "--frames", "3"]) == 0
    assert tree("objs") == [f"out.{f:04d}.obj" for f in FRAMES]
