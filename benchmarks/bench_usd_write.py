"""USD writing cost per frame against usd-core's own floor. Prints JSON.

    python benchmarks/bench_usd_write.py [--frames 200]

For a tube whose Surface has V vertices: ``StageWriter.write_frame`` (Centerline points, Surface
points, normals and extent, one ``Sdf.ChangeBlock``) against usd-core writing only the bare
Surface points of the same size (``Vt.Vec3fArray.FromNumpy`` + ``Sdf.Layer.SetTimeSample``), both
into in-memory stages, medians over ``--frames`` frames, measured side by side in one run.
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
    from pxr import Usd, UsdGeom, Vt

    from warp_tube.scene import Scene, StageInfo, TubeParams, TubeSpec
    from warp_tube.writer import StageWriter

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
        with tempfile.TemporaryDirectory() as d:
            w = StageWriter(os.path.join(d, "o.usdc"), scene, [Surf()])
            ours = []
            for k in range(a.frames):
                t0 = time.perf_counter()
                w.write_frame(float(k), [cl[k]], [(pts[k], nrm[k])])
                ours.append(time.perf_counter() - t0)
            w.abort()
        st = Usd.Stage.CreateInMemory()
        mesh = UsdGeom.Mesh.Define(st, "/M")
        path = mesh.CreatePointsAttr().GetPath()
        layer = st.GetRootLayer()
        bare = []
        for k in range(a.frames):
            t0 = time.perf_counter()
            layer.SetTimeSample(path, float(k), Vt.Vec3fArray.FromNumpy(pts[k]))
            bare.append(time.perf_counter() - t0)
        mo, mb = float(np.median(ours)), float(np.median(bare))
        out["cases"].append({"hubs": hubs, "spokes": spokes, "vertices": V, "write_frame_us": mo * 1e6,
                             "bare_points_us": mb * 1e6, "ratio": mo / mb})  # fmt: skip
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
