"""warp-tube batch end to end: where the wall time goes. Prints JSON.

    python benchmarks/bench_batch.py [--variants 1024] [--frames 61] [--layouts files,arrays]
                                     [--device cpu|cuda:0] [--workers N] [--writers M] [--chunk C]
                                     [--floor-variants 1024] [--keep DIR]

The batch: ``--variants`` variants of a curved (a quarter-circle arc), clamped, pushed 20-hub x
16-spoke tube with caps (``scene.usda`` written into a temporary folder), ``--frames`` frames at 60
per second, 30 substeps a frame (``warptube:timeStep`` 1/1800 s, within every variant's stability
bound), the Surface written (``files``) or ``surface.npy`` (``arrays``). The table varies each
variant's Young's modulus (20-50 kPa), mass damping (1-4 1/s) and push (direction and size,
seeded), so all variants are one group: the worlds of one model, in chunks.

Reported per layout, from one ``run_batch`` call (seconds):

- ``wall_s``: the whole batch, reading the variants to the summary (one simulating process unless
  ``--workers`` says otherwise: the kernels' time of several would add up over them);
- ``kernels_s``: the device's time in the simulation's launches (centerline substeps, the frame
  checks' sums, surface rebuilds and frame stores): on a GPU by CUDA events around them, on the
  CPU the launches' own time (``sync_s``, also reported, is the host's time waiting for them; on
  a GPU ``launch_s`` is the host's time queueing them, part of ``other_s``);
- ``other_s``: everything else but writing: ``wall_s - kernels_s - write_wait_s``, i.e. reading
  and checking the table, planning, building the models, copying states back, control, the
  host-side frame checks (``checks_s``, also reported alone), copying into the writers' arrays,
  recording finished chunks (``books_s``: journal records and summary lines); ``rest`` in the
  split is the part of it no timer holds (handing chunks to the writers, the batch's ends);
- ``write_wait_s``: time the simulation waited for the writers (they run in other processes
  or threads meanwhile; ``write_s`` is their summed time), and on a GPU for earlier chunks'
  frames to be copied back to the host for them (``flush_wait_s``, also reported: the device
  memory those frames hold);
- ``floor_s``: usd-core's own time to write the same samples from one process: for ``files``,
  per variant a new layer with the Centerline points and extent and the Surface points, normals and extent
  of every frame (``Vt.Vec3fArray.FromNumpy`` + ``Sdf.Layer.SetTimeSample``, then ``Save``),
  measured on ``--floor-variants`` variants and scaled to all of them; for ``arrays``, NumPy
  writing the same arrays to one ``.npy`` file per output;
- the issue's criteria: ``other_fraction`` (goal <= 0.10) and ``wall_over_bound``, the wall time
  over the larger of ``kernels_s`` and ``floor_s`` (goal <= 1.5).

A two-variant batch runs first, untimed, so that compiling the kernels is not counted.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import tempfile
import time

import numpy as np

HUBS, SPOKES, RADIUS, LENGTH = 20, 16, 0.01, 0.2


def write_scene(folder: str, substeps: int = 30) -> str:
    """A curved, clamped, pushed tube [cm units], 60 frames per second, ``substeps`` a frame."""
    theta = np.linspace(0.0, 0.5 * np.pi, HUBS)
    r = LENGTH / (0.5 * np.pi)
    pts = np.stack([r * np.sin(theta), r * (1 - np.cos(theta)), 0 * theta], 1) / 0.01  # cm
    p = ", ".join(f"({x:.6f}, {y:.6f}, {z:.6f})" for x, y, z in pts)
    text = f"""#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 0.01
    upAxis = "Y"
    timeCodesPerSecond = 60
    framesPerSecond = 60
    startTimeCode = 0
    endTimeCode = 60
)

def Xform "World"
{{
    def Scope "Simulation"
    {{
        token warptube:integrator = "auto"
        double warptube:timeStep = {1.0 / (60.0 * substeps)!r}
    }}

    def BasisCurves "Tube"
    {{
        uniform token type = "linear"
        int[] curveVertexCounts = [{HUBS}]
        point3f[] points = [{p}]
        float[] widths = [{2 * RADIUS / 0.01}] (interpolation = "constant")
        double warptube:youngsModulus = 30000
        double warptube:density = 1050
        double warptube:damping = 2
        int[] warptube:pinnedPoints = [0, 1]
        int warptube:spokes = {SPOKES}
        bool warptube:caps = true
    }}

    def Scope "Push"
    {{
        rel warptube:target = </World/Tube>
        int warptube:point = 15
        float3 warptube:force = (0, 0, 0.02)
        bool warptube:assistantLine = true
    }}
}}
"""
    path = os.path.join(folder, "scene.usda")
    with open(path, "w") as f:
        f.write(text)
    return path


def write_table(folder: str, n: int, name: str = "variants.csv") -> str:
    """``n`` variants (seeded): Young's modulus, mass damping and the push."""
    rng = np.random.default_rng(0)
    path = os.path.join(folder, name)
    with open(path, "w") as f:
        f.write("/World/Tube.warptube:youngsModulus,/World/Tube.warptube:damping,/World/Push.warptube:force\n")
        for _ in range(n):
            e = rng.uniform(2e4, 5e4)
            d = rng.uniform(1.0, 4.0)
            v = rng.normal(size=3)
            v = v / np.linalg.norm(v) * rng.uniform(0.005, 0.03)
            f.write(f'{e:.6g},{d:.4g},"({v[0]:.5g}, {v[1]:.5g}, {v[2]:.5g})"\n')
    return path


def usd_floor(n_variants: int, frames: int, points: int, vertices: int, measure: int, folder: str) -> tuple[float, int]:
    """usd-core writing ``measure`` variants' samples from one process, scaled to ``n_variants``."""
    from pxr import Sdf, Vt

    rng = np.random.default_rng(1)
    cl = rng.normal(size=(frames, points, 3)).astype(np.float32)
    pts = rng.normal(size=(frames, vertices, 3)).astype(np.float32)
    nrm = rng.normal(size=(frames, vertices, 3)).astype(np.float32)
    ext = np.stack([pts.min(axis=1), pts.max(axis=1)], 1)
    cl_ext = np.stack([cl.min(axis=1), cl.max(axis=1)], 1)
    measure = min(measure, n_variants)
    t0 = time.perf_counter()
    for k in range(measure):
        layer = Sdf.Layer.CreateNew(os.path.join(folder, f"floor_{k}.usdc"))
        paths = []
        for prim, attr in (("/W/T/Centerline", "points"), ("/W/T/Centerline", "extent"), ("/W/T/Surface", "points"),
                           ("/W/T/Surface", "normals"), ("/W/T/Surface", "extent")):  # fmt: skip
            spec = layer.GetPrimAtPath(prim) or Sdf.CreatePrimInLayer(layer, prim)
            spec.specifier = Sdf.SpecifierDef
            a = spec.attributes.get(attr) or Sdf.AttributeSpec(spec, attr, Sdf.ValueTypeNames.Point3fArray)
            paths.append(a.path)
        for f in range(frames):
            for path, values in zip(paths, (cl[f], cl_ext[f], pts[f], nrm[f], ext[f])):
                layer.SetTimeSample(path, float(f), Vt.Vec3fArray.FromNumpy(values))
        layer.Save()
        del layer
        os.remove(os.path.join(folder, f"floor_{k}.usdc"))
    return (time.perf_counter() - t0) * n_variants / measure, measure


def numpy_floor(n_variants: int, frames: int, points: int, vertices: int, surface: bool, folder: str) -> float:
    """NumPy writing arrays of the batch's shapes to .npy files from one process."""
    t0 = time.perf_counter()
    for name, n in (("c", points), ("s", vertices if surface else 0)):
        if n:
            np.save(os.path.join(folder, f"floor_{name}.npy"), np.ones((n_variants, frames, n, 3), dtype=np.float32))
            os.remove(os.path.join(folder, f"floor_{name}.npy"))
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=61)
    ap.add_argument("--layouts", default="files,arrays")
    ap.add_argument("--device")
    ap.add_argument("--workers", type=int, default=1,
                    help="simulating processes (default 1: the split below adds up only for one; a CPU batch of "
                         "arrays of 512 rows a core or more runs one a core by default)")
    ap.add_argument("--writers", type=int)
    ap.add_argument("--chunk", type=int)
    ap.add_argument("--floor-variants", type=int, default=1024)
    ap.add_argument("--keep", help="keep the batch folders here")
    a = ap.parse_args()
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only
    wp.config.quiet = True
    from warp_tube.batch import run_batch

    tmp = tempfile.mkdtemp(prefix="bench-batch-")
    out = {"benchmark": "batch", "date": datetime.date.today().isoformat(), "machine": platform.node(),
           "cpus": os.cpu_count(), "variants": a.variants, "frames": a.frames, "hubs": HUBS, "spokes": SPOKES, "runs": []}  # fmt: skip
    try:
        scene = write_scene(tmp)
        # Warm-up: Warp compiles (or loads) the kernels of this scene's features on their first
        # launch; a small batch first keeps that out of the timed runs.
        run_batch(scene, os.path.join(tmp, "warm"), write_table(tmp, 2, "warm.csv"), frames=2, device=a.device, workers=1,
                  writers=0)  # fmt: skip
        table = write_table(tmp, a.variants)
        for layout in a.layouts.split(","):
            folder = os.path.join(a.keep or tmp, f"out_{layout}")
            shutil.rmtree(folder, ignore_errors=True)
            surface = True
            r = run_batch(scene, folder, table, layout=layout, frames=a.frames, surface=surface, device=a.device,
                          workers=a.workers, writers=a.writers, chunk=a.chunk)  # fmt: skip
            t = r.timings
            points, vertices = HUBS, HUBS * SPOKES + 2 * ((max(2, -(-SPOKES // 4)) - 1) * SPOKES + 1)
            if layout == "arrays":
                floor, measured = numpy_floor(a.variants, r.frames, points, vertices, surface, tmp), a.variants
            else:
                floor, measured = usd_floor(a.variants, r.frames, points, vertices, a.floor_variants, tmp)
            other = r.wall_s - t["kernels_s"] - r.write_wait_s
            split = {"reading_and_planning": r.prepare_s, **{k: v for k, v in t.items() if k != "kernels_s"}, "books_s": r.books_s}
            # the part of other no timer holds: handing chunks to the writers, the ends of the batch
            split["rest"] = other - sum(v for k, v in split.items() if k != "flush_wait_s")
            out["runs"].append({
                "layout": layout, "devices": r.devices, "groups": r.groups, "chunks": r.chunks, "ok": r.ok, "failed": r.failed,
                "wall_s": r.wall_s, "kernels_s": t["kernels_s"], "other_s": other, "write_wait_s": r.write_wait_s,
                "write_s": r.write_s, "floor_s": floor, "floor_measured_variants": measured,
                "split_s": split,
                "other_fraction": other / r.wall_s, "wall_over_bound": r.wall_s / max(t["kernels_s"], floor),
            })  # fmt: skip
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
