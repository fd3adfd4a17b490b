"""Surface rebuild speed (SurfaceBuilder.compute), by kernel path. Prints JSON.

A rebuild runs as one launch of the world kernel (a thread per world; the CPU's default) or of the
block kernel (a warp per world; the GPU's default); see :mod:`warp_tube.surface.builder`.

- CPU, one tube: 20 hubs x 9 spokes; median wall time of one rebuild over many calls after a
  warm-up (each call replays a captured graph).
- CPU, batch: 256 tubes (worlds) x 32 hubs x 32 spokes (262,144 vertices), median of a few
  rebuilds.
- CUDA (when a device exists): 65,536 tubes (worlds) x 32 hubs x 32 spokes (67,108,864 vertices),
  circular (one spoke length per hub) and measured (lengths varying around each ring), each
  captured in a CUDA graph and timed with CUDA events over many replays: the whole rebuild by the
  block kernel, and a reference kernel that only stores a point and a normal per vertex.
  Reported as surface vertices per second against the bound that the memory bandwidth sets for
  the 24 bytes a rebuild must write per vertex (points + normals, float32 vec3 each):
  ``bandwidth / 24 B``. The bandwidth is ``--bandwidth-gbs`` (default 2988 GB/s, an H100's
  measured by ``benchmarks/bandwidth.py``: a device-to-device copy) or the ``bandwidth_gbs`` of
  that script's JSON output given by ``--bandwidth-json``. Reads (hub positions, frames, per-hub
  data) are per hub and shared by the S spokes of a ring, so writes dominate the traffic.

Usage: python benchmarks/bench_surface.py [--bandwidth-gbs GBS | --bandwidth-json PATH] [--repeats N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only: no banner, no module messages

from warp_tube.surface.builder import SurfaceBuilder  # noqa: E402


def helix(n: int, world_count: int = 1) -> np.ndarray:
    u = np.linspace(0.0, 2.0 * np.pi, n)
    x = np.stack([np.cos(u), np.sin(u), 0.3 * u], 1) * 0.05
    return np.broadcast_to(x, (world_count, n, 3))


H100_MEASURED_GBS = 2988.0
"""Device-to-device copy bandwidth of an H100 measured with benchmarks/bandwidth.py (2026-11-22)."""


def straight_rest(n: int) -> np.ndarray:
    rest = np.zeros((n, 3))
    rest[:, 2] = np.linspace(0.0, 0.3 * 2 * np.pi * 0.05, n)
    return rest


def _median_s(fn, calls: int) -> float:
    samples = []
    for _ in range(calls):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def bench_cpu(repeats: int) -> dict:
    n, S = 20, 9
    q = wp.array(helix(n).astype(np.float32), dtype=wp.vec3, device="cpu")
    b = SurfaceBuilder([0, n], straight_rest(n), S, np.full(n, 0.01), device="cpu", kernel="world")
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
        "rebuild_world_median_us": 1e6 * statistics.median(samples),
        "rebuild_world_p10_us": 1e6 * float(np.percentile(samples, 10)),
        "rebuild_world_p90_us": 1e6 * float(np.percentile(samples, 90)),
        "calls": repeats,
        "method": "median of per-call perf_counter times of SurfaceBuilder.compute (replayed graphs)",
    }


def bench_cpu_batch(repeats: int) -> dict:
    W, n, S = 256, 32, 32
    q = wp.array(np.ascontiguousarray(helix(n, W)).astype(np.float32), dtype=wp.vec3, device="cpu")
    b = SurfaceBuilder([0, n], straight_rest(n), S, np.full(n, 0.01), world_count=W, device="cpu", kernel="world")
    for _ in range(2):
        b.compute(q)
    t = _median_s(lambda: b.compute(q), repeats)
    vertices = W * n * S
    return {
        "device": "cpu",
        "tubes": W,
        "hubs": n,
        "spokes": S,
        "vertices": vertices,
        "rebuild_world_median_ms": 1e3 * t,
        "ns_per_vertex_rebuild_world": 1e9 * t / vertices,
        "vertices_per_s_rebuild_world": vertices / t,
        "calls": repeats,
        "method": "median of per-call perf_counter times; Warp's CPU backend runs one thread",
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


@wp.kernel(enable_backward=False)
def write_reference_kernel(points: wp.array2d[wp.vec3], normals: wp.array2d[wp.vec3]):
    """The stores a rebuild must make and nothing else: a point and a normal per vertex, one
    thread per (world, vertex) (what the hardware gives for this output, next to the bound)."""
    w, v = wp.tid()
    x = float(v)
    points[w, v] = wp.vec3(x, x + 1.0, x + 2.0)
    normals[w, v] = wp.vec3(x + 3.0, x + 4.0, x + 5.0)


def bench_cuda(bandwidth_gbs: float, bandwidth_source: str, replays: int) -> dict:
    device = wp.get_device("cuda:0")
    W, n, S = 65536, 32, 32
    vertices = W * n * S
    bound = bandwidth_gbs * 1e9 / 24.0
    q = wp.array(np.ascontiguousarray(helix(n, W)).astype(np.float32), dtype=wp.vec3, device=device)
    out = {
        "device": device.name,
        "tubes": W,
        "hubs": n,
        "spokes": S,
        "vertices": vertices,
        "bytes_written_per_vertex": 24,
        "bandwidth_gbs": bandwidth_gbs,
        "bandwidth_source": bandwidth_source,
        "bandwidth_bound_vertices_per_s": bound,
    }
    measured = 0.01 * (1.0 + 0.2 * np.random.default_rng(0).random((n, S)))  # a measured shape
    for case, lengths in (("block", np.full(n, 0.01)), ("block_measured", measured)):
        b = SurfaceBuilder([0, n], straight_rest(n), S, lengths, world_count=W, device=device, kernel="block")
        b.compute(q)  # compile, record
        b.compute(q)  # capture (warp_tube.runtime.replay)
        t_all = _time_graph(b._graphs._graphs[(q.ptr, q.shape, q.strides)][1], device, replays)
        out[f"{case}_rebuild_s"] = t_all
        out[f"{case}_vertices_per_s_rebuild"] = vertices / t_all
        out[f"{case}_rebuild_fraction_of_bound"] = (vertices / t_all) / bound
        out[f"{case}_achieved_write_gbs"] = vertices * 24 / t_all / 1e9
        del b
    p = wp.empty((W, n * S), dtype=wp.vec3, device=device)
    nrm = wp.empty((W, n * S), dtype=wp.vec3, device=device)
    wp.launch(write_reference_kernel, (W, n * S), outputs=[p, nrm], device=device)
    with wp.ScopedCapture(device) as cap:
        wp.launch(write_reference_kernel, (W, n * S), outputs=[p, nrm], device=device)
    t_ref = _time_graph(cap.graph, device, replays)
    out["write_reference_s"] = t_ref
    out["write_reference_fraction_of_bound"] = (vertices / t_ref) / bound
    out["replays"] = replays
    out["method"] = "CUDA graph replays timed with CUDA events, mean per replay, all in one run"
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    bandwidth = parser.add_mutually_exclusive_group()
    bandwidth.add_argument(
        "--bandwidth-gbs", type=float, default=H100_MEASURED_GBS,
        help=f"device memory bandwidth [GB/s] (default {H100_MEASURED_GBS:g}, an H100's, measured)",
    )  # fmt: skip
    bandwidth.add_argument("--bandwidth-json", help="JSON output of benchmarks/bandwidth.py for this device")
    parser.add_argument("--repeats", type=int, default=2000, help="CPU calls timed (one tube)")
    parser.add_argument("--batch-repeats", type=int, default=10, help="CPU calls timed (batch)")
    parser.add_argument("--replays", type=int, default=50, help="CUDA graph replays timed")
    args = parser.parse_args()
    if args.bandwidth_json:
        with open(args.bandwidth_json) as f:
            bandwidth_gbs = float(json.load(f)["bandwidth_gbs"])
        bandwidth_source = args.bandwidth_json
    else:
        bandwidth_gbs = args.bandwidth_gbs
        bandwidth_source = "--bandwidth-gbs"
    wp.init()
    results = {
        "warp": wp.__version__,
        "cpu": bench_cpu(args.repeats),
        "cpu_batch": bench_cpu_batch(args.batch_repeats),
    }
    if wp.get_cuda_device_count() > 0:
        results["cuda"] = bench_cuda(bandwidth_gbs, bandwidth_source, args.replays)
    else:
        results["cuda"] = "skipped: no CUDA device"
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
