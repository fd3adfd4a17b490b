"""Centerline extraction on the real meshes of ../shared/data/meshes and on the synthetic tubes:
time, centring and fidelity of the rest surface the simulator writes.

Per case: the hub count (automatic unless ``--hubs``), seconds of extraction (median of
``--repeat`` runs, kernel compile excluded: one warm-up extraction runs first), and the frame-0
Surface of the scene that ``warp-tube extract`` writes, built through the public API
(``warp_tube.load_scene`` then ``warp_tube.Simulation(scene, device="cpu").surface_points()``):

- distances from the input's vertices to that Surface (side branches and one end radius at each
  end left out) and from the Surface's vertices to the input (nothing left out): mean, 99th
  percentile and largest, as fractions of the mean spoke length;
- the longest over the shortest spoke of the two end rings, and how far the inner-bend guard moved
  a vertex (against the same surface rebuilt with the guard off);
- synthetic tubes: the distance of every interior hub from the true curve, over the local true radius.

Prints JSON; ``--table`` prints a Markdown table instead.

Run: ``python benchmarks/bench_extract.py [MESH_DIR] [--only real|synthetic] [--repeat R] [--hubs N] [--table]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import pathlib
import platform
import sys
import tempfile
import time

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only: no banner, no module messages

import warp_tube
from warp_tube.bench.synthetic_tubes import synthetic_cases
from warp_tube.extract.fidelity import Distances, measured_vertices, mesh_distances, rest_surface
from warp_tube.extract.mesh_io import load_mesh
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.polyline import arclength, project_points
from warp_tube.extract.usd import write_scene

VOXEL_MM = (0.832031, 0.832031, 1.0)  # EdinGCA CT voxel size (SOURCES.md): mesh units -> mm
DEFAULT_DIR = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "data" / "meshes"


def simulated_surface(tube, meters_per_unit: float):
    """Frame-0 Surface of the scene written for ``tube``: ``(points (V, 3) [mesh units], faces (F, 3))``."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "scene.usda")
        write_scene(tube, path, meters_per_unit=meters_per_unit)
        sim = warp_tube.Simulation(warp_tube.load_scene(path), device="cpu")
        points = sim.surface_points()[0].astype(np.float64)
        faces = np.asarray(sim.surfaces[0].face_vertex_indices, dtype=np.int64).reshape(-1, 3)
    return points, faces


def measure(tube, mesh, meters_per_unit: float) -> dict:
    """Two-way distances, end-ring spoke ratios and guard moves of the frame-0 Surface (see module doc)."""
    points, faces = simulated_surface(tube, meters_per_unit)
    radius = float(tube.spoke_lengths.mean())
    end_r = tube.spoke_lengths.mean(axis=1)
    tips = np.stack([e.tip for e in tube.ends])
    keep = measured_vertices(tube.points, end_r[0], end_r[-1], mesh.vertices, tips,
                             [b.path for b in tube.branch_details])  # fmt: skip
    to_surface = Distances.of(mesh_distances(mesh.vertices[keep], points, faces), radius, int((~keep).sum()))
    to_input = Distances.of(mesh_distances(points, mesh.vertices, mesh.faces), radius)
    n, s = tube.spoke_lengths.shape
    ring = np.linalg.norm(points[: n * s].reshape(n, s, 3) - tube.points[:, None], axis=-1)
    ratio = ring.max(axis=1) / ring.min(axis=1)
    unguarded = rest_surface(tube.points, tube.spoke_lengths, tube.reference_normal, tube.caps).unguarded
    return {
        "to_surface": {k: round(getattr(to_surface, k), 4) for k in ("mean", "p99", "max")},
        "to_input": {k: round(getattr(to_input, k), 4) for k in ("mean", "p99", "max")},
        "vertices_left_out": to_surface.left_out,
        "end_ratios": [round(float(ratio[0]), 2), round(float(ratio[-1]), 2)],
        "guard_moved": round(float(np.linalg.norm(points - unguarded, axis=1).max() / radius), 4),
    }


def centring(tube, case) -> dict:
    """Distances of the interior hubs from the true curve over the local true radius."""
    d, arc = project_points(tube.points[1:-1], case.curve)
    local = np.interp(arc, arclength(case.curve), case.radius)
    e = d / local
    return {"hub_error_max": round(float(e.max()), 4), "hub_error_mean": round(float(e.mean()), 4)}


def row(name, mesh, tube, seconds, meters_per_unit, case=None) -> dict:
    out = {
        "mesh": name,
        "vertices": int(len(mesh.vertices)),
        "hubs": tube.hubs,
        "seconds": round(seconds, 3),
        "length": float(f"{tube.length:.4g}"),
        "mean_radius": float(f"{tube.spoke_lengths.mean():.4g}"),
        "ends": [e.kind for e in tube.ends],
        "branches": [[j, float(f"{x:.4g}")] for j, x in tube.branches],
        **measure(tube, mesh, meters_per_unit),
    }
    if case is not None:
        out.update(centring(tube, case))
    return out


def table(result: dict) -> str:
    """Markdown table of the rows."""
    head = ("| mesh | hubs | s | in->surface mean / p99 / max | surface->in mean / p99 / max | end ratios | "
            "guard | hub error max / mean |")  # fmt: skip
    lines = [head, "|" + "---|" * 8]
    for r in result["rows"]:
        a, b = r["to_surface"], r["to_input"]
        hub = f"{100 * r['hub_error_max']:.1f}% / {100 * r['hub_error_mean']:.2f}%" if "hub_error_max" in r else ""
        lines.append(
            f"| {r['mesh']} | {r['hubs']} | {r['seconds']:.2f} | {100 * a['mean']:.1f} / {100 * a['p99']:.1f} / "
            f"{100 * a['max']:.1f} | {100 * b['mean']:.1f} / {100 * b['p99']:.1f} / {100 * b['max']:.1f} | "
            f"{r['end_ratios'][0]:.1f}, {r['end_ratios'][1]:.1f} | {100 * r['guard_moved']:.0f}% | {hub} |"
        )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("meshes", nargs="?", default=str(DEFAULT_DIR))
    ap.add_argument("--only", choices=("real", "synthetic"))
    ap.add_argument("--repeat", type=int, default=3, help="extractions per real mesh (median time)")
    ap.add_argument("--spokes", type=int, default=16)
    ap.add_argument("--hubs", type=int, default=None)
    ap.add_argument("--table", action="store_true", help="print a Markdown table instead of JSON")
    a = ap.parse_args()
    rows = []
    with contextlib.redirect_stdout(sys.stderr):  # Warp's start-up banner and module loads: not JSON
        wp.init()
        cases = synthetic_cases() if a.only != "real" else []
        extract_centerline(cases[0].mesh if cases else load_mesh(sorted(pathlib.Path(a.meshes).glob("*.ply"))[0]),
                           hubs=8, spokes=a.spokes)  # fmt: skip
    if a.only != "synthetic":
        files = sorted(pathlib.Path(a.meshes).glob("*.ply"))
        if not files:
            raise SystemExit(f"no .ply meshes in {a.meshes}")
        for f in files:
            voxels = f.name.startswith("EdinGCA")
            mesh = load_mesh(f, VOXEL_MM if voxels else 1.0)
            times = []
            for _ in range(max(1, a.repeat)):
                t0 = time.perf_counter()
                tube = extract_centerline(mesh, hubs=a.hubs, spokes=a.spokes, source=str(f))
                times.append(time.perf_counter() - t0)
            rows.append(row(f.name, mesh, tube, float(np.median(times)), 0.001 if voxels else 1.0))
    for case in cases:
        t0 = time.perf_counter()
        tube = extract_centerline(case.mesh, hubs=a.hubs, spokes=a.spokes, source=case.name)
        rows.append(row(case.name, case.mesh, tube, time.perf_counter() - t0, 1.0, case))
    result = {
        "device": "cpu",
        "cpu_count": os.cpu_count(),
        "machine": platform.processor() or platform.machine(),
        "rows": rows,
    }
    print(table(result) if a.table else json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
