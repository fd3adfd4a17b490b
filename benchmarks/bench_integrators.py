"""Speed against error of the two integrators on the clamped cantilever; prints JSON.

Scene: the cantilever of tests/test_elastica.py (L = 1 m, r = 0.02 m, E = 1e6 Pa, rho = 1000
kg/m^3), ``segments`` free segments. For each integrator, segment count and substep:

- ``wall_per_sim_s``: wall time [s] per simulated second (one world, frames of 1/60 s, after a
  warm-up, the undamped rod swinging under the tip load), and ``us_per_substep_node``: the same per substep and per node [us];
- ``tip_error``: statics, |tip - elastica| / L under the tip load PL^2/EI = 5 (damped, settled);
- ``freq_error``: first natural frequency (undamped, released in the first mode at 1e-3 L) against
  Euler-Bernoulli, relative; ``decay_per_period``: relative loss of amplitude per period.

Semi-implicit runs at 0.5 x its stability bound; implicit at 1/60, 1/240 and 1/1000 s.
Usage: ``python benchmarks/bench_integrators.py [--device cpu|cuda:0] [--segments 10 20 40 80]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # stdout carries the JSON only: no banner, no module messages

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from warp_tube.bench.problems import settle, straight_points  # noqa: E402
from warp_tube.centerline.implicit import ImplicitEulerSolver  # noqa: E402
from warp_tube.model.tube import build_model  # noqa: E402
from warp_tube.bench.references import cantilever_frequency, elastica_tip, mode1  # noqa: E402
from warp_tube.scene.spec import ForceSpec, Scene, TubeParams, TubeSpec  # noqa: E402
from warp_tube.centerline.explicit import SemiImplicitEulerSolver  # noqa: E402
from warp_tube.centerline.stability import critical_time_step  # noqa: E402

E, RHO, L, R, LOAD = 1.0e6, 1000.0, 1.0, 0.02, 5.0
EI = E * np.pi * R**4 / 4
W1 = 2 * np.pi * cantilever_frequency(EI, RHO * np.pi * R**2, L)
FRAME = 1.0 / 60.0


def scene(segments, damping, load):
    pts = straight_points(segments + 2, L)
    tube = TubeSpec("/World/Rod", pts, [len(pts)], np.full(len(pts), R), TubeParams(density=RHO, youngs_modulus=E, damping=damping), pinned=[0, 1])
    P = load * EI / L**2
    force = ForceSpec("/World/Load", 0, len(pts) - 1, [0.0], [[0.0, -P, 0.0]], assistant_line=False)
    return Scene((tube,), (force,)), P


def make(kind, model):
    return SemiImplicitEulerSolver(model) if kind == "semiImplicitEuler" else ImplicitEulerSolver(model)


def timing(kind, segments, dt, device):
    sc, P = scene(segments, 0.0, LOAD)
    model = build_model(sc, device=device)
    solver = make(kind, model)
    state, other, control = model.state(), model.state(), model.control()
    f = np.zeros((1, model.node_count, 3))
    f[0, -1] = [0.0, -P, 0.0]
    control.node_f_ext.assign(f)  # timed while swinging under the load (a rod at rest iterates less)
    substeps = max(1, round(FRAME / dt))
    solver.integrate(state, other, control, FRAME / substeps, substeps)  # compile, record
    wp.synchronize_device(device)
    frames = max(3, int(0.3 / (substeps * model.node_count * 2e-6 * (5 if kind != "semiImplicitEuler" else 1))))
    t0 = time.perf_counter()
    for _ in range(frames):
        solver.integrate(state, other, control, FRAME / substeps, substeps)
        state, other = other, state
    wp.synchronize_device(device)
    wall = (time.perf_counter() - t0) / (frames * FRAME)
    return wall, wall / (substeps / FRAME) / model.node_count * 1e6


def statics(kind, segments, dt, device):
    sc, P = scene(segments, 1.5 * W1, LOAD)
    model = build_model(sc, device=device)
    solver = make(kind, model)
    state, control = model.state(), model.control()
    f = np.zeros((1, model.node_count, 3))
    f[0, -1] = [0.0, -P, 0.0]
    control.node_f_ext.assign(f)
    chunk = max(1, int(2 * np.pi / W1 / dt / 10))
    q = settle(solver, model, state, control, dt, chunk, tol=3e-6 * L)
    ref = elastica_tip(LOAD, P / (E * np.pi * R**2)) * L
    return float(np.linalg.norm(q[0, -1, :2] - ref) / L)


def frequency(kind, segments, dt, device):
    sc, _ = scene(segments, 0.0, 0.0)
    model = build_model(sc, device=device)
    solver = make(kind, model)
    state, other, control = model.state(), model.state(), model.control()
    q = state.node_q.numpy()
    x = q[0, 1:, 0]
    mid = 0.5 * (x[1:] + x[:-1]) / L
    theta = np.arctan(1e-3 * (mode1(mid + 1e-6) - mode1(mid - 1e-6)) / 2e-6)
    q[0, 2:, 0] = x[0] + np.cumsum(np.diff(x) * np.cos(theta))
    q[0, 2:, 1] = np.cumsum(np.diff(x) * np.sin(theta))
    state.node_q.assign(q)
    chunk = max(1, int(2 * np.pi / W1 / dt / 400))
    n = int(6.2 * 2 * np.pi / W1 / (dt * chunk))
    ys = np.empty(n)
    for k in range(n):
        solver.integrate(state, other, control, dt, chunk)
        state, other = other, state
        ys[k] = state.node_q.numpy()[0, -1, 1]
    t = np.arange(1, n + 1) * dt * chunk
    i = np.nonzero((ys[:-1] < 0) & (ys[1:] >= 0))[0]
    tc = t[i] + (t[i + 1] - t[i]) * (-ys[i]) / (ys[i + 1] - ys[i])
    f = (len(tc) - 1) / (tc[-1] - tc[0])
    periods = [ys[a : b + 1].max() for a, b in zip(i[:-1], i[1:])]
    decay = 1 - (periods[-1] / periods[0]) ** (1 / max(len(periods) - 1, 1))
    return float(f / (W1 / (2 * np.pi)) - 1), float(decay)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--segments", type=int, nargs="+", default=[10, 20, 40, 80])
    ap.add_argument("--implicit-steps", type=float, nargs="+", default=[1 / 60, 1 / 240, 1 / 1000])
    args = ap.parse_args()
    wp.init()
    rows = []
    for n in args.segments:
        hc = critical_time_step(build_model(scene(n, 0.0, 0.0)[0], device="cpu").host)
        runs = [("semiImplicitEuler", FRAME / np.ceil(FRAME / (0.5 * hc)))] + [("implicitEuler", h) for h in args.implicit_steps]
        for kind, dt in runs:
            wall, per = timing(kind, n, dt, args.device)
            ferr, decay = frequency(kind, n, dt, args.device)
            row = dict(integrator=kind, segments=n, dt=dt, dt_over_bound=dt / hc, wall_per_sim_s=wall,
                       us_per_substep_node=per, tip_error=statics(kind, n, dt, args.device),
                       freq_error=ferr, decay_per_period=decay)  # fmt: skip
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    print(json.dumps(dict(device=str(wp.get_device(args.device)), E=E, r=R, L=L, load=LOAD, rows=rows), indent=1))


if __name__ == "__main__":
    main()
