"""Extraction inputs as DCC tools write them: a USD Mesh whose warptube: parameters are time
samples, and a mesh file named like a part of the output (Surface.stl)."""

import numpy as np
import trimesh
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from warp_tube import load_scene
from warp_tube.cli import main
from warp_tube.extract.usd import prim_name

from .test_extract_robustness import straight_tube


def mesh_tube_stage(path, vertices, faces):
    """A new stage at ``path`` holding ``/World/Tube``: a Mesh of ``vertices`` (V, 3) and triangles
    ``faces`` (F, 3) with ``warptube:extract`` and a Young's modulus of 1e5 Pa (no density: the
    caller sets it). Returns ``(stage, prim)``; the caller saves the stage."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.Xform.Define(stage, "/World")
    mesh = UsdGeom.Mesh.Define(stage, "/World/Tube")
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in np.asarray(vertices, dtype=float)]))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(faces)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(np.asarray(faces).reshape(-1).tolist()))
    prim = mesh.GetPrim()
    prim.CreateAttribute("warptube:extract", Sdf.ValueTypeNames.Bool).Set(True)
    prim.CreateAttribute("warptube:youngsModulus", Sdf.ValueTypeNames.Double).Set(1e5)
    return stage, prim


def test_time_sampled_parameters_of_an_extracted_mesh_are_read_at_the_first_frame(tmp_path, caplog):
    """A Mesh with ``warptube:extract`` whose density is authored only as time samples (as DCC
    tools often write attributes) is read at the start frame, with a warning that the samples
    differ, instead of being reported missing."""
    v, f = straight_tube(length=10.0, radius=1.0)
    stage, prim = mesh_tube_stage(tmp_path / "s.usda", v, f)
    stage.SetStartTimeCode(1.0)
    stage.SetEndTimeCode(3.0)
    density = prim.CreateAttribute("warptube:density", Sdf.ValueTypeNames.Double)
    density.Set(900.0, 1.0)
    density.Set(1200.0, 3.0)
    stage.GetRootLayer().Save()
    scene = load_scene(str(tmp_path / "s.usda"))
    assert scene.tubes[0].params.density == 900.0  # the value at startTimeCode 1, exactly
    assert any("warptube:density: time-sampled" in r.getMessage() for r in caplog.records)


def test_a_mesh_named_surface_extracts_to_a_tube_not_named_like_the_outputs_parts(tmp_path, monkeypatch):
    """``Surface.stl`` would name the tube Surface, and the output writes a Surface under each
    tube: the tube is named Surface_tube, and its run's output has one tube at that path."""
    assert prim_name("Surface.stl") == "Surface_tube" and prim_name("centerline.ply") == "centerline"
    v, f = straight_tube(length=10.0, radius=1.0)
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "Surface.stl")
    monkeypatch.chdir(tmp_path)
    assert main(["extract", "Surface.stl", "-o", "s.usda", "--scale", "0.01"]) == 0
    assert main(["run", "s.usda", "-o", "out.usdc", "--frames", "2", "--quiet"]) == 0
    stage = Usd.Stage.Open(str(tmp_path / "out.usdc"))
    surfaces = [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert surfaces == ["/World/Surface_tube/Surface"], surfaces
    assert np.isfinite(np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath(surfaces[0])).GetPointsAttr().Get(1.0))).all()


def test_a_plain_cylinder_given_in_a_scene_is_measured_as_extract_measures_it(tmp_path, caplog):
    """A cylinder whose vertices are its two end rings (trimesh's): `warp-tube extract` measures its
    fit on the mesh as it refined it; given as a scene's Mesh, it was measured on the raw mesh,
    with no vertex away from the ends, and warned "could not be measured"."""
    cyl = trimesh.creation.cylinder(radius=1.0, height=20.0, sections=32)
    assert len(np.unique(np.round(cyl.vertices[:, 2], 6))) <= 3  # (its end rings, and the caps' centres)
    stage, prim = mesh_tube_stage(tmp_path / "s.usda", cyl.vertices, cyl.faces)
    prim.CreateAttribute("warptube:density", Sdf.ValueTypeNames.Double).Set(1000.0)
    stage.GetRootLayer().Save()
    with caplog.at_level("WARNING"):
        load_scene(str(tmp_path / "s.usda"))
    assert "could not be measured" not in caplog.text, caplog.text
