"""One 60 fps output frame of the paper's tube on the CPU: substeps plus one surface rebuild. Prints JSON.

    python benchmarks/bench_frame.py [--reps 3000] [--device cpu]

The tube has the paper's size: 20 hubs x 9 spokes (342 triangles) with caps off, the material of
``scenes/intestine.usda`` (Young's modulus 20 kPa, density 1050 kg/m^3, radius 1.5 cm, mass damping
8 1/s) on a 0.4 m centerline with its first two points pinned. Two cases:

- ``minimal``: straight at rest, structural and bending springs and damping only (the paper's
  centerline without its assistant line);
- ``intestine``: curved at rest, gravity, two anchors, a sideways push with its assistant line
  (every feature of ``scenes/intestine.usda``).

``Simulation`` picks the integrator and substeps as a run would (``auto``: semi-implicit Euler at
half the stability bound).

Timed, medians of ``--reps`` calls after a warm-up, side by side in one run:

- ``substeps_us``: the solver's frame (all substeps: one launch on the CPU, replayed from its
  captured graph, :mod:`warp_tube.runtime.replay`);
- ``surface_us``: one surface rebuild (``SurfaceBuilder.compute``, replayed the same way);
- ``frame_us``: both, back to back, as the issue's "one 60 fps frame" counts it;
- ``simulation_step_us``: ``Simulation.step`` (the frame plus its host-side checks: finite,
  runaway, energy against work), and ``simulation_step_surface_us`` with the surface rebuild after
  it, what ``warp-tube run`` does per frame before writing.

The error of this discretisation is reported by ``bench_centerline.py`` (cantilever statics and
frequency at 20 segments) and the surface tests (exact geometry to float32 round-off).
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

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only: no banner, no module messages

from warp_tube.scene.spec import ForceSpec, Scene, SimulationSettings, StageInfo, TubeParams, TubeSpec
from warp_tube import Simulation

HUBS, SPOKES, RADIUS, LENGTH = 20, 9, 0.015, 0.4


def paper_scene(features: bool, fps: float = 60.0) -> Scene:
    s = np.linspace(0.0, LENGTH, HUBS)
    pts = np.stack([s, 0.03 * np.sin(2 * np.pi * s / LENGTH) if features else 0 * s, 0 * s], axis=1)
    params = TubeParams(density=1050.0, youngs_modulus=2.0e4, damping=8.0, anchor_stiffness=60.0 if features else 0.0,
                        spokes=SPOKES)  # fmt: skip
    tube = TubeSpec("/World/Bowel", pts, [HUBS], np.full(HUBS, RADIUS), params, pinned=[0, 1],
                    anchors=[9, 19] if features else [])  # fmt: skip
    stage = StageInfo(meters_per_unit=1.0, time_codes_per_second=fps, frames_per_second=fps, end_time_code=fps)
    if not features:
        return Scene((tube,), stage=stage)
    push = ForceSpec("/World/Push", 0, 14, [0.0], [[0.0, 0.0, 0.05]], assistant_line=True)
    return Scene((tube,), (push,), settings=SimulationSettings(gravity=(0.0, -9.81, 0.0)), stage=stage)


def median_us(fn, reps: int) -> float:
    samples = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return 1e6 * statistics.median(samples)


def case(features: bool, device: str, reps: int) -> dict:
    sim = Simulation(paper_scene(features), device=device, surface=True)
    for _ in range(10):  # compile, build the assistant line, settle the caches
        sim.step()
    builder = sim.surfaces[0]
    s0, s1, c = sim.state, sim.next_state, sim.control
    n = sim.substeps
    sync = (lambda: wp.synchronize_device(device))

    def substeps():
        sim.solver.integrate(s0, s1, c, sim.dt, n)
        sync()

    def surface():
        builder.compute(s1.node_q)
        sync()

    def frame():
        sim.solver.integrate(s0, s1, c, sim.dt, n)
        builder.compute(s1.node_q)
        sync()

    def step_surface():
        sim.step()
        sim.surfaces[0].compute(sim.state.node_q)
        sync()

    for fn in (substeps, surface, frame):
        fn()
    res = {
        "hubs": HUBS,
        "spokes": SPOKES,
        "triangles": len(builder.face_vertex_counts),
        "integrator": sim.integrator,
        "substeps_per_frame": n,
        "dt_s": sim.dt,
        "substeps_us": median_us(substeps, reps),
        "surface_us": median_us(surface, reps),
        "frame_us": median_us(frame, reps),
        "simulation_step_us": median_us(lambda: (sim.step(), sync()), reps),
        "simulation_step_surface_us": median_us(step_surface, reps),
    }
    res["substep_us"] = res["substeps_us"] / n
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=3000)
    ap.add_argument("--device", default="cpu")
    a = ap.parse_args()
    wp.init()
    res = {
        "benchmark": "frame_60fps_paper_tube",
        "date": datetime.date.today().isoformat(),
        "device": a.device,
        "cpu": platform.processor() or platform.machine(),
        "warp": wp.config.version,
        "target_frame_us": 20.0,
        "method": "median of per-call perf_counter times after a warm-up, all cases in one run",
        "minimal": case(False, a.device, a.reps),
        "intestine": case(True, a.device, a.reps),
    }
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
