"""The costs behind the up-front warnings of a long model build and a long run, measured.

- model set-up per centerline point: ``Simulation(scene)`` (build_model and the surface topology)
  of straight tubes of N points, against ``warp_tube.cli.BUILD_SECONDS_PER_POINT``;
- a semi-implicit substep on the CPU: the default scene made stiff (E = 1e10 Pa, tens of thousands
  of substeps a frame) with semi-implicit Euler forced, frames after the first (kernels compiled),
  against ``Simulation.estimated_seconds`` (``warp_tube.sim.budget``'s costs); the same scene with
  ``auto`` (which takes implicit Euler, estimated at ``IMPLICIT_COST_RATIO`` times the cost); and
  straight tubes of 21 to 20,001 points.

Prints medians of ``--repeat`` runs. Usage: ``.venv/bin/python benchmarks/bench_estimates.py``.
"""

from __future__ import annotations

import argparse
import pathlib
import statistics
import time

import numpy as np
import warp as wp

import warp_tube
from warp_tube.cli import BUILD_SECONDS_PER_POINT
from warp_tube.scene.spec import Scene, SimulationSettings, StageInfo, TubeParams, TubeSpec
from warp_tube import Simulation

ROOT = pathlib.Path(__file__).resolve().parents[1]


def straight_scene(n: int) -> Scene:
    x = np.zeros((n, 3))
    x[:, 0] = np.arange(n) * 1e-3
    tube = TubeSpec("/World/Tube", x, [n], np.full(n, 1e-3), TubeParams(density=1050.0, youngs_modulus=1e5), pinned=[0, 1])
    info = StageInfo(meters_per_unit=1.0, up_axis="Y", time_codes_per_second=24.0, frames_per_second=24.0,
                     start_time_code=0.0, end_time_code=2.0)  # fmt: skip
    return Scene(tubes=[tube], forces=[], settings=SimulationSettings(), stage=info, source="<straight>")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, nargs="+", default=[5_000, 20_000])
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    for n in a.points:
        scene = straight_scene(n)
        times = []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            Simulation(scene, device="cpu")
            times.append(time.perf_counter() - t0)
        per = statistics.median(times) / n
        print(f"set-up, {n:,} points: median {statistics.median(times):.2f} s, {per * 1e3:.3f} ms a point "
              f"(estimate uses {BUILD_SECONDS_PER_POINT * 1e3:.3f})")  # fmt: skip

    stiff = (ROOT / "scenes" / "default.usda").read_text().replace("youngsModulus = 100000", "youngsModulus = 1e10")
    for integrator in ("semiImplicitEuler", "auto"):
        path = pathlib.Path("/tmp") / f"warp_tube_bench_stiff_{integrator}.usda"
        path.write_text(stiff.replace('warptube:integrator = "auto"', f'warptube:integrator = "{integrator}"'))
        sim = Simulation(warp_tube.load_scene(str(path)), device="cpu", surface=False)
        frame = _frame_seconds(sim, a.repeat)
        per_step = frame / sim.substeps
        per_point = per_step / sim.model.node_count
        print(f"stiff default scene, {sim.integrator}: {sim.substeps:,} substeps a frame, median frame "
              f"{frame:.3f} s, {per_step * 1e6:.2f} us a substep, {per_point * 1e9:.0f} ns a point "
              f"and substep ({sim.model.node_count} points; the estimate takes "
              f"{sim.estimated_seconds(1) / sim.substeps * 1e6:.2f} us a substep)")  # fmt: skip
    for n in (21, 201, 2001, 20001):  # a straight tube under gravity, semi-implicit: the cost a substep and a point
        x = np.linspace(0.0, 0.01 * (n - 1), n)
        tube = TubeSpec("/World/Tube", np.stack([x, 0 * x, 0 * x], 1), [n], np.full(n, 0.01),
                        TubeParams(density=1050.0, youngs_modulus=1e5, damping=2.0), pinned=[0, 1])  # fmt: skip
        settings = SimulationSettings(integrator="semiImplicitEuler", time_step=1e-4, gravity=(0.0, -9.81, 0.0))
        sim = Simulation(Scene((tube,), (), settings=settings, stage=StageInfo(meters_per_unit=1.0)), device="cpu", surface=False)
        per_step = _frame_seconds(sim, a.repeat) / sim.substeps
        print(f"straight tube, {n:,} points: {per_step * 1e6:.1f} us a substep ({per_step / n * 1e9:.0f} ns a point; the "
              f"estimate takes {sim.estimated_seconds(1) / sim.substeps * 1e6:.1f} us)")  # fmt: skip


def _frame_seconds(sim, repeat: int) -> float:
    """Median wall time [s] of ``repeat`` frames of ``sim``, after one (its kernels compiled)."""
    sim.step()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        sim.step()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)

if __name__ == "__main__":
    main()
