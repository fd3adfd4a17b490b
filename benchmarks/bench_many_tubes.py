"""``warp-tube run`` of one scene holding many tubes: where the time goes. Prints JSON.

    python benchmarks/bench_many_tubes.py [--tubes 4096] [--points 20] [--prims 1,64,4096]
                                          [--frames 31] [--device cpu|cuda:0] [--reps 5]

The scene: ``--tubes`` curved tubes (quarter-circle arcs 0.2 m long, radius 1 cm, 16 spokes, caps,
the paper's intestine material: 20 kPa, 1050 kg/m^3, mass damping 8 1/s), each clamped at its first
two points and sagging under gravity, laid out on a grid 0.3 m apart; held as curves of ``P``
tube prims (``--prims``, each a case: 1 prim holding every tube, ..., one prim per tube).

Reported per case, side by side in one run (seconds):

- ``setup_s``: ``Simulation(scene)`` (the model, solver, surface builders and checks);
- ``frame_s``: median of ``--reps`` ``Simulation.step()`` calls (the substeps and the frame's checks);
- ``surface_s``: median of ``--reps`` ``Simulation.surface()`` calls (rebuild and copy to the host:
  what writing a frame needs);
- ``run_s``: ``Simulation.run(frames, output)`` writing a ``.usdc`` (Centerline and Surface);
- ``tip_m``: the first tube's last point after the run [m] (the same physics in every case: the
  prims differ only in how the tubes are grouped).

The first case runs once untimed first so that compiling the kernels is not counted.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import tempfile
import time

import numpy as np

SPACING, LENGTH, RADIUS = 0.3, 0.2, 0.01


def make_scene(tubes: int, points: int, prims: int, frames: int):
    """``tubes`` clamped arcs as curves of ``prims`` tube prims (metres, Z up, 60 frames/s)."""
    from warp_tube.scene.spec import Scene, SimulationSettings, StageInfo, TubeParams, TubeSpec

    theta = np.linspace(0.0, 0.5 * np.pi, points)
    r = LENGTH / (0.5 * np.pi)
    arc = np.stack([r * np.sin(theta), np.zeros_like(theta), r * np.cos(theta)], axis=1)
    side = int(np.ceil(np.sqrt(tubes)))
    params = TubeParams(density=1050.0, youngs_modulus=2.0e4, damping=8.0, spokes=16, caps=True)
    per = np.full(prims, tubes // prims)
    per[: tubes % prims] += 1
    specs, k = [], 0
    for p, count in enumerate(per):
        idx = np.arange(k, k + count)
        k += count
        origin = np.stack([SPACING * (idx % side), SPACING * (idx // side), np.zeros(count)], axis=1)
        pts = (origin[:, None, :] + arc[None]).reshape(-1, 3)
        pinned = (np.arange(count)[:, None] * points + np.array([0, 1])[None]).reshape(-1)
        specs.append(TubeSpec(f"/World/Tubes_{p:05d}", pts, np.full(count, points), np.full(len(pts), RADIUS), params,
                              pinned=pinned))  # fmt: skip
    stage = StageInfo(meters_per_unit=1.0, up_axis="Z", time_codes_per_second=60.0, frames_per_second=60.0,
                      start_time_code=0.0, end_time_code=float(frames - 1))  # fmt: skip
    return Scene(tuple(specs), settings=SimulationSettings(gravity=(0.0, 0.0, -9.81)), stage=stage, source="<bench>")


def run_case(tubes: int, points: int, prims: int, frames: int, device: str, reps: int, folder: str) -> dict:
    from warp_tube import Simulation

    scene = make_scene(tubes, points, prims, frames)
    t0 = time.perf_counter()
    sim = Simulation(scene, device=device)
    setup = time.perf_counter() - t0
    step, surf = [], []
    for _ in range(reps):
        t = time.perf_counter()
        sim.step()
        step.append(time.perf_counter() - t)
        t = time.perf_counter()
        sim.surface()
        surf.append(time.perf_counter() - t)
    sim = Simulation(scene, device=device)
    out = os.path.join(folder, f"many_{prims}.usdc")
    t = time.perf_counter()
    sim.run(frames, output=out)
    run = time.perf_counter() - t
    tip = sim.centerline_points()[0][points - 1] * scene.stage.meters_per_unit
    os.remove(out)
    return dict(prims=prims, tubes=tubes, points=points, setup_s=setup, frame_s=statistics.median(step),
                surface_s=statistics.median(surf), run_s=run, frames=frames, tip_m=[float(x) for x in tip])  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tubes", type=int, default=4096)
    ap.add_argument("--points", type=int, default=20)
    ap.add_argument("--prims", default="1,64,4096", help="comma-separated prim counts, one case each")
    ap.add_argument("--frames", type=int, default=31)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--reps", type=int, default=5)
    a = ap.parse_args()
    import warp as wp

    wp.config.quiet = True
    prims = [int(p) for p in a.prims.split(",")]
    with tempfile.TemporaryDirectory() as folder:
        run_case(min(a.tubes, 16), a.points, 1, 3, a.device, 1, folder)  # compile the kernels
        cases = [run_case(a.tubes, a.points, p, a.frames, a.device, a.reps, folder) for p in prims]
    print(json.dumps({"benchmark": "many_tubes", "date": datetime.date.today().isoformat(), "device": a.device,
                      "device_name": wp.get_device(a.device).name, "machine": platform.node(), "cpus": os.cpu_count(),
                      "warp": wp.config.version, "cases": cases}, indent=1))  # fmt: skip


if __name__ == "__main__":
    main()
