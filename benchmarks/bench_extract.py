"""Centerline extraction on the five real meshes of ../shared/data/meshes: time and fidelity.

Prints JSON: per mesh the hub count (automatic), seconds of extraction (kernel compile excluded:
one warm-up extraction runs first), mean and 95th-percentile distance from the mesh's vertices to
the rest surface rebuilt from hubs and spokes (fractions of the mean radius; vertices within one
radius of an end or on a side branch left out), length, side branches and stage timings.

Run: ``python benchmarks/bench_extract.py [MESH_DIR] [--spokes S] [--hubs N]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import pathlib
import platform
import sys
import time

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only: no banner, no module messages

from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.fidelity import surface_fidelity
from warp_tube.extract.mesh_io import load_mesh

VOXEL_MM = (0.832031, 0.832031, 1.0)  # EdinGCA CT voxel size (SOURCES.md): mesh units -> mm
DEFAULT_DIR = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "data" / "meshes"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("meshes", nargs="?", default=str(DEFAULT_DIR))
    ap.add_argument("--spokes", type=int, default=16)
    ap.add_argument("--hubs", type=int, default=None)
    ap.add_argument("--device", default=None)
    a = ap.parse_args()
    files = sorted(pathlib.Path(a.meshes).glob("*.ply"))
    if not files:
        raise SystemExit(f"no .ply meshes in {a.meshes}")
    with contextlib.redirect_stdout(sys.stderr):  # Warp's start-up banner and module loads: not JSON
        wp.init()
        warm = load_mesh(files[0], VOXEL_MM if files[0].name.startswith("EdinGCA") else 1.0)
        extract_centerline(warm, hubs=8, spokes=a.spokes, device=a.device)  # compiles or loads kernels
    rows = []
    for f in files:
        scale = VOXEL_MM if f.name.startswith("EdinGCA") else (1.0, 1.0, 1.0)
        mesh = load_mesh(f, scale)
        t0 = time.perf_counter()
        tube = extract_centerline(mesh, hubs=a.hubs, spokes=a.spokes, device=a.device, source=str(f))
        seconds = time.perf_counter() - t0
        fid = surface_fidelity(tube, mesh, device=a.device)
        rows.append({
            "mesh": f.name,
            "units": "mm" if f.name.startswith("EdinGCA") else "m",
            "vertices": int(len(mesh.vertices)),
            "hubs": tube.hubs,
            "spokes": tube.spokes,
            "seconds": round(seconds, 3),
            "fidelity_mean": round(fid.mean, 4),
            "fidelity_p95": round(fid.p95, 4),
            "fidelity_max": round(fid.max, 4),
            "mean_radius": float(f"{fid.mean_radius:.4g}"),
            "vertices_counted": fid.counted,
            "length": float(f"{tube.length:.4g}"),
            "ends": [e.kind for e in tube.ends],
            "branches": [[j, float(f"{x:.4g}")] for j, x in tube.branches],
            "voxel_size": float(f"{tube.voxel_size:.4g}"),
            "stages": {k: round(v, 3) for k, v in tube.timings.items()},
        })  # fmt: skip
    out = {
        "device": str(wp.get_device(a.device)),
        "cpu_count": __import__("os").cpu_count(),
        "machine": platform.processor() or platform.machine(),
        "meshes": rows,
        "all_within_targets": bool(all(r["fidelity_mean"] <= 0.05 and r["fidelity_p95"] <= 0.15 for r in rows)),
        "max_seconds": float(np.max([r["seconds"] for r in rows])),
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
