"""USD writing cost per frame against usd-core's own floor. Prints JSON.

    python benchmarks/bench_usd_write.py [--frames 200]

For a tube whose Surface has V vertices: ``StageWriter.write_frame`` (Centerline points and extent,
Surface points, normals and extent) against usd-core writing only the bare
Surface points of the same size (``Vt.Vec3fArray.FromNumpy`` + ``Sdf.Layer.SetTimeSample``, into a
layer that no stage has open: usd-core's cheapest way, the one the writer takes), medians over
``--frames`` frames, measured side by side in one run. ``bare_points_stage_us``: the same bare
points written the everyday way, ``UsdAttribute.Set`` on an open stage (about 1 us more per sample
for the stage's change processing), and ``ratio_vs_stage_set`` the frame's time against it.

``write_frame`` copies arrays of 2,048 vertices or more into USD with one ``memmove`` each
(:func:`warp_tube.io.writer.vec3f_array`) instead of ``FromNumpy``'s element-by-element conversion; the
bare points written that way (``bare_points_direct_us``) are reported beside the ``FromNumpy`` floor,
so ``ratio_vs_direct`` shows what the extra normals and extent cost by the same path. The extent
is handed over as a run hands it (the surface kernel writes it beside the points). Every sample
stays in memory until the stage is saved, so large frames also pay for fresh pages each time.

``three_bare_writes_us``: usd-core's own cost of the three Surface samples alone (points, normals,
extent, each ``FromNumpy`` + ``SetTimeSample``), the floor of any writer going through its Python
API; on small meshes its ratio to one bare write shows that the fixed cost per sample (a few
microseconds) dominates there.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    a = ap.parse_args()
    from pxr import Sdf, Usd, UsdGeom, Vt

    from warp_tube.scene.spec import Scene, StageInfo, TubeParams, TubeSpec
    from warp_tube.io.writer import StageWriter, vec3f_array

    rng = np.random.default_rng(0)
    out = {"benchmark": "usd_write", "frames": a.frames, "cases": []}
    for hubs, spokes in ((20, 9), (256, 32), (4096, 32)):
        x = np.linspace(0.0, 1.0, hubs)
        tube = TubeSpec("/World/Tube", np.stack([x, 0 * x, 0 * x], 1), [hubs], np.full(hubs, 0.01),
                        TubeParams(density=1000.0, youngs_modulus=1e6, spokes=spokes))  # fmt: skip
        scene = Scene((tube,), stage=StageInfo(meters_per_unit=1.0, end_time_code=float(a.frames)))

        class Surf:  # the topology the writer needs, static
            face_vertex_counts = np.full((hubs - 1) * spokes * 2, 3)
            face_vertex_indices = np.zeros(((hubs - 1) * spokes * 2) * 3, dtype=np.int32)
            st = np.zeros(((hubs - 1) * spokes * 2 * 3, 2), np.float32)
            st_interpolation = "faceVarying"

        V = hubs * spokes
        pts = rng.normal(size=(a.frames, V, 3)).astype(np.float32)
        nrm = rng.normal(size=(a.frames, V, 3)).astype(np.float32)
        cl = rng.normal(size=(a.frames, hubs, 3)).astype(np.float32)
        ext = np.stack([pts.min(axis=1), pts.max(axis=1)], axis=1)  # a run's surface kernel writes it
        layer = Sdf.Layer.CreateAnonymous()
        st = Usd.Stage.Open(layer)
        path_bare = UsdGeom.Mesh.Define(st, "/M").CreatePointsAttr().GetPath()
        path_direct = UsdGeom.Mesh.Define(st, "/D").CreatePointsAttr().GetPath()
        floor_mesh = UsdGeom.Mesh.Define(st, "/F")
        floor_paths = [a.GetPath() for a in (floor_mesh.CreatePointsAttr(), floor_mesh.CreateNormalsAttr(), floor_mesh.CreateExtentAttr())]
        del st  # samples go into a layer no stage listens to, as the writer's do
        staged = Usd.Stage.CreateInMemory()
        staged_points = UsdGeom.Mesh.Define(staged, "/S").CreatePointsAttr()
        ours, bare, direct, floor, on_stage = [], [], [], [], []
        with tempfile.TemporaryDirectory() as d:
            w = StageWriter(os.path.join(d, "o.usdc"), scene, [Surf()])
            for k in range(a.frames):  # interleaved, so that all three see the same memory state
                t0 = time.perf_counter()
                w.write_frame(float(k), [cl[k]], [(pts[k], nrm[k], ext[k])])
                t1 = time.perf_counter()
                layer.SetTimeSample(path_bare, float(k), Vt.Vec3fArray.FromNumpy(pts[k]))
                t2 = time.perf_counter()
                layer.SetTimeSample(path_direct, float(k), vec3f_array(pts[k]))
                t3 = time.perf_counter()
                for path, values in zip(floor_paths, (pts[k], nrm[k], ext[k])):
                    layer.SetTimeSample(path, float(k), Vt.Vec3fArray.FromNumpy(values))
                t4 = time.perf_counter()
                staged_points.Set(Vt.Vec3fArray.FromNumpy(pts[k]), float(k))
                t5 = time.perf_counter()
                on_stage.append(t5 - t4)
                ours.append(t1 - t0)
                bare.append(t2 - t1)
                direct.append(t3 - t2)
                floor.append(t4 - t3)
            w.abort()
        mo, mb, md, mf, ms = (float(np.median(x)) for x in (ours, bare, direct, floor, on_stage))
        out["cases"].append({"hubs": hubs, "spokes": spokes, "vertices": V, "write_frame_us": mo * 1e6,
                             "bare_points_us": mb * 1e6, "ratio": mo / mb,
                             "bare_points_direct_us": md * 1e6, "ratio_vs_direct": mo / md,
                             "three_bare_writes_us": mf * 1e6, "three_bare_writes_ratio": mf / mb,
                             "bare_points_stage_us": ms * 1e6, "ratio_vs_stage_set": mo / ms})  # fmt: skip
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
