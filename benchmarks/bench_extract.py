"""Centerline extraction on the real meshes of ../shared/data/meshes and on the synthetic tubes:
time, centring and fidelity of the rest surface the simulator writes.

Per case: the hub count (automatic unless ``--hubs``), seconds of extraction (median of
``--repeat`` runs, kernel compile excluded: one warm-up extraction runs first), and the frame-0
Surface of the scene that ``warp-tube extract`` writes, built through the public API
(``warp_tube.load_scene`` then ``warp_tube.Simulation(scene, device="cpu").surface_points()``,
:func:`warp_tube.bench.extraction.simulated_surface`):

- distances from the input's vertices to that Surface (side branches and one end radius at each
  end left out) and from the Surface's vertices to the input (nothing left out): mean, 99th
  percentile and largest, as fractions of the mean spoke length;
- the longest over the shortest spoke of the two end rings (and of the rings one hub in: the mesh's
  own section there), and how far the inner-bend guard moved a vertex (against the same surface
  rebuilt with the guard off);
- synthetic tubes: the distance of every interior hub from the true curve, over the local true radius.

Prints JSON; ``--table`` prints a Markdown table instead (``--from FILE`` prints the table of a saved
result). ``--centres`` compares, on the synthetic set, the two centres the extraction could use:
the cross-section's centroid and the maximal inscribed circle (the distance field's ridge).

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
import time

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only: no banner, no module messages

from warp_tube.bench.extraction import simulated_surface
from warp_tube.bench.synthetic_tubes import synthetic_cases
from warp_tube.extract.fidelity import surface_fidelity
from warp_tube.extract.mesh_io import load_mesh
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.polyline import arclength, project_points

VOXEL_MM = (0.832031, 0.832031, 1.0)  # EdinGCA CT voxel size (SOURCES.md): mesh units -> mm
DEFAULT_DIR = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "data" / "meshes"


def measure(tube, mesh, meters_per_unit: float) -> dict:
    """Two-way distances, end-ring spoke ratios and guard moves of the frame-0 Surface (see module doc)."""
    fid = surface_fidelity(tube, mesh, surface=simulated_surface(tube, meters_per_unit))
    lengths = tube.spoke_lengths
    inner = lengths[[1, -2]] if tube.hubs > 3 else lengths[[0, -1]]
    return {
        "to_surface": {k: round(getattr(fid.to_surface, k), 4) for k in ("mean", "p99", "max")},
        "to_input": {k: round(getattr(fid.to_input, k), 4) for k in ("mean", "p99", "max")},
        "vertices_left_out": fid.to_surface.left_out,
        "end_ratios": [round(x, 2) for x in fid.end_ratios],
        # the mesh's own cross-section next to each end: the ratio of the ring one hub in
        "mesh_end_ratios": [round(float(r.max() / r.min()), 2) for r in inner],
        "guard_moved": round(fid.guard_moved, 4),
    }


def centring(tube, case) -> dict:
    """Distances of the interior hubs from the true curve over the local true radius."""
    d, arc = project_points(tube.points[1:-1], case.curve)
    local = np.interp(arc, arclength(case.curve), case.radius)
    e = d / local
    return {"hub_error_max": round(float(e.max()), 4), "hub_error_mean": round(float(e.mean()), 4)}


def centres(case, samples: int = 40) -> dict:
    """Centre of the cross-section normal to the true curve, at ``samples`` points of it (a tenth of
    the length from each end left out), found two ways from a start a fifth of the radius off: the
    section's centroid (rays, :func:`warp_tube.extract.sections.section_offsets`, 8 iterations) and
    the maximal inscribed circle (the distance field's ridge in the plane: the point of largest
    distance from the wall, by a shrinking 9 x 9 grid search); distance of each from the curve over
    the radius there."""
    from warp_tube.extract.polyline import tangents
    from warp_tube.extract.queries import MeshQueries
    from warp_tube.extract.sections import plane_basis, section_offsets

    v = np.asarray(case.mesh.vertices)
    shift = 0.5 * (v.min(axis=0) + v.max(axis=0))
    q = MeshQueries(v - shift, case.mesh.faces, v - shift, case.mesh.faces, "cpu")
    diag = float(np.linalg.norm(np.ptp(v, axis=0)))
    k = len(case.curve)
    idx = np.linspace(k // 10, k - 1 - k // 10, samples).astype(int)
    x, t, r = case.curve[idx] - shift, tangents(case.curve)[idx], case.radius[idx]
    a, b = plane_basis(t)
    start = x + 0.2 * r[:, None] * a
    p = start.copy()
    for _ in range(8):
        p = p + section_offsets(q, p, t, diag)[0]
    centroid = np.linalg.norm(p - x, axis=1) / r
    p, step = start.copy(), 0.3
    grid = np.array([(u, w) for u in np.linspace(-1, 1, 9) for w in np.linspace(-1, 1, 9)])
    for _ in range(6):
        cand = p[:, None] + step * r[:, None, None] * (grid[None, :, :1] * a[:, None] + grid[None, :, 1:] * b[:, None])
        d = q.distance(cand.reshape(-1, 3), diag).reshape(len(p), -1)
        p = cand[np.arange(len(p)), d.argmax(axis=1)]
        step /= 3.0
    ridge = np.linalg.norm(p - x, axis=1) / r
    return {"mesh": case.name, "centroid_max": round(float(centroid.max()), 4), "centroid_mean": round(float(centroid.mean()), 4),
            "ridge_max": round(float(ridge.max()), 4), "ridge_mean": round(float(ridge.mean()), 4)}  # fmt: skip


def row(name, mesh, tube, seconds, meters_per_unit, case=None, times=None) -> dict:
    out = {
        "mesh": name,
        "vertices": int(len(mesh.vertices)),
        "hubs": tube.hubs,
        "seconds": round(seconds, 3),
        "seconds_each": [round(x, 3) for x in (times or [seconds])],
        "length": float(f"{tube.length:.4g}"),
        "mean_radius": float(f"{tube.spoke_lengths.mean():.4g}"),
        "ends": [e.kind for e in tube.ends],
        "branches": [[j, float(f"{x:.4g}")] for j, x in tube.branches],
        "openings": [[o.kind, float(f"{o.radius:.4g}")] for o in tube.openings],
        "stages": {k: round(v, 3) for k, v in tube.timings.items()},
        **measure(tube, mesh, meters_per_unit),
    }
    if case is not None:
        out.update(centring(tube, case))
    return out


def table(result: dict) -> str:
    """Markdown table of the rows."""
    head = ("| mesh | hubs | s | mesh to surface: mean / p99 / max % | surface to mesh: mean / p99 / max % | "
            "end ring ratios | guard moved | hub error max / mean |")  # fmt: skip
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
    ap.add_argument("--from", dest="saved", help="print the table of a saved JSON result and stop")
    ap.add_argument("--centres", action="store_true", help="compare section centroids and inscribed circles")
    a = ap.parse_args()
    if a.saved:
        print(table(json.loads(pathlib.Path(a.saved).read_text())))
        return
    if a.centres:
        with contextlib.redirect_stdout(sys.stderr):
            wp.init()
        print(json.dumps([centres(c) for c in synthetic_cases()], indent=1))
        return
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
            rows.append(row(f.name, mesh, tube, float(np.median(times)), 0.001 if voxels else 1.0, times=times))
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
