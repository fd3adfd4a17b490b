"""warp-tube batch on one GPU against all GPUs of the host: identical results, speed-up. Prints JSON.

    python benchmarks/bench_batch_gpus.py [--variants 16384] [--frames 61] [--layouts files,arrays]
                                          [--substeps 30] [--every 1] [--chunk C]

The batch of ``bench_batch.py`` (curved, clamped, pushed 20 x 16 tube, 30 substeps a frame, or
``--substeps``: more substeps make the same outputs cost more simulation, as a stiffer material
or a finer tube would), run
with ``--workers 1`` (one GPU) and then on every GPU (one worker process each), output writing
included. Results are compared file by file (``files``: every ``variant_*.usdc`` byte for byte;
``arrays``: ``centerline.npy`` and ``surface.npy`` element for element, NaN equal) and the
wall-time speed-up is reported with the writing's share (``write_wait_s``: time the simulation
waited for writers; ``write_s``: the writers' own time, summed).
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import shutil
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_batch import write_scene, write_table  # noqa: E402


def same_outputs(a: str, b: str, layout: str) -> bool:
    if layout == "arrays":
        return all(np.array_equal(np.load(os.path.join(a, n)), np.load(os.path.join(b, n)), equal_nan=True)
                   for n in ("centerline.npy", "surface.npy"))  # fmt: skip
    names = sorted(n for n in os.listdir(a) if n.endswith(".usdc"))
    return names == sorted(n for n in os.listdir(b) if n.endswith(".usdc")) and all(
        filecmp.cmp(os.path.join(a, n), os.path.join(b, n), shallow=False) for n in names)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", type=int, default=16384)
    ap.add_argument("--frames", type=int, default=61)
    ap.add_argument("--layouts", default="files,arrays")
    ap.add_argument("--substeps", type=int, default=30, help="substeps a frame (the scene's timeStep: 1/(60 substeps) s)")
    ap.add_argument("--every", type=int, default=1, help="write every K-th frame (more simulation for the same output)")
    ap.add_argument("--chunk", type=int, help="variants per chunk, both runs (default: the batch's own choice for each)")
    a = ap.parse_args()
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    from warp_tube.batch import run_batch

    gpus = wp.get_cuda_device_count()
    out = {"benchmark": "batch_gpus", "gpus": gpus, "variants": a.variants, "frames": a.frames, "substeps": a.substeps,
           "every": a.every, "chunk": a.chunk, "runs": []}  # fmt: skip
    tmp = tempfile.mkdtemp(prefix="bench-batch-gpus-")
    try:
        scene, table = write_scene(tmp, a.substeps), write_table(tmp, a.variants)
        for w in (1, None):  # warm-up, untimed: each GPU's kernels compiled or loaded before the runs
            run_batch(scene, os.path.join(tmp, f"warm{w}"), write_table(tmp, 4, "warm.csv"), frames=2, workers=w, chunk=1)
        for layout in a.layouts.split(","):
            runs = {}
            for label, workers in (("one_gpu", 1), ("all_gpus", None)):
                folder = os.path.join(tmp, f"{layout}_{label}")
                r = run_batch(scene, folder, table, layout=layout, frames=a.frames, every=a.every, surface=True, workers=workers,
                              chunk=a.chunk)  # fmt: skip
                runs[label] = (folder, r)
            (f1, r1), (fn, rn) = runs["one_gpu"], runs["all_gpus"]
            out["runs"].append({
                "layout": layout, "identical": same_outputs(f1, fn, layout), "speedup": r1.wall_s / rn.wall_s,
                **{f"{k}_{label}": getattr(r, k) for label, (_, r) in runs.items()
                   for k in ("wall_s", "prepare_s", "write_wait_s", "write_s", "devices", "ok")},
                **{f"split_{label}": {k: round(v, 3) for k, v in r.timings.items()} for label, (_, r) in runs.items()},
                "kernels_s_one_gpu": r1.timings["kernels_s"], "kernels_s_all_gpus_summed": rn.timings["kernels_s"],
            })  # fmt: skip
            for folder, _ in runs.values():
                shutil.rmtree(folder, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
