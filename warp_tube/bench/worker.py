"""One code's share of one repetition of ``warp-tube bench``, in a process of its own.

``python -m warp_tube.bench.worker CODE --suite S --device D --rep R [--quick] --out FILE`` writes
one JSON object to FILE: ``code``, ``rep``, ``device``, ``versions``, ``compile_time`` [s] (the
warm-up run: first kernel compilation or cache load, Numba's JIT) and ``records`` (one dict per
measurement: ``kind`` "static" | "frequency" | "throughput", ``problem``, ``config`` and figures).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import traceback
from importlib import import_module

from . import plan

RUNNERS = {"warp_tube": "warp_tube.bench.warp_tube_runner", "pyelastica": "warp_tube.bench.peers.pyelastica_runner",
           "newton": "warp_tube.bench.peers.newton_runner"}  # fmt: skip
#: the throughput sweep stops growing a batch once one measurement took longer than this [s], or
#: when the next batch, at the same cost per tube, would take more than 3x as long.
THROUGHPUT_CAP_S = {False: 60.0, True: 10.0}


def runner(code: str):
    """The runner module of ``code``."""
    return import_module(RUNNERS[code])


def _device_for(code: str, device: str) -> str:
    return "cpu" if code == "pyelastica" else device


def run(code: str, suite: str, device: str, rep: int, quick: bool) -> dict:
    """Every measurement of ``code`` in ``suite`` ("accuracy", "speed" or "all") for repetition ``rep``."""
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    r = runner(code)
    dev = _device_for(code, device)
    t0 = time.perf_counter()
    r.warmup(dev)
    out = dict(code=code, rep=rep, device=dev, versions=r.versions(), compile_time=time.perf_counter() - t0, records=[])
    recs = out["records"]

    def record(kind, problem, config, fn):
        try:
            figures = fn()
        except Exception as e:  # noqa: BLE001 (a failed measurement is reported, the others go on)
            figures = {"failed": f"{type(e).__name__}: {e}"}
            traceback.print_exc(file=sys.stderr)
        recs.append(dict(kind=kind, problem=problem, config=config, **figures))
        print(json.dumps(recs[-1]), file=sys.stderr, flush=True)

    if suite in ("accuracy", "all"):
        for problem, config, once in plan.static_plan(code, quick):
            if once and rep > 0:
                continue
            record("static", problem.name, config, lambda: r.static(problem, config, dev, problem.static_duration))
        if rep == 0:
            for config in plan.frequency_plan(code, quick):
                record("frequency", plan.cantilever(0.0).name, config, lambda: r.frequency(plan.cantilever(0.0), config, dev))
    if suite in ("speed", "all"):
        configs, sizes = plan.speed_plan(code, quick)
        cap = THROUGHPUT_CAP_S[quick]
        for config in configs:
            for k, batch in enumerate(sizes):
                t = time.perf_counter()
                record("throughput", f"{config['segments']}-segment tubes", dict(config, batch=batch),
                       lambda: r.throughput(plan.cantilever(0.0), config, batch, dev))  # fmt: skip
                took = time.perf_counter() - t
                if k + 1 < len(sizes) and (took > cap or took * sizes[k + 1] / batch > 3 * cap):
                    print(f"throughput: {code} stops at {batch} tubes ({took:.1f} s for that batch)", file=sys.stderr)
                    break
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("code", choices=sorted(RUNNERS))
    ap.add_argument("--suite", default="all", choices=("accuracy", "speed", "all"))
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--rep", type=int, default=0)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    result = run(a.code, a.suite, a.device, a.rep, a.quick)
    with open(a.out, "w") as f:
        json.dump(result, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
