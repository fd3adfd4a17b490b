"""Centerline speed, with the error of the same discretisation beside it. Prints JSON.

    python benchmarks/bench_centerline.py [--device cpu|cuda:0] [--reps 7] [--worlds 65536]

Cases (each timed after a warm-up; medians of ``--reps`` repetitions, all in one run):

- ``substep_20pt_minimal``: one 20-point tube, clamped, structural + bending springs only; one
  launch of the per-tube kernel runs a 60 fps frame's substeps; time per substep.
- ``substep_20pt_all_features``: the same tube curved at rest, with anchors, gravity, both
  dampings and a point force with its assistant line: what each feature costs.
- ``frame_60fps_20pt``: ``Simulation.step`` for that minimal tube at 60 fps (substeps + host work).
- ``batch``: ``--worlds`` copies of a 32-point tube (on CUDA: 65,536), per-node kernels with the
  frame's substeps captured in a CUDA graph (block sizes compared), the same with every feature on,
  and the per-tube kernel; hub-steps per second.
- ``batch_onchip`` (+ ``_block64/128/512`` on CUDA): the same batch with the on-chip kernel (one
  launch per frame, each block keeps whole tubes in registers and shared memory).
- ``error``: the cantilever at 20 free segments with the same kernels: static tip error against
  the elastica (PL^2/EI = 2) and first-frequency error against Euler-Bernoulli.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import platform
import time

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only: no banner, no module messages

from warp_tube.model.tube import build_model
from warp_tube.bench.references import cantilever_frequency, elastica_tip
from warp_tube.scene.spec import ForceSpec, Scene, StageInfo, TubeParams, TubeSpec
from warp_tube import Simulation
from warp_tube.centerline.explicit import SemiImplicitEulerSolver
from warp_tube.centerline.stability import critical_time_step

E, RHO, R = 1.0e6, 1000.0, 0.02


def tube(n_points, curved=False, extras=False, length=1.0):
    s = np.linspace(0.0, length, n_points)
    pts = np.stack([s, 0.1 * np.sin(2 * s) if curved else 0 * s, 0 * s], axis=1)
    params = TubeParams(
        density=RHO, youngs_modulus=E, damping=1.0 if extras else 0.0, spring_damping=1e-4 if extras else 0.0,
        anchor_stiffness=100.0 if extras else 0.0,
    )  # fmt: skip
    return TubeSpec("/World/Tube", pts, [n_points], np.full(n_points, R), params, pinned=[0, 1],
                    anchors=[n_points // 2] if extras else [])  # fmt: skip


def scene(n_points, extras=False, fps=60.0):
    forces = (ForceSpec("/World/Push", 0, n_points - 3, [0.0], [[0.0, 0.0, 0.01]], assistant_line=True),) if extras else ()
    stage = StageInfo(meters_per_unit=1.0, time_codes_per_second=fps, frames_per_second=fps, end_time_code=fps)
    from warp_tube.scene.spec import SimulationSettings

    settings = SimulationSettings(gravity=(0.0, -9.81, 0.0)) if extras else SimulationSettings()
    return Scene((tube(n_points, curved=extras, extras=extras),), forces, settings=settings, stage=stage)


def timed(fn, reps, sync):
    out = []
    for _ in range(reps):
        sync()
        t0 = time.perf_counter()
        fn()
        sync()
        out.append(time.perf_counter() - t0)
    return float(np.median(out)), out


def substep_case(device, n_points, extras, reps, per_node=None, worlds=1, substeps=None, block_dim=None, onchip=False):
    sim = Simulation(scene(n_points, extras), device=device, world_count=worlds, surface=False)
    sim.step()  # builds the assistant line, compiles
    try:
        solver = SemiImplicitEulerSolver(sim.model, per_node=per_node, block_dim=block_dim, onchip=onchip)
    except ValueError as e:  # a feature the on-chip kernel lacks
        return {"skipped": str(e)}
    n = substeps or sim.substeps
    s0, s1 = sim.state, sim.next_state
    sync = (lambda: wp.synchronize_device(device))

    def run():
        solver.integrate(s0, s1, sim.control, sim.dt, n)

    run()
    med, all_t = timed(run, reps, sync)
    return {
        "worlds": worlds, "points": n_points, "substeps_per_launch": n, "dt_s": sim.dt,
        "per_node_kernel": solver.per_node and not solver.onchip,
        "onchip_kernel": solver.onchip,
        "block_dim": solver.onchip_block_dim if solver.onchip else solver.block_dim if solver.per_node else None,
        "time_per_substep_us": med / n * 1e6,
        "hub_steps_per_s": worlds * sim.model.node_count * n / med,
        "reps_s": all_t,
    }  # fmt: skip


def frame_case(device, reps):
    sim = Simulation(scene(20), device=device, surface=False)
    sim.step()
    med, all_t = timed(sim.step, max(reps, 50), lambda: wp.synchronize_device(device))
    return {"substeps_per_frame": sim.substeps, "time_per_frame_us": med * 1e6,
            "time_per_substep_us": med / sim.substeps * 1e6}  # fmt: skip


def error_case(device):
    """Static tip error (PL^2/EI = 2) and first-frequency error of the 20-segment cantilever."""
    L, n = 1.0, 22
    EI = E * math.pi * R**4 / 4
    x = (np.arange(n) - 1) * L / 20
    pts = np.stack([x, 0 * x, 0 * x], axis=1)
    f1 = cantilever_frequency(EI, RHO * math.pi * R**2, L)
    P = 2 * EI / L**2
    t = TubeSpec("/R", pts, [n], np.full(n, R), TubeParams(density=RHO, youngs_modulus=E, damping=1.5 * 2 * math.pi * f1), pinned=[0, 1])
    m = build_model(Scene((t,), (ForceSpec("/F", 0, n - 1, [0.0], [[0, -P, 0]], assistant_line=False),)), device=device)
    solver = SemiImplicitEulerSolver(m)
    dt = 0.5 * critical_time_step(m.host)
    s0, s1, c = m.state(), m.state(), m.control()
    fe = np.zeros((1, n, 3))
    fe[0, -1] = [0, -P, 0]
    c.node_f_ext.assign(fe)
    chunk = int(1 / f1 / dt / 10) + 1
    prev = None
    for _ in range(2000):
        solver.integrate(s0, s1, c, dt, chunk)
        s0, s1 = s1, s0
        tip = s0.node_q.numpy()[0, -1, :2]
        if prev is not None and np.abs(tip - prev).max() < 3e-6:
            break
        prev = tip
    ref = elastica_tip(2.0, P / (E * math.pi * R**2))
    return {"cantilever_20seg_tip_error_over_L": float(np.linalg.norm(tip - ref)), "dt_s": dt}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default=None)
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--worlds", type=int, default=None, help="batch size (default 65536 on CUDA, 256 on CPU)")
    ap.add_argument("--points", type=int, default=32, help="points per tube in the batch cases")
    ap.add_argument("--batch-only", action="store_true", help="only the batch cases")
    a = ap.parse_args()
    wp.init()
    device = a.device or ("cuda:0" if wp.get_cuda_device_count() else "cpu")
    dev = wp.get_device(device)
    worlds = a.worlds or (65536 if dev.is_cuda else 256)
    res = {
        "benchmark": "centerline", "date": datetime.date.today().isoformat(), "device": device,
        "device_name": dev.name, "warp": wp.config.version, "cpu": platform.processor() or platform.machine(),
    }  # fmt: skip
    if not a.batch_only:
        res["substep_20pt_minimal"] = substep_case(device, 20, False, a.reps)
        res["substep_20pt_all_features"] = substep_case(device, 20, True, a.reps)
        res["feature_cost_ratio"] = res["substep_20pt_all_features"]["time_per_substep_us"] / res["substep_20pt_minimal"]["time_per_substep_us"]
        res["frame_60fps_20pt"] = frame_case(device, a.reps)
    P = a.points
    res["batch_per_node"] = substep_case(device, P, False, a.reps, per_node=True, worlds=worlds)
    if wp.get_device(device).is_cuda:
        for bd in (64, 128, 512):
            res[f"batch_per_node_block{bd}"] = substep_case(device, P, False, a.reps, per_node=True, worlds=worlds, block_dim=bd)
    res["batch_per_node_all_features"] = substep_case(device, P, True, a.reps, per_node=True, worlds=worlds)
    res["batch_per_tube"] = substep_case(device, P, False, a.reps, per_node=False, worlds=worlds)
    # On-chip: a frame's substeps in one launch, a block per group of tubes (on the CPU it runs
    # on cooperative fibers: a correctness path, slow).
    res["batch_onchip"] = substep_case(device, P, False, a.reps, worlds=worlds, onchip=True)
    if wp.get_device(device).is_cuda:
        for bd in (64, 256, 512):
            res[f"batch_onchip_block{bd}"] = substep_case(device, P, False, a.reps, worlds=worlds, block_dim=bd, onchip=True)
    res["error"] = error_case(device)
    for v in res.values():
        if isinstance(v, dict):
            v.pop("reps_s", None)
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
