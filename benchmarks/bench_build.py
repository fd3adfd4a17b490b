"""Build speed of many tubes and of one long tube on the CPU. Prints JSON.

    python benchmarks/bench_build.py [--reps 3] [--tubes 16384] [--points 20] [--long 1000000]

Two cases, each a curved rest shape (a helix-like curve, so every rest curvature is non-zero):

- ``many``: ``--tubes`` tubes of ``--points`` points each (16 spokes, caps);
- ``long``: one tube of ``--long`` points (16 spokes, caps).

Timed, medians of ``--reps`` repetitions (seconds), measured side by side in one run:

- ``rest_curvature_s``: :func:`warp_tube.model.tube.rest_curvature_coordinates` of every tube, in
  one call for tubes of equal length (how a batch calls it);
- ``build_model_s``: :func:`warp_tube.model.tube.build_model` of a scene holding the tubes (one
  prim per tube for ``many``), CPU device, arrays included;
- ``build_topology_s``: :func:`warp_tube.surface.topology.build_topology` of all the tubes as one
  prim (what ``SurfaceBuilder`` builds for a prim holding them);
- ``rest_frames_s``: :func:`warp_tube.surface.builder.rest_frames`, the rest tangents and
  normals of every hub that ``SurfaceBuilder`` computes (tubes of one length at once);
- ``build_topology_one_tube_s`` (``many`` only): the topology of one tube, which a batch of
  variants shares across its worlds.

``build_model_s`` includes ``build_model``'s own loop over curves (a few dozen NumPy calls per
curve for masses, stiffnesses and damping), which ``build_model_without_rest_curvature_s``
isolates (``build_model_s`` minus ``rest_curvature_s``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import statistics
import time

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only

from warp_tube.model.tube import build_model, rest_curvature_coordinates
from warp_tube.scene.spec import Scene, StageInfo, TubeParams, TubeSpec
from warp_tube.surface.builder import rest_frames
from warp_tube.surface.topology import build_topology


def curved(points: int, length: float, phase: float = 0.0) -> np.ndarray:
    """A helix-like centerline [m], (points, 3): every interior point has a rest curvature."""
    s = np.linspace(0.0, length, points)
    return np.stack([s, 0.05 * length * np.sin(6.0 * s / length + phase), 0.05 * length * np.cos(4.0 * s / length + phase)], 1)


def median_time(fn, reps: int) -> float:
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--tubes", type=int, default=16384)
    ap.add_argument("--points", type=int, default=20)
    ap.add_argument("--long", type=int, default=1_000_000)
    a = ap.parse_args()
    wp.init()
    params = TubeParams(density=1050.0, youngs_modulus=1e5, damping=2.0, spokes=16, caps=True)
    out = {"benchmark": "build", "date": datetime.date.today().isoformat(), "machine": platform.processor() or platform.machine(),
           "reps": a.reps, "cases": []}  # fmt: skip

    # many short tubes
    T, n = a.tubes, a.points
    pts = np.stack([curved(n, 0.2, 0.001 * k) for k in range(T)])
    tubes = tuple(TubeSpec(f"/V{k}/Tube", pts[k], [n], np.full(n, 0.01), params, pinned=[0, 1]) for k in range(T))
    scene = Scene(tubes, stage=StageInfo(meters_per_unit=1.0))
    starts = np.arange(T + 1) * n
    flat = pts.reshape(-1, 3)
    cap = np.full((T, 2), 0.01)
    case = {"case": "many", "tubes": T, "points": n, "spokes": 16}
    case["rest_curvature_s"] = median_time(lambda: rest_curvature_coordinates(pts), a.reps)
    case["build_model_s"] = median_time(lambda: build_model(scene, device="cpu"), a.reps)
    case["build_model_without_rest_curvature_s"] = case["build_model_s"] - case["rest_curvature_s"]
    case["build_topology_s"] = median_time(lambda: build_topology(starts, 16, caps=True, rest_q=flat, cap_radius=cap), a.reps)
    case["rest_frames_s"] = median_time(lambda: rest_frames(flat, starts), a.reps)
    case["build_topology_one_tube_s"] = median_time(lambda: build_topology(starts[:2], 16, caps=True, rest_q=pts[0], cap_radius=cap[:1]), a.reps)
    out["cases"].append(case)

    # one long tube
    N = a.long
    x = curved(N, 100.0)
    tube = TubeSpec("/World/Tube", x, [N], np.full(N, 0.01), params, pinned=[0, 1])
    scene = Scene((tube,), stage=StageInfo(meters_per_unit=1.0))
    case = {"case": "long", "tubes": 1, "points": N, "spokes": 16}
    case["rest_curvature_s"] = median_time(lambda: rest_curvature_coordinates(x), a.reps)
    case["build_model_s"] = median_time(lambda: build_model(scene, device="cpu"), a.reps)
    case["build_topology_s"] = median_time(lambda: build_topology(np.array([0, N]), 16, caps=True, rest_q=x, cap_radius=np.full((1, 2), 0.01)), a.reps)
    case["rest_frames_s"] = median_time(lambda: rest_frames(x, np.array([0, N])), a.reps)
    case["model_and_topology_s"] = case["build_model_s"] + case["build_topology_s"]
    case["model_topology_and_rest_frames_s"] = case["model_and_topology_s"] + case["rest_frames_s"]
    out["cases"].append(case)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
