"""The ``extent`` of every BasisCurves the package writes, against usd-core's own rule for curves
(``UsdGeom.Boundable.ComputeExtentFromPlugins``: the points' bounds padded by half the largest
width), which viewports (Hydra, usdview) cull by: an extracted scene's tube, a saved scene's tube
with moving pins, and the Centerline of ``warp-tube run`` (complete and partial) and of
``warp-tube batch`` in its ``files`` and ``grid`` layouts, at every time sample."""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from warp_tube.cli import main

from .test_api_checks import tube
from .test_batch import DEFAULT, E, WIDTHS, write_table
from .test_extract import tube_mesh
from .test_output_dcc import SCENE as DCC_SCENE

#: the DCC test's two tubes, the capped one tapering (widths 4 to 14 mm, one per point: the extent
#: takes half the largest)
SCENE = DCC_SCENE.replace('float[] widths = [10] (interpolation = "constant")',
                          'float[] widths = [4, 6, 8, 10, 12, 14] (interpolation = "vertex")')


def curves_extents(path, name=None):
    """Per BasisCurves prim of the stage at ``path`` (those named ``name`` only, where given): its
    prim path and, per time of its points (their default where they have no samples), the
    authored extent, usd-core's extent of the prim at that time, its points and its widths."""
    stage = Usd.Stage.Open(str(path))
    out = {}
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.BasisCurves) or (name is not None and prim.GetName() != name):
            continue
        c = UsdGeom.BasisCurves(prim)
        assert c.GetExtentAttr().GetTimeSamples() == c.GetPointsAttr().GetTimeSamples(), prim.GetPath()
        times = c.GetPointsAttr().GetTimeSamples() or [Usd.TimeCode.Default()]
        out[str(prim.GetPath())] = [(np.array(c.GetExtentAttr().Get(t), dtype=np.float32),
                                     np.array(UsdGeom.Boundable.ComputeExtentFromPlugins(c, Usd.TimeCode(t)), dtype=np.float32),
                                     np.array(c.GetPointsAttr().Get(t), dtype=np.float32),
                                     np.array(c.GetWidthsAttr().Get(t), dtype=np.float32)) for t in times]  # fmt: skip
    return out


def assert_extents_as_usd_computes_them(path, name=None, prims=1, times=None):
    found = curves_extents(path, name)
    assert len(found) == prims, found.keys()
    for prim, samples in found.items():
        assert times is None or len(samples) == times, (prim, len(samples))
        for authored, usd, points, widths in samples:
            # The extent is the float32 bounds of the same float32 points, padded by the same
            # float32 half width in float32 arithmetic as usd-core's UsdGeomCurves::ComputeExtent:
            # exact (before, a Centerline had none and an extracted tube's held the mesh's bounds).
            assert authored.shape == (2, 3), prim
            np.testing.assert_array_equal(authored, usd, err_msg=prim)
            # and, by its definition, it holds every point's sphere of its own width (exact: each
            # width is at most the largest)
            w = np.broadcast_to(widths, len(points))[:, None] / 2
            assert (authored[0] <= points - w).all() and (authored[1] >= points + w).all(), prim


def test_an_extracted_tubes_extent_is_usds_for_its_points_and_widths(tmp_path):
    from warp_tube.extract.pipeline import extract_centerline
    from warp_tube.extract.usd import write_scene

    mesh, _, _ = tube_mesh(caps=True)
    write_scene(extract_centerline(mesh, hubs=24), tmp_path / "tube.usda", meters_per_unit=0.01, name="Helix")
    assert_extents_as_usd_computes_them(tmp_path / "tube.usda")


def test_a_saved_scenes_tube_has_usds_extent_at_every_frame_of_its_moving_pins(tmp_path):
    from warp_tube.scene.spec import Scene, StageInfo, TubeSpec
    from warp_tube.scene.usd import save_scene

    t = tube(pinned=(0, 10))
    track = np.repeat(t.points[[0, 10]][None], 5, axis=0)
    track[:, 1, 1] = np.linspace(0.0, 0.05, 5)  # the far end rises 5 cm over the frames [m]
    moving = TubeSpec(t.path, t.points, t.curve_counts, t.radius, t.params, pinned=t.pinned, pin_track=track)
    save_scene(Scene((moving,), stage=StageInfo(meters_per_unit=0.01, end_time_code=4.0)), str(tmp_path / "moving.usda"))
    assert_extents_as_usd_computes_them(tmp_path / "moving.usda", times=5)
    stage = Usd.Stage.Open(str(tmp_path / "moving.usda"))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(t.path))
    assert np.array_equal(curves.GetExtentAttr().Get(), UsdGeom.Boundable.ComputeExtentFromPlugins(curves, Usd.TimeCode.Default()))


def test_a_runs_centerlines_have_usds_extent_at_every_frame(tmp_path):
    """Two tube prims (one of two curves), one with widths that vary along it, with and without
    the Surface: each Centerline's extent is sampled with its points and is usd-core's."""
    (tmp_path / "tubes.usda").write_text(SCENE)
    for flags in ([], ["--no-surface"]):
        out = tmp_path / f"out{len(flags)}.usda"
        assert main(["run", str(tmp_path / "tubes.usda"), "-o", str(out), "--frames", "3", "--quiet", *flags]) == 0
        assert_extents_as_usd_computes_them(out, "Centerline", prims=2, times=3)


def test_a_partial_output_and_a_frame_of_some_prims_have_usds_extent(tmp_path):
    """What a stopped run keeps (``keep_partial``), and a frame that holds some prims only (a grid's
    variant that failed): every sample written has its extent, the prims left out have none."""
    from warp_tube.io.writer import StageWriter
    from warp_tube.scene.usd import load_scene

    (tmp_path / "tubes.usda").write_text(SCENE)
    scene = load_scene(str(tmp_path / "tubes.usda"))
    w = StageWriter(str(tmp_path / "out.usdc"), scene)
    rng = np.random.default_rng(0)
    points = [t.points / 0.001 for t in scene.tubes]
    w.write_frame(1001.0, [p + rng.normal(size=p.shape) for p in points])
    w.write_frame(1002.0, [points[1] + 1.0], prims=[1])
    partial = w.keep_partial()
    assert partial is not None and not (tmp_path / "out.usdc").exists()
    assert_extents_as_usd_computes_them(partial, "Centerline", prims=2)
    times = {p: len(s) for p, s in curves_extents(partial, "Centerline").items()}
    assert times == {"/Root/Group/Capped/Centerline": 1, "/Root/Open/Centerline": 2}


def test_batch_files_and_grid_centerlines_have_usds_extent_at_every_frame(tmp_path):
    """Variants of other widths, and one that fails (its finished frames kept: a partial file, or
    fewer frames in its grid cell), in the files and grid layouts."""
    table = write_table(tmp_path / "t.csv", [E, WIDTHS, "/World/Simulation.warptube:integrator", "/World/Simulation.warptube:timeStep"],
                        [("100000", "[2]", "semiImplicitEuler", "0.0002"), ("50000000", "[2]", "semiImplicitEuler", "0.0002"),
                         ("80000", "[3]", "semiImplicitEuler", "0.0002")])  # fmt: skip
    files, grid = tmp_path / "files", tmp_path / "grid"
    for out, layout in ((files, "files"), (grid, "grid")):
        status = main(["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "6", "--writers", "0",
                       "--layout", layout, "--quiet"])  # fmt: skip
        assert status == 3  # (the stiff variant fails)
    for name in ("variant_00000.usdc", "variant_00001.partial.usdc", "variant_00002.usdc"):
        assert_extents_as_usd_computes_them(files / name, "Centerline")
    assert_extents_as_usd_computes_them(grid / "grid.usda", "Centerline", prims=3)
    samples = {p: len(s) for p, s in curves_extents(grid / "grid.usda", "Centerline").items()}
    assert samples["/Grid/variant_00000/World/Tube/Centerline"] == 6 and 0 < samples["/Grid/variant_00001/World/Tube/Centerline"] < 6


def test_an_extracted_tube_far_from_the_origin_is_placed_by_a_translate(tmp_path, caplog):
    """A mesh 500 m from its origin (a scan in scanner coordinates): float32 points there step by
    6e-5 m, 0.8% of its 8 mm segments, which the scene's own check warns of. The scene holds the points
    about their middle and a double-precision translate: the tube reads back in world space as
    extracted (float32 of coordinates within 4 cm of the middle: 4e-9 m), and only the world's
    float32 steps, in which the simulation holds and writes its positions, are warned of."""
    from warp_tube.extract.pipeline import extract_centerline
    from warp_tube.extract.usd import write_scene
    from warp_tube.scene.usd import load_scene

    mesh, _, _ = tube_mesh(stations=80, ring=24)
    mesh.apply_scale(0.01)  # a helix 7 cm across, segments of about 8 mm
    mesh.apply_translation([500.0, 0.0, 0.0])
    tube = extract_centerline(mesh, hubs=24)
    path = tmp_path / "far.usda"
    write_scene(tube, path, meters_per_unit=1.0, name="Far", push=False)
    stage = Usd.Stage.Open(str(path))
    ops = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Far")).GetOrderedXformOps()
    assert [op.GetOpName() for op in ops] == ["xformOp:translate"] and ops[0].GetPrecision() == UsdGeom.XformOp.PrecisionDouble
    with caplog.at_level("WARNING"):
        read = load_scene(str(path)).tubes[0]
    said = [r.getMessage() for r in caplog.records if "float32" in r.getMessage()]
    assert len(said) == 1 and "placed up to 500 m from the origin" in said[0] and "float32 world coordinates" in said[0], said
    np.testing.assert_allclose(read.points, tube.points, rtol=0, atol=1e-8)
    assert_extents_as_usd_computes_them(path, None, prims=1)  # (the extent in the prim's own space)
