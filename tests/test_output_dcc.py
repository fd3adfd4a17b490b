"""Outputs as DCC tools read them: the USD stage (usdview, Houdini, Blender) and the OBJ / GLB files
of `export`, checked against the formats' rules on a small scene of two tubes (one capped, one
open) in a Z-up millimetre stage starting at frame 1001."""

import json
import struct

import numpy as np
import pytest
from pxr import Usd, UsdGeom, Vt

from warp_tube.cli import main

from .conftest import check_output_problems, needs_shared

SCENE = """#usda 1.0
(
    defaultPrim = "Root"
    metersPerUnit = 0.001
    upAxis = "Z"
    timeCodesPerSecond = 30
    framesPerSecond = 30
    startTimeCode = 1001
    endTimeCode = 1100
)
def Xform "Root"
{
    def Scope "Simulation"
    {
        float3 warptube:gravity = (0, 0, -9.81)
    }
    def Xform "Group"
    {
        double3 xformOp:translate = (0, 0, 50)
        uniform token[] xformOpOrder = ["xformOp:translate"]
        def BasisCurves "Capped"
        {
            uniform token type = "linear"
            int[] curveVertexCounts = [6]
            point3f[] points = [(0, 0, 0), (20, 0, 0), (40, 0, 0), (60, 0, 0), (80, 0, 0), (100, 0, 0)]
            float[] widths = [10] (interpolation = "constant")
            double warptube:youngsModulus = 100000
            double warptube:density = 1050
            double warptube:damping = 2
            int[] warptube:pinnedPoints = [0, 1]
            int warptube:spokes = 8
            bool warptube:caps = true
        }
    }
    def BasisCurves "Open"
    {
        uniform token type = "linear"
        int[] curveVertexCounts = [5, 4]
        point3f[] points = [(0, 30, 0), (20, 30, 0), (40, 30, 0), (60, 30, 0), (80, 30, 0), (0, 60, 0), (20, 60, 0), (40, 60, 0), (60, 60, 0)]
        float[] widths = [8] (interpolation = "constant")
        double warptube:youngsModulus = 100000
        double warptube:density = 1050
        double warptube:damping = 2
        int[] warptube:pinnedPoints = [0, 1, 5, 6]
        int warptube:spokes = 6
    }
}
"""
FRAMES = [1001.0, 1002.0, 1003.0]
CAPPED, OPEN = "/Root/Group/Capped", "/Root/Open"


@pytest.fixture(scope="module")
def stage_path(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dcc")
    (folder / "tubes.usda").write_text(SCENE)
    out = folder / "tubes.usda.out.usda"
    assert main(["run", str(folder / "tubes.usda"), "-o", str(out), "--frames", "3", "--quiet"]) == 0
    return out


def surface(stage, tube):
    return UsdGeom.Mesh(stage.GetPrimAtPath(tube + "/Surface"))


def samples(mesh, t):
    P = np.array(mesh.GetPointsAttr().Get(t), dtype=np.float32)
    N = np.array(mesh.GetNormalsAttr().Get(t), dtype=np.float32)
    F = np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    return P, N, F


def test_open_tube_surface_is_double_sided_and_capped_one_single_sided(stage_path):
    st = Usd.Stage.Open(str(stage_path))
    # Storm culls back faces of a mesh that is not doubleSided: the open tube's inner wall would vanish
    assert surface(st, OPEN).GetDoubleSidedAttr().HasAuthoredValue()
    assert surface(st, OPEN).GetDoubleSidedAttr().Get() is True
    assert surface(st, CAPPED).GetDoubleSidedAttr().Get() is False


def test_stage_metadata_and_samples_as_a_dcc_reads_them(stage_path):
    st = Usd.Stage.Open(str(stage_path))
    assert UsdGeom.GetStageUpAxis(st) == "Z" and UsdGeom.GetStageMetersPerUnit(st) == 0.001
    assert (st.GetTimeCodesPerSecond(), st.GetFramesPerSecond()) == (30.0, 30.0)
    assert (st.GetStartTimeCode(), st.GetEndTimeCode()) == (1001.0, 1003.0)
    assert st.GetDefaultPrim().GetPath() == "/Root"
    for tube in (CAPPED, OPEN):
        mesh = surface(st, tube)
        assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
        assert mesh.GetOrientationAttr().Get() == "rightHanded"
        assert mesh.GetNormalsInterpolation() == "vertex"
        for attr in (mesh.GetPointsAttr(), mesh.GetNormalsAttr(), mesh.GetExtentAttr()):
            assert attr.GetTimeSamples() == FRAMES  # exactly at the stage's frames
        cl = UsdGeom.BasisCurves(st.GetPrimAtPath(tube + "/Centerline"))
        assert cl.GetPointsAttr().GetTimeSamples() == FRAMES


def test_extent_and_bounding_box_equal_the_points_bounds_at_every_frame(stage_path):
    st = Usd.Stage.Open(str(stage_path))
    for t in FRAMES:
        cache = UsdGeom.BBoxCache(t, [UsdGeom.Tokens.default_])  # as usdview frames a selection
        for tube in (CAPPED, OPEN):
            mesh = surface(st, tube)
            P, _, _ = samples(mesh, t)
            # extent is the float32 min / max of the same float32 points: exact
            np.testing.assert_array_equal(np.array(mesh.GetExtentAttr().Get(t)), np.stack([P.min(0), P.max(0)]))
            box = cache.ComputeWorldBound(mesh.GetPrim()).ComputeAlignedRange()
            np.testing.assert_array_equal(np.array(box.GetMin(), dtype=np.float32), P.min(0))
            np.testing.assert_array_equal(np.array(box.GetMax(), dtype=np.float32), P.max(0))


def test_normals_point_outwards_and_match_the_winding(stage_path):
    st = Usd.Stage.Open(str(stage_path))
    for t in FRAMES:
        for tube in (CAPPED, OPEN):
            P, N, F = samples(surface(st, tube), t)
            assert N.shape == P.shape
            np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0, atol=1e-5)  # float32 unit vectors
            a, b, c = (P[F[:, k]].astype(np.float64) for k in range(3))
            face_n = np.cross(b - a, c - a)
            # rightHanded: counter-clockwise seen from outside, so each face normal agrees with its vertices'
            assert (np.einsum("ij,ij->i", face_n, N[F].sum(1)) > 0).all()
            # and points away from the axis: outward from the centerline point of its ring
            cl = np.array(UsdGeom.BasisCurves(st.GetPrimAtPath(tube + "/Centerline")).GetPointsAttr().Get(t))
            nearest = cl[np.argmin(np.linalg.norm(P[:, None] - cl[None], axis=2), axis=1)]
            assert (np.einsum("ij,ij->i", P - nearest, N) > 0).all()
        P, _, F = samples(surface(st, CAPPED), t)
        a, b, c = (P[F[:, k]].astype(np.float64) for k in range(3))
        volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
        # closed surface, outward winding: positive, near the capped cylinder's pi r^2 L + 4/3 pi r^3
        # (an octagon's section is 0.90 of the circle's and the caps are coarse: within 15%)
        assert volume == pytest.approx(np.pi * 25 * 100 + 4 / 3 * np.pi * 125, rel=0.15)


@needs_shared
def test_output_passes_the_output_checker(stage_path):
    assert check_output_problems(stage_path, require_surface=True) == []


def read_obj(path):
    """Objects of an OBJ file as {name: (v, vn, faces as (v, vn) 1-based pairs)} and its comments."""
    objects, comments, v, vn, name = {}, [], [], [], None
    for line in path.read_text().splitlines():
        key, *rest = line.split()
        if key == "#":
            comments.append(line)
        elif key == "o":
            name = rest[0]
            objects[name] = []
        elif key == "v":
            v.append([float(x) for x in rest])
        elif key == "vn":
            vn.append([float(x) for x in rest])
        elif key == "f":
            objects[name].append([[int(i) for i in c.split("//")] for c in rest])
    return objects, np.array(v), np.array(vn), comments


def test_obj_export_has_one_object_per_tube_in_stage_units_and_axes(stage_path, tmp_path):
    assert main(["export", str(stage_path), "-o", str(tmp_path), "--frame", "1003"]) == 0
    objects, v, vn, comments = read_obj(tmp_path / "tubes.usda.out.1003.obj")
    st = Usd.Stage.Open(str(stage_path))
    assert list(objects) == [CAPPED + "/Surface", OPEN + "/Surface"]
    assert "1 unit = 0.001 m" in comments[1] and "up axis: Z" in comments[1]
    base = 0
    for tube in (CAPPED, OPEN):
        P, N, F = samples(surface(st, tube), 1003.0)
        faces = np.array(objects[tube + "/Surface"])
        assert faces.shape == (len(F), 3, 2)
        np.testing.assert_array_equal(faces[..., 0] - 1 - base, F)  # same triangles, same winding
        np.testing.assert_array_equal(faces[..., 1], faces[..., 0])
        # %.9g text round-trips float32 exactly
        np.testing.assert_array_equal(v[base:base + len(P)].astype(np.float32), P)
        # export renormalises the normals in double precision: within a float32 ulp of the stage's
        np.testing.assert_allclose(vn[base:base + len(P)], N, rtol=0, atol=2e-7)
        base += len(P)
    assert len(v) == base


def read_glb(path):
    data = path.read_bytes()
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert (magic, version, length) == (b"glTF", 2, len(data))
    n = struct.unpack("<I", data[12:16])[0]
    gltf = json.loads(data[20:20 + n])
    binary = data[20 + n + 8:]

    def accessor(i):
        a = gltf["accessors"][i]
        view = gltf["bufferViews"][a["bufferView"]]
        width = {"SCALAR": 1, "VEC3": 3}[a["type"]]
        dtype = {5126: np.float32, 5125: np.uint32}[a["componentType"]]
        start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        return np.frombuffer(binary, dtype, a["count"] * width, start).reshape(a["count"], width)

    return gltf, accessor


def test_glb_export_is_in_metres_y_up_with_a_double_sided_material_for_the_open_tube(stage_path, tmp_path):
    out = tmp_path / "f.glb"
    assert main(["export", str(stage_path), "--format", "glb", "-o", str(out), "--frame", "1002"]) == 0
    gltf, accessor = read_glb(out)
    from warp_tube import __version__

    assert gltf["asset"] == {"version": "2.0", "generator": f"warp_tube {__version__}"}  # (it named trimesh)
    st = Usd.Stage.Open(str(stage_path))
    nodes = {node["name"]: gltf["meshes"][node["mesh"]] for node in gltf["nodes"]}
    assert list(nodes) == [CAPPED + "/Surface", OPEN + "/Surface"]
    for tube, two_sided in ((CAPPED, False), (OPEN, True)):
        P, _, F = samples(surface(st, tube), 1002.0)
        [prim] = nodes[tube + "/Surface"]["primitives"]
        pos = accessor(prim["attributes"]["POSITION"])
        # Z-up millimetres -> Y-up metres: (x, y, z) -> 0.001 (x, z, -y); float32 products
        expected = 0.001 * np.stack([P[:, 0], P[:, 2], -P[:, 1]], 1).astype(np.float64)
        np.testing.assert_allclose(pos, expected, rtol=1e-6, atol=1e-9)
        np.testing.assert_array_equal(accessor(prim["indices"]).reshape(-1, 3), F)
        material = gltf["materials"][prim["material"]]
        assert material["doubleSided"] is two_sided
        assert material["pbrMetallicRoughness"]["metallicFactor"] == 0.0


def test_frame_names_keep_one_width_so_they_sort_in_frame_order(tmp_path):
    path = tmp_path / "s.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.Xform.Define(stage, "/W")
    mesh = UsdGeom.Mesh.Define(stage, "/W/T/Surface")
    mesh.CreateFaceVertexCountsAttr().Set(Vt.IntArray([3]))
    mesh.CreateFaceVertexIndicesAttr().Set(Vt.IntArray([0, 1, 2]))
    for t in (9998, 9999, 10000):
        mesh.GetPointsAttr().Set(Vt.Vec3fArray([(0, 0, 0), (1, 0, 0), (0, 1, 0)]), t)
    stage.GetRootLayer().Save()
    assert main(["export", str(path), "-o", str(tmp_path / "seq")]) == 0
    names = sorted(p.name for p in (tmp_path / "seq").iterdir())
    assert names == ["s.09998.obj", "s.09999.obj", "s.10000.obj"]


def test_export_warns_of_an_earlier_longer_sequence_in_its_folder_and_keeps_it(stage_path, tmp_path, capsys):
    folder = tmp_path / "seq"
    folder.mkdir()
    (folder / "tubes.usda.out.1004.obj").write_bytes(b"earlier export")
    (folder / "notes.txt").write_bytes(b"mine")
    assert main(["export", str(stage_path), "-o", str(folder)]) == 0
    err = capsys.readouterr().err
    assert "holds 1 other frame file(s) of this name (tubes.usda.out.1004.obj)" in err
    assert (folder / "tubes.usda.out.1004.obj").read_bytes() == b"earlier export"
    assert sorted(p.name for p in folder.iterdir()) == ["notes.txt"] + [f"tubes.usda.out.{int(t)}.obj" for t in FRAMES + [1004.0]]
    assert main(["export", str(stage_path), "-o", str(tmp_path / "fresh")]) == 0
    assert "other frame file" not in capsys.readouterr().err


def test_writer_given_a_topology_without_a_caps_flag_finds_the_open_one_by_its_edges(tmp_path):
    from types import SimpleNamespace

    import warp_tube
    from warp_tube.io.writer import StageWriter

    (tmp_path / "tubes.usda").write_text(SCENE)
    scene = warp_tube.load_scene(str(tmp_path / "tubes.usda"))
    closed = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]  # a tetrahedron: every edge in two faces
    strip = [[0, 1, 2], [0, 2, 3]]  # a square: four edges in one face only

    def topology(faces):
        return SimpleNamespace(face_vertex_counts=np.full(len(faces), 3), face_vertex_indices=np.ravel(faces),
                               st=np.zeros((3 * len(faces), 2)), st_interpolation="faceVarying")  # fmt: skip

    w = StageWriter(str(tmp_path / "o.usda"), scene, [topology(closed), topology(strip)])
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    w.write_frame(1001, [t.points for t in scene.tubes], [(corners, corners), (corners, corners)])
    w.close()
    st = Usd.Stage.Open(str(tmp_path / "o.usda"))
    assert not surface(st, CAPPED).GetDoubleSidedAttr().HasAuthoredValue()
    assert surface(st, OPEN).GetDoubleSidedAttr().Get() is True


def test_centerline_is_a_guide_beside_its_surface_and_plain_without_one(stage_path, tmp_path):
    st = Usd.Stage.Open(str(stage_path))
    for tube in (CAPPED, OPEN):
        # a render (purpose render / default) leaves guides out: only the Surface is drawn
        assert UsdGeom.Imageable(st.GetPrimAtPath(tube + "/Centerline")).ComputePurpose() == "guide"
        assert UsdGeom.Imageable(st.GetPrimAtPath(tube + "/Surface")).ComputePurpose() == "default"
    (tmp_path / "tubes.usda").write_text(SCENE)
    out = tmp_path / "bare.usda"
    assert main(["run", str(tmp_path / "tubes.usda"), "-o", str(out), "--frames", "2", "--quiet", "--no-surface"]) == 0
    bare = Usd.Stage.Open(str(out))
    assert UsdGeom.Imageable(bare.GetPrimAtPath(OPEN + "/Centerline")).ComputePurpose() == "default"


def test_texture_coordinates_are_face_varying_over_the_documented_ranges(stage_path):
    st = Usd.Stage.Open(str(stage_path))
    for tube, cap in ((OPEN, 0.0), (CAPPED, np.pi * 5.0 / 2 / 100.0)):  # quarter circle of r = 5 over L = 100
        mesh = surface(st, tube)
        primvar = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
        assert primvar.GetInterpolation() == "faceVarying" and primvar.GetTypeName() == "texCoord2f[]"
        uv = np.array(primvar.ComputeFlattened())
        assert len(uv) == len(mesh.GetFaceVertexIndicesAttr().Get())  # one per face corner
        # u: 0 to 1 around; v: 0 to 1 along the body, caps beyond by their arc (float32 values)
        np.testing.assert_allclose([uv[:, 0].min(), uv[:, 0].max()], [0.0, 1.0], atol=1e-7)
        np.testing.assert_allclose([uv[:, 1].min(), uv[:, 1].max()], [-cap, 1.0 + cap], atol=1e-6)


def test_obj_comment_stays_one_line_for_a_stage_named_with_a_line_break(stage_path, tmp_path):
    odd = tmp_path / "two\nlines.usda"
    odd.write_bytes(stage_path.read_bytes())
    assert main(["export", str(odd), "--frame", "1001", "-o", str(tmp_path / "f.obj")]) == 0
    lines = (tmp_path / "f.obj").read_text().splitlines()
    assert lines[0].startswith("# two lines.usda, time code 1001") and lines[1].startswith("# units:")
    assert lines[2] == "o " + CAPPED + "/Surface"
