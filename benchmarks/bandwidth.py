"""Device memory bandwidth measured with a device-to-device copy. Prints JSON.

    python benchmarks/bandwidth.py [--device cuda:0] [--gib 2]

A copy reads and writes every byte once: bandwidth = 2 x bytes / time (median of 20 copies,
timed with CUDA events after a warm-up). This is the bound the surface benchmark compares with.
"""

import argparse
import json

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only: no banner, no module messages


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--gib", type=float, default=2.0)
    a = ap.parse_args()
    dev = wp.get_device(a.device)
    n = int(a.gib * 2**30 / 4)
    src = wp.zeros(n, dtype=wp.float32, device=dev)
    dst = wp.zeros(n, dtype=wp.float32, device=dev)
    wp.copy(dst, src)
    times = []
    for _ in range(20):
        start, end = wp.Event(dev, enable_timing=True), wp.Event(dev, enable_timing=True)
        wp.record_event(start)
        wp.copy(dst, src)
        wp.record_event(end)
        wp.synchronize_device(dev)
        times.append(wp.get_event_elapsed_time(start, end) / 1e3)
    t = float(np.median(times))
    print(json.dumps({"device": dev.name, "bytes_copied": 4 * n, "median_s": t, "bandwidth_gbs": 2 * 4 * n / t / 1e9}))


if __name__ == "__main__":
    main()
