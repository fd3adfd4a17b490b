"""A long CPU run of the default scene with subnormals flushed to zero (as warp_tube runs) and with
IEEE subnormals kept (the mode left alone), alternated in fresh processes.

Per mode and repetition, one process measures:

- ``run_s``: ``warp-tube run scenes/default.usda --frames N --no-surface -o <tmp>.usdc`` in
  process (``warp_tube.cli.main``), wall time [s] including start-up and writing;
- ``per_1000_s``: ``Simulation(load_scene("scenes/default.usda"), device="cpu", surface=False)``
  stepped N frames, the time of each block of 1,000 frames [s]; the last block is the tube at rest
  (``steady_per_1000_s``);
- ``subnormals``: how many float32 components of the state (``node_q``, ``node_q_lo``,
  ``node_qd``) are subnormal after the N frames.

Prints JSON: medians over ``--repeat`` runs per mode and the ratios. About 80 s with the defaults
on two cores. Usage: ``.venv/bin/python benchmarks/bench_long_run.py [--frames 4000] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "scenes" / "default.usda")
BLOCK = 1000
MODES = ("flush", "ieee")


def child(mode: str, frames: int) -> dict:
    """One process's measurements in one mode (see the module docstring)."""
    import numpy as np

    import warp_tube
    from warp_tube.cli import main as cli_main
    from warp_tube.runtime import float_mode

    if mode == "ieee":  # before anything starts Warp: this thread keeps IEEE subnormals
        float_mode.flush_subnormals_on_this_thread = lambda: False

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            status = cli_main(["run", SCENE, "--frames", str(frames), "--no-surface", "-o", os.path.join(tmp, "x.usdc")])
        run_s = time.perf_counter() - t0
    if status != 0:
        raise RuntimeError(f"warp-tube run exited with {status}")

    sim = warp_tube.Simulation(warp_tube.load_scene(SCENE), device="cpu", surface=False)
    blocks = []
    done = 0
    while done < frames:
        n = min(BLOCK, frames - done)
        t0 = time.perf_counter()
        for _ in range(n):
            sim.step()
        blocks.append((time.perf_counter() - t0) * BLOCK / n)
        done += n
    tiny = np.finfo(np.float32).tiny
    subnormals = 0
    for name in ("node_q", "node_q_lo", "node_qd"):
        a = getattr(sim.state, name).numpy().ravel()
        subnormals += int(np.count_nonzero((a != 0) & (np.abs(a) < tiny)))
    return {"run_s": run_s, "per_1000_s": blocks, "subnormals": subnormals, "flushed": float_mode.flush_subnormals_on_this_thread()}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=4000)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--child", choices=MODES, help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.child:
        print(json.dumps(child(a.child, a.frames)))
        return

    runs = {m: [] for m in MODES}
    for _ in range(a.repeat):
        for mode in MODES:  # alternated, so that drift in the machine's speed hits both alike
            proc = subprocess.run([sys.executable, __file__, "--child", mode, "--frames", str(a.frames)],
                                  capture_output=True, text=True, cwd=ROOT, check=False)  # fmt: skip
            if proc.returncode != 0:
                sys.exit(f"the {mode} process failed:\n{proc.stderr}")
            runs[mode].append(json.loads(proc.stdout.strip().splitlines()[-1]))

    result = {"frames": a.frames, "repeat": a.repeat, "machine": platform.processor() or platform.machine(),
              "command": f"warp-tube run scenes/default.usda --frames {a.frames} --no-surface -o <tmp>.usdc"}  # fmt: skip
    for mode in MODES:
        r = runs[mode]
        blocks = [statistics.median(b) for b in zip(*(x["per_1000_s"] for x in r))]
        result[mode] = {
            "flushed": r[0]["flushed"],
            "run_s": round(statistics.median(x["run_s"] for x in r), 3),
            "run_s_all": [round(x["run_s"], 3) for x in r],
            "per_1000_s": [round(b, 3) for b in blocks],
            "steady_per_1000_s": round(blocks[-1], 3),
            "subnormals": r[0]["subnormals"],
        }
    result["run_ratio"] = round(result["ieee"]["run_s"] / result["flush"]["run_s"], 2)
    result["steady_ratio"] = round(result["ieee"]["steady_per_1000_s"] / result["flush"]["steady_per_1000_s"], 2)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
