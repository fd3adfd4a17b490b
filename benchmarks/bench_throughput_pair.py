"""Throughput of warp_tube and Newton at equal error, at chosen batch sizes. Prints JSON.

    python benchmarks/bench_throughput_pair.py --device cuda:0 --batches 8192 16384

The same measurement as ``warp-tube bench --suite speed`` (each code's configuration that reaches
0.2% of L at 20 segments: :func:`warp_tube.bench.plan.speed_plan`; 20-segment cantilevers, one
world each, unloaded and damped; :func:`~warp_tube.bench.warp_tube_runner.throughput` and the
Newton runner's), but at the batch sizes given, with no time cap: the sweep of ``warp-tube bench``
stops growing a batch once the next would take more than three minutes, which on Newton's side
(its set-up of a batch grows with the batch) ends the GPU sweep near 512 tubes. Each code is
compiled first (its warm-up), then the batches run in order: warp_tube (``Simulation`` and solver
API), then Newton. ``ratio_*``: warp_tube's simulated tube-seconds per second over Newton's, same
batch. Needs Newton installed (``benchmarks/gpu_bench.sh`` says how, offline).
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time

import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only

from warp_tube.bench import plan, warp_tube_runner


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--batches", type=int, nargs="+", default=[8192])
    a = ap.parse_args()
    from warp_tube.bench.peers import newton_runner

    wp.init()
    res = {"benchmark": "throughput_pair", "date": datetime.date.today().isoformat(), "device": a.device,
           "device_name": wp.get_device(a.device).name, "warp": wp.config.version, "rows": []}  # fmt: skip
    codes = (("warp_tube", warp_tube_runner), ("newton", newton_runner))
    for code, mod in codes:
        t = time.perf_counter()
        mod.warmup(a.device)
        res[f"{code}_warmup_s"] = time.perf_counter() - t
        configs, _ = plan.speed_plan(code, quick=False)
        for config in configs:
            for batch in a.batches:
                t = time.perf_counter()
                row = dict(code=code, config=config, batch=batch, **mod.throughput(plan.cantilever(0.0), config, batch, a.device))
                row["wall_s"] = time.perf_counter() - t
                res["rows"].append(row)
                print(json.dumps(row), file=sys.stderr, flush=True)
    newton = {r["batch"]: r["rod_seconds_per_s"] for r in res["rows"] if r["code"] == "newton"}
    for r in res["rows"]:
        if r["code"] == "warp_tube":
            res[f"ratio_{r['config'].get('api', 'simulation')}_{r['batch']}"] = r["rod_seconds_per_s"] / newton[r["batch"]]
    print(json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
