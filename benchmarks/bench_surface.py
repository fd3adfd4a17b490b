"""Surface rebuild speed: frames + per-spoke kernel (SurfaceBuilder.compute). Prints JSON.

- CPU: one tube of 20 hubs x 9 spokes; median wall time of one rebuild over many calls after a
  warm-up, each call replaying recorded launches (``wp.launch(record_cmd=True)``, no argument
  packing per call).
- CUDA (when a device exists): 65,536 tubes (worlds) x 32 hubs x 32 spokes, rebuild captured in a
  CUDA graph and timed with CUDA events over many replays. Reported: surface vertices per second,
  and the memory-bandwidth bound for the 24 bytes the spoke kernel must write per vertex (points +
  normals, float32 vec3 each): ``bandwidth / 24 B``, with the bandwidth from ``--bandwidth-gbs``
  (default by device name: 3350 GB/s for H100 SXM, 4800 for H200; the vendors' datasheet peak
  HBM3/HBM3e figures, not measured here). Reads (hub positions, frames, lengths) are per hub and
  shared by the S spokes of a ring, so writes dominate the traffic.

Usage: python benchmarks/bench_surface.py [--bandwidth-gbs GBS] [--repeats N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
import warp as wp

from warp_tube.surface import SurfaceBuilder


def helix(n: int, world_count: int = 1) -> np.ndarray:
    u = np.linspace(0.0, 2.0 * np.pi, n)
    x = np.stack([np.cos(u), np.sin(u), 0.3 * u], 1) * 0.05
    return np.broadcast_to(x, (world_count, n, 3))


def bench_cpu(repeats: int) -> dict:
    n, S = 20, 9
    rest = np.zeros((n, 3))
    rest[:, 2] = np.linspace(0.0, 0.3 * 2 * np.pi * 0.05, n)
    b = SurfaceBuilder([0, n], rest, S, np.full(n, 0.01), device="cpu")
    q = wp.array(helix(n).astype(np.float32), dtype=wp.vec3, device="cpu")
    for _ in range(50):
        b.compute(q)
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        b.compute(q)
        samples.append(time.perf_counter() - t0)
    return {
        "device": "cpu",
        "tubes": 1,
        "hubs": n,
        "spokes": S,
        "vertices": b.vertex_count,
        "rebuild_median_us": 1e6 * statistics.median(samples),
        "rebuild_p10_us": 1e6 * float(np.percentile(samples, 10)),
        "rebuild_p90_us": 1e6 * float(np.percentile(samples, 90)),
        "calls": repeats,
        "method": "median of per-call perf_counter times of SurfaceBuilder.compute (2 recorded launches)",
    }


def _time_graph(graph, device, replays: int) -> float:
    start = wp.Event(device, enable_timing=True)
    end = wp.Event(device, enable_timing=True)
    for _ in range(3):
        wp.capture_launch(graph)
    wp.record_event(start)
    for _ in range(replays):
        wp.capture_launch(graph)
    wp.record_event(end)
    wp.synchronize_device(device)
    return wp.get_event_elapsed_time(start, end) / 1e3 / replays  # seconds per replay


def bench_cuda(bandwidth_gbs: float | None, replays: int) -> dict:
    device = wp.get_device("cuda:0")
    W, n, S = 65536, 32, 32
    rest = np.zeros((n, 3))
    rest[:, 2] = np.linspace(0.0, 0.3 * 2 * np.pi * 0.05, n)
    b = SurfaceBuilder([0, n], rest, S, np.full(n, 0.01), world_count=W, device=device)
    q = wp.array(np.ascontiguousarray(helix(n, W)).astype(np.float32), dtype=wp.vec3, device=device)
    b.compute(q)  # compile, record
    frames_launch, spokes_launch = b._launches[(q.ptr, q.shape, q.strides)]
    with wp.ScopedCapture(device) as cap_all:
        b.compute(q)
    with wp.ScopedCapture(device) as cap_spokes:
        spokes_launch.launch()
    t_all = _time_graph(cap_all.graph, device, replays)
    t_spokes = _time_graph(cap_spokes.graph, device, replays)
    vertices = W * n * S
    name = device.name
    if bandwidth_gbs is None:
        bandwidth_gbs = 4800.0 if "H200" in name else 3350.0
    bound = bandwidth_gbs * 1e9 / 24.0
    return {
        "device": name,
        "tubes": W,
        "hubs": n,
        "spokes": S,
        "vertices": vertices,
        "rebuild_s": t_all,
        "spoke_kernel_s": t_spokes,
        "frames_kernel_s": t_all - t_spokes,
        "vertices_per_s_rebuild": vertices / t_all,
        "vertices_per_s_spoke_kernel": vertices / t_spokes,
        "bytes_written_per_vertex": 24,
        "bandwidth_gbs_assumed": bandwidth_gbs,
        "bandwidth_bound_vertices_per_s": bound,
        "spoke_kernel_fraction_of_bound": (vertices / t_spokes) / bound,
        "achieved_write_gbs_spoke_kernel": vertices * 24 / t_spokes / 1e9,
        "replays": replays,
        "method": "CUDA graph replays timed with CUDA events, mean per replay",
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bandwidth-gbs", type=float, default=None, help="device memory bandwidth [GB/s]")
    parser.add_argument("--repeats", type=int, default=2000, help="CPU calls timed")
    parser.add_argument("--replays", type=int, default=50, help="CUDA graph replays timed")
    args = parser.parse_args()
    wp.config.quiet = True
    wp.init()
    results = {"warp": wp.__version__, "cpu": bench_cpu(args.repeats)}
    if wp.get_cuda_device_count() > 0:
        results["cuda"] = bench_cuda(args.bandwidth_gbs, args.replays)
    else:
        results["cuda"] = "skipped: no CUDA device"
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
