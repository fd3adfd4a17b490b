"""Centerline speed, with the error of the same discretisation beside it. Prints JSON.

    python benchmarks/bench_centerline.py [--device cpu|cuda:0] [--reps 7] [--worlds 65536] [--points 32] [--batch-only] [--breakdown] [--max-registers N]

On the GPU machine (H100 or H200), the issue's figures::

    python benchmarks/bench_centerline.py --device cuda:0 --batch-only

Cases (each timed after a warm-up; medians of ``--reps`` repetitions, all in one run):

- ``substep_20pt_minimal``: one 20-point tube, clamped, structural + bending springs only; one
  launch runs a 60 fps frame's substeps; time per substep.
- ``substep_20pt_all_features``: the same tube curved at rest, with anchors, gravity, both
  dampings and a point force with its assistant line: what each feature costs.
- ``frame_60fps_20pt``: ``Simulation.step`` for that minimal tube at 60 fps (substeps + host work).
- ``batch_onchip_minimal`` / ``batch_onchip_all_features``: ``--worlds`` copies (65,536 on CUDA,
  256 on the CPU) of a ``--points``-point tube, minimal and with every feature on (curved,
  anchors, gravity, mass and spring damping, a pushed point with its assistant line), on the
  on-chip kernel (the default on CUDA: a frame in one launch, each block keeping whole tubes in
  registers and shared memory; on the CPU it runs on cooperative fibers, a correctness path, slow);
  both at the same substeps per launch; hub-steps per second and ``all_features_over_minimal``,
  the ratio of their times per substep. On CUDA the on-chip kernel exchanges neighbours' values
  through warp shuffles where every tube lies within a warp, and curved tubes' scans through
  shuffles carried between warps elsewhere (``exchange``: shuffle, mixed, shared); ``_shared`` or
  ``_shuffle`` cases run the same batches with shared memory, or with shuffles in a layout padded
  to whole warps (e.g. 20-point tubes) where the default was shared memory; and both at 32, 64,
  256 and 512 threads per block.
- ``batch_onchip_curved_free_turning`` / ``_all_features_free_turning``: the curved and the
  all-features batches with each tube held at its first point only (its first edge free to turn,
  so its first frame is twisted to the bending energy's minimum: one more scan a substep, and on
  CUDA the shared-memory exchange), with ``over_minimal``.
- ``batch_per_tube_minimal`` / ``_all_features``: the same batches on the per-tube kernel (the CPU
  path; on CUDA the path of tubes longer than a block).
- ``batch_onchip_only_<feature>`` / ``batch_onchip_without_<feature>`` (``--breakdown``): the
  on-chip batch with one feature of :data:`FEATURES` alone and with all but that one, each with
  ``over_minimal`` (its time per substep over the minimal batch's): what each feature costs.
- On CUDA each on-chip case also gives its kernel's ``register_count`` (per thread) and
  ``local_memory_size`` (bytes per thread: spilled registers and register arrays in local memory).
- ``bound``: what the on-chip kernel is judged against (see :func:`bound`): global-memory bytes per
  hub-step (the state and parameters are read and the state written once a frame), float32
  operations per hub-step (a count of the kernel's arithmetic, FMA = 2), shared-memory exchanges
  per substep, and on a known GPU the hub-steps per second that its peak FP32 rate and memory
  bandwidth allow, with each batch's fraction of it.
- ``error``: the cantilever at 20 free segments with the same kernels: static tip error against
  the elastica (PL^2/EI = 2).
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

from warp_tube.bench.references import elastica_tip
from warp_tube.centerline import explicit
from warp_tube.centerline.explicit import SemiImplicitEulerSolver
from warp_tube.centerline.stability import critical_time_step
from warp_tube.model.tube import build_model
from warp_tube.scene.spec import ForceSpec, Scene, SimulationSettings, StageInfo, TubeParams, TubeSpec
from warp_tube import Simulation

E, RHO, R = 1.0e6, 1000.0, 0.02

#: Peak float32 rate [FLOP/s, FMA = 2, no tensor cores] and memory bandwidth [B/s] by device name
#: (vendor data sheets, SXM parts).
PEAKS = {"H100": (67.0e12, 3.35e12), "H200": (67.0e12, 4.8e12)}


#: the features the all-features case turns on; ``--breakdown`` times each alone and each left out
FEATURES = ("curved", "anchors", "gravity", "mass_damping", "spring_damping", "assistant_line")


def _features(extras) -> frozenset:
    """``extras``: True (every feature), False (none) or an iterable of names from FEATURES."""
    if extras is True:
        return frozenset(FEATURES)
    return frozenset(extras or ())


def tube(n_points, extras=False, length=1.0, pinned=(0, 1)):
    """The benchmark's tube: clamped at its start (``pinned``: its first two points), or with
    ``pinned=(0,)`` held at one point, its first edge free to turn."""
    f = _features(extras)
    s = np.linspace(0.0, length, n_points)
    pts = np.stack([s, 0.1 * np.sin(2 * s) if "curved" in f else 0 * s, 0 * s], axis=1)
    params = TubeParams(
        density=RHO, youngs_modulus=E, damping=1.0 if "mass_damping" in f else 0.0,
        spring_damping=1e-4 if "spring_damping" in f else 0.0, anchor_stiffness=100.0 if "anchors" in f else 0.0,
    )  # fmt: skip
    return TubeSpec("/World/Tube", pts, [n_points], np.full(n_points, R), params, pinned=list(pinned),
                    anchors=[n_points // 2] if "anchors" in f else [])  # fmt: skip


def scene(n_points, extras=False, fps=60.0, pinned=(0, 1)):
    """A clamped tube (``pinned``: as :func:`tube`); ``extras`` as in :func:`_features` (a pushed
    point with its assistant line for "assistant_line")."""
    f = _features(extras)
    push = ForceSpec("/World/Push", 0, n_points - 3, [0.0], [[0.0, 0.0, 0.01]], assistant_line=True)
    forces = (push,) if "assistant_line" in f else ()
    stage = StageInfo(meters_per_unit=1.0, time_codes_per_second=fps, frames_per_second=fps, end_time_code=fps)
    settings = SimulationSettings(gravity=(0.0, -9.81, 0.0)) if "gravity" in f else SimulationSettings()
    return Scene((tube(n_points, extras=f, pinned=pinned),), forces, settings=settings, stage=stage)


def timed(fn, reps, sync):
    out = []
    for _ in range(reps):
        sync()
        t0 = time.perf_counter()
        fn()
        sync()
        out.append(time.perf_counter() - t0)
    return float(np.median(out)), out


def substep_case(device, n_points, extras, reps, worlds=1, substeps=None, block_dim=None, onchip=None, exchange="auto",
                 pinned=(0, 1)):  # fmt: skip
    sim = Simulation(scene(n_points, extras, pinned=pinned), device=device, world_count=worlds, surface=False)
    sim.step()  # builds the assistant line, compiles
    solver = SemiImplicitEulerSolver(sim.model, block_dim=block_dim, onchip=onchip, exchange=exchange)
    n = substeps or sim.substeps
    s0, s1 = sim.state, sim.next_state
    if extras is True:
        assert all(sim.model.features) and sim.control.al_active.numpy().all()

    def run():
        solver.integrate(s0, s1, sim.control, sim.dt, n)

    run()
    med, all_t = timed(run, reps, lambda: wp.synchronize_device(device))
    resources = {}
    if solver.onchip and wp.get_device(device).is_cuda:
        # registers per thread and bytes of local memory per thread (spilled registers, arrays)
        resources = wp.get_cuda_kernel_properties(solver.onchip_kernel, device, solver.onchip_block_dim)
    return {
        "worlds": worlds, "points": n_points, "substeps_per_launch": n, "dt_s": sim.dt,
        "onchip_kernel": solver.onchip, "block_dim": solver.onchip_block_dim, "exchange": solver.onchip_exchange,
        "time_per_substep_us": med / n * 1e6,
        "hub_steps_per_s": worlds * sim.model.node_count * n / med,
        "reps_s": all_t, **resources,
    }  # fmt: skip


def frame_case(device, reps):
    sim = Simulation(scene(20), device=device, surface=False)
    sim.step()
    med, all_t = timed(sim.step, max(reps, 50), lambda: wp.synchronize_device(device))
    return {"substeps_per_frame": sim.substeps, "time_per_frame_us": med * 1e6,
            "time_per_substep_us": med / sim.substeps * 1e6}  # fmt: skip


#: float32 operations per hub-step of the on-chip kernel, by term (a count of its arithmetic as
#: written, FMA = 2, square root and division 1 each under fast math; a hand count, approximate):
#: minimal = exchange + edges + spring + stencil + advance; the rest are added by the features.
FLOPS = {
    "edges": 18,  # two compensated edges
    "spring": 22,  # spring_force
    "stencil": 122,  # bend_gradients + stencil_forces
    "exchange": 20,  # summing the contributions in and out
    "advance": 22,  # compensated semi-implicit update
    "mass_damping": 5,
    "spring_damping": 10,  # velocity differences, damping along the springs
    "anchors": 15,
    "curved": 290,  # transports, a 5-round quaternion scan (32-point tubes), target, holonomy, mu scan
    "assistant_line": 170,  # four row differences, up to four springs, the line point's update
}
#: Global-memory bytes per node per frame (loads and stores, float32 / int32), by term.
BYTES = {"state": 72, "minimal": 64, "spring_damping": 8, "anchors": 20, "external": 12, "curved": 12, "assistant_line": 104}


def bound(device_name, substeps_minimal, substeps_all, exchanges_all):
    """The roofline the on-chip batches are judged against: flops and bytes per hub-step, and the
    hub-steps per second a known GPU's peaks allow (the lower of the two limits)."""
    flops_min = FLOPS["edges"] + FLOPS["spring"] + FLOPS["stencil"] + FLOPS["exchange"] + FLOPS["advance"]
    flops_all = sum(FLOPS.values())
    bytes_min = BYTES["state"] + BYTES["minimal"]
    bytes_all = sum(BYTES.values())
    out = {
        "flops_per_hub_step": {"minimal": flops_min, "all_features": flops_all},
        "bytes_per_node_frame": {"minimal": bytes_min, "all_features": bytes_all},
        "bytes_per_hub_step": {"minimal": bytes_min / substeps_minimal, "all_features": bytes_all / substeps_all},
        "shared_exchanges_per_substep": {"minimal": 2, "all_features": exchanges_all},
    }
    peak = next((v for k, v in PEAKS.items() if k in device_name), None)
    if peak is not None:
        fl, bw = peak
        out["peaks_flops_bytes_per_s"] = [fl, bw]
        out["bound_hub_steps_per_s"] = {
            "minimal": min(fl / flops_min, bw * substeps_minimal / bytes_min),
            "all_features": min(fl / flops_all, bw * substeps_all / bytes_all),
        }
    return out


def error_case(device):
    """Static tip error (PL^2/EI = 2) of the 20-segment cantilever."""
    L, n = 1.0, 22
    EI = E * math.pi * R**4 / 4
    x = (np.arange(n) - 1) * L / 20
    pts = np.stack([x, 0 * x, 0 * x], axis=1)
    w1 = 1.8751**2 * math.sqrt(EI / (RHO * math.pi * R**2 * L**4))
    P = 2 * EI / L**2
    t = TubeSpec("/R", pts, [n], np.full(n, R), TubeParams(density=RHO, youngs_modulus=E, damping=1.5 * w1), pinned=[0, 1])
    m = build_model(Scene((t,), (ForceSpec("/F", 0, n - 1, [0.0], [[0, -P, 0]], assistant_line=False),)), device=device)
    solver = SemiImplicitEulerSolver(m)
    dt = 0.5 * critical_time_step(m.host)
    s0, s1, c = m.state(), m.state(), m.control()
    fe = np.zeros((1, n, 3))
    fe[0, -1] = [0, -P, 0]
    c.node_f_ext.assign(fe)
    chunk = int(2 * math.pi / w1 / dt / 10) + 1
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
    ap.add_argument("--batch-only", action="store_true", help="only the batch cases and the bound")
    ap.add_argument("--breakdown", action="store_true",
                    help="also the on-chip batch with each feature alone and with each left out")
    ap.add_argument("--max-registers", type=int, default=None,
                    help="hold the on-chip kernel to this many registers a thread where it takes more "
                         "(default: warp_tube.centerline.explicit.ONCHIP_MAX_REGISTERS; 255: as compiled)")
    a = ap.parse_args()
    if a.max_registers is not None:
        explicit.ONCHIP_MAX_REGISTERS = a.max_registers
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
    # Both batches at the substeps a frame of the all-features tube takes (the smaller step), so
    # that a launch carries the same work per node.
    n = Simulation(scene(P, True), device="cpu", surface=False).substeps
    for kernel, onchip in (("onchip", True), ("per_tube", False)):
        cases = {}
        for name, extras in (("minimal", False), ("all_features", True)):
            cases[name] = substep_case(device, P, extras, a.reps, worlds=worlds, substeps=n, onchip=onchip)
            res[f"batch_{kernel}_{name}"] = cases[name]
        res[f"batch_{kernel}_all_features_over_minimal"] = cases["all_features"]["time_per_substep_us"] / cases["minimal"]["time_per_substep_us"]
        if dev.is_cuda and onchip:
            # the same batches with the other exchange of neighbours' values (shuffles: in a
            # layout padded to whole warps where the compact one is not)
            for name, extras in (("minimal", False), ("all_features", True)):
                other = "shared" if cases[name]["exchange"] != "shared" else "shuffle"
                try:
                    res[f"batch_onchip_{name}_{other}"] = substep_case(device, P, extras, a.reps, worlds=worlds, substeps=n, onchip=True, exchange=other)
                except ValueError as e:  # tubes longer than a warp: no shuffles
                    res[f"batch_onchip_{name}_{other}"] = {"error": str(e)}
            for bd in (32, 64, 256, 512):
                for name, extras in (("minimal", False), ("all_features", True)):
                    try:  # a block size the device cannot launch is reported, not fatal
                        res[f"batch_onchip_{name}_block{bd}"] = substep_case(device, P, extras, a.reps, worlds=worlds, substeps=n, block_dim=bd, onchip=True)
                    except Exception as e:  # noqa: BLE001
                        res[f"batch_onchip_{name}_block{bd}"] = {"error": f"{type(e).__name__}: {e}"}
    # A curved tube held at one point, its first edge free to turn: its first frame is twisted to
    # the bending energy's minimum, one more scan a substep (on CUDA: shared-memory exchange).
    base = res["batch_onchip_minimal"]["time_per_substep_us"]
    for name, extras in (("curved", {"curved"}), ("all_features", True)):
        c = substep_case(device, P, extras, a.reps, worlds=worlds, substeps=n, onchip=True, pinned=(0,))
        c["over_minimal"] = c["time_per_substep_us"] / base
        res[f"batch_onchip_{name}_free_turning"] = c
    if a.breakdown:
        for feat in FEATURES:
            for label, feats in (("only", {feat}), ("without", set(FEATURES) - {feat})):
                c = substep_case(device, P, feats, a.reps, worlds=worlds, substeps=n, onchip=True)
                c["over_minimal"] = c["time_per_substep_us"] / base
                res[f"batch_onchip_{label}_{feat}"] = c
    rounds = math.ceil(math.log2(P))
    res["bound"] = b = bound(dev.name, n, n, 2 + 2 * (1 + rounds))
    if "bound_hub_steps_per_s" in b:
        for name in ("minimal", "all_features"):
            b[f"fraction_of_bound_{name}"] = res[f"batch_onchip_{name}"]["hub_steps_per_s"] / b["bound_hub_steps_per_s"][name]
    res["goal"] = {"all_features_hub_steps_per_s": 5e10, "all_features_over_minimal": 1.5}
    if not a.batch_only:
        res["error"] = error_case(device)
    for v in res.values():
        if isinstance(v, dict):
            v.pop("reps_s", None)
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
