"""Newton (VBD rods: capsule bodies joined by rod joints, on Warp) on the benchmark problems.

Set-up as Newton's cantilever cable example (``newton/examples/vbd/example_cable_bend_stiffness.py``)
does it: ``newton.Rod`` with the material (E, shear modulus E / 3 as PyElastica's default) so that
``ModelBuilder.add_rod`` derives each joint's stiffness from EI, EA and GJ; the root body made
kinematic by zero mass and inertia; ``SolverVBD``; frames of 1/60 s in substeps (captured in a CUDA
graph on the GPU); the tip load as a body wrench every substep (here at the tip node: force at the
centre of mass plus its moment, from a small kernel). Stretch and shear damping are off; bend and
twist damping are ``kd = 2 zeta / omega1 x ke``, the same first-mode damping ratio as the other codes
(VBD bodies have no mass-proportional damping). Body masses and inertias are set to the solid
cylinder's ``rho A dl`` (Newton's capsules add hemispherical caps: 53% more mass here).

Clamps (``clamp`` in a configuration):

- ``"documented"``: the rod starts at the clamp and its first segment body is kinematic (the
  example's root body), so the rod bends from its second node on.
- ``"behind"`` (tuned by hand): one more segment lies behind the clamp and is the kinematic root,
  and the clamp joint's bend stiffness and damping are doubled (half of its dual length lies in
  the rigid root), as warp_tube's clamp has it.

``substeps`` and ``iterations`` come from each configuration (the example uses 10 and 20).
"""

from __future__ import annotations

import time

import numpy as np

from ..problems import FREQUENCY_AMPLITUDE, FREQUENCY_PERIODS, RodProblem, measure_frequency, mode1_centerline, track_static

NAME = "newton"
FRAME_DT = 1.0 / 60.0

_kernels = {}


def available():
    """(installed, why not)."""
    try:
        import newton  # noqa: F401
    except Exception as e:  # noqa: BLE001 (any import failure means "not available", said in the report)
        return False, (f"Newton not importable ({type(e).__name__}: {e}); install it with "
                       'pip install "warp-tube[peers]" (from a checkout: pip install -e ".[peers]")')
    return True, ""


def versions() -> dict:
    from importlib.metadata import version

    return {"newton": version("newton"), "warp-lang": version("warp-lang")}


def _tip_wrench_kernel():
    """A kernel writing a dead force at each tip node as a wrench on its body (built once)."""
    if "tip" not in _kernels:
        import warp as wp

        @wp.kernel(enable_backward=False)
        def tip_wrench(
            body_q: wp.array(dtype=wp.transform),
            tip_body: wp.array(dtype=wp.int32),
            half_length: float,
            force: wp.vec3,
            body_f: wp.array(dtype=wp.spatial_vector),
        ):
            i = wp.tid()
            b = tip_body[i]
            arm = wp.quat_rotate(wp.transform_get_rotation(body_q[b]), wp.vec3(0.0, 0.0, half_length))
            body_f[b] = wp.spatial_vector(force, wp.cross(arm, force))

        _kernels["tip"] = tip_wrench
    return _kernels["tip"]


def _rod_builder(problem: RodProblem, config: dict, damping_ratio: float, gravity: bool):
    """(builder, tip body index, segment length): one rod of ``config`` in a fresh ModelBuilder."""
    import newton
    import warp as wp

    n = config["segments"]
    behind = 1 if config.get("clamp") == "behind" else 0
    dl = problem.length / n
    b = newton.ModelBuilder(gravity=(0.0, -problem.gravity if gravity else 0.0, 0.0))
    pts = problem.rest_centerline(n, behind)
    G = problem.youngs_modulus / 3.0
    rod = newton.Rod(pts, radius=problem.radius, youngs_modulus=problem.youngs_modulus, shear_modulus=G)
    ke_bend = problem.EI / dl
    kd = 2.0 * damping_ratio / problem.omega1 * ke_bend
    bodies, joints = b.add_rod(rod=rod, stretch_damping=0.0, shear_damping=0.0, bend_damping=kd, twist_damping=kd)
    m = problem.mass_per_length * dl
    ixx = m * (3 * problem.radius**2 + dl**2) / 12.0
    izz = m * problem.radius**2 / 2.0
    for k in bodies:
        b.body_mass[k], b.body_inv_mass[k] = m, 1.0 / m
        b.body_inertia[k] = wp.mat33(ixx, 0.0, 0.0, 0.0, ixx, 0.0, 0.0, 0.0, izz)
        b.body_inv_inertia[k] = wp.mat33(1 / ixx, 0.0, 0.0, 0.0, 1 / ixx, 0.0, 0.0, 0.0, 1 / izz)
    root = bodies[0]
    b.body_mass[root], b.body_inv_mass[root] = 0.0, 0.0
    b.body_inertia[root], b.body_inv_inertia[root] = wp.mat33(0.0), wp.mat33(0.0)
    if behind:
        s = b.joint_qd_start[joints[0]]
        for d in (3, 4):  # the two bend axes of the clamp joint (dofs: 3 linear, then bend x, bend y, twist)
            b.joint_target_ke[s + d] *= 2.0
            b.joint_target_kd[s + d] *= 2.0
    return b, bodies[-1], dl


class _Run:
    """One or many rods (``batch`` worlds) advanced a frame of ``substeps`` VBD steps at a time."""

    def __init__(self, problem, config, device, batch=1, damping_ratio=None, load=True, points=None):
        import newton
        import warp as wp

        from ..problems import DAMPING_RATIO

        zeta = DAMPING_RATIO if damping_ratio is None else damping_ratio
        rb, tip, self.dl = _rod_builder(problem, config, zeta, load and problem.gravity > 0)
        self.bodies_per_rod = len(rb.body_mass)
        if batch == 1:
            b = rb
        else:
            b = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))  # batches run unloaded (throughput)
            b.replicate(rb, batch)
        b.color()
        self.model = b.finalize(device=device)
        self.device = self.model.device
        self.solver = newton.solvers.SolverVBD(self.model, iterations=config["iterations"])
        self.s0, self.s1, self.control = self.model.state(), self.model.state(), self.model.control()
        if points is not None:
            self._pose(points)
        self.tips = wp.array(np.arange(batch, dtype=np.int32) * self.bodies_per_rod + tip, dtype=wp.int32, device=self.device)
        self.tip_body = tip
        self.force = wp.vec3(*(problem.force if load else np.zeros(3)))
        self.loaded = bool(load and np.any(problem.force))
        self.substeps, self.iterations = config["substeps"], config["iterations"]
        self.dt = FRAME_DT / self.substeps
        self.frame_dt = FRAME_DT
        self.graph = None
        self.kernel = _tip_wrench_kernel()  # defined before a capture, which loads the modules that exist
        if self.device.is_cuda:
            # the graph replays fixed buffers: an even number of state swaps per frame ends where it began
            if self.substeps % 2:
                raise ValueError(f"substeps {self.substeps}: an even count is needed for the CUDA graph of a frame")
            with wp.ScopedCapture(device=self.device) as cap:
                self._substeps()
            self.graph = cap.graph

    def _pose(self, points):
        """Place every segment body along ``points`` [m], shape (segments + 1, 3), at rest."""
        q = self.s0.body_q.numpy()
        seg = np.diff(points, axis=0)
        for k in range(len(seg)):
            th = np.arctan2(seg[k, 1], seg[k, 0]) - np.arctan2(*(self._axis(q[k])[[1, 0]]))
            rz = np.array([0.0, 0.0, np.sin(th / 2), np.cos(th / 2)])
            q[k, 3:7] = _qmul(rz, q[k, 3:7])
            q[k, :3] = 0.5 * (points[k] + points[k + 1])
        self.s0.body_q.assign(q)

    @staticmethod
    def _axis(row):
        return _qrot(row[3:7], np.array([0.0, 0.0, 1.0]))

    def _substeps(self):
        import warp as wp

        for _ in range(self.substeps):
            self.s0.clear_forces()
            if self.loaded:
                wp.launch(self.kernel, dim=len(self.tips), inputs=[self.s0.body_q, self.tips, 0.5 * self.dl, self.force, self.s0.body_f], device=self.device)
            self.solver.step(self.s0, self.s1, self.control, None, self.dt)
            self.s0, self.s1 = self.s1, self.s0

    def frame(self):
        import warp as wp

        if self.graph is not None:
            wp.capture_launch(self.graph)
        else:
            self._substeps()

    def tip(self):
        row = self.s0.body_q.numpy()[self.tip_body]
        return row[:3] + 0.5 * self.dl * self._axis(row)

    def describe(self):
        return f"SolverVBD, {self.substeps} substeps x {self.iterations} iterations per 1/60 s frame"


def _qrot(q, v):
    """Rotate v by the unit quaternion q = (x, y, z, w)."""
    u, w = np.asarray(q[:3], dtype=np.float64), float(q[3])
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _qmul(a, b):
    """Quaternion product a * b, (x, y, z, w) layout."""
    av, aw, bv, bw = a[:3], a[3], b[:3], b[3]
    return np.concatenate([aw * bv + bw * av + np.cross(av, bv), [aw * bw - np.dot(av, bv)]])


def static(problem: RodProblem, config: dict, device: str, duration: float) -> dict:
    return track_static(lambda: _Run(problem, config, device), problem, duration)


def frequency(problem: RodProblem, config: dict, device: str) -> dict:
    behind = 1 if config.get("clamp") == "behind" else 0
    pts, _ = mode1_centerline(problem, config["segments"], behind, FREQUENCY_AMPLITUDE)
    run = _Run(problem, config, device, damping_ratio=0.0, load=False, points=pts)
    period = 2 * np.pi / problem.omega1

    def step():
        run.frame()
        return float(run.tip()[1])

    return {"frequency_error": measure_frequency(step, problem, FRAME_DT, FREQUENCY_PERIODS * period)}


def throughput(problem: RodProblem, config: dict, batch: int, device: str, min_time: float = 0.5) -> dict:
    """Rod-steps per wall second of ``batch`` rods, one world each (damped, unloaded)."""
    import warp as wp

    t0 = time.perf_counter()
    run = _Run(problem, config, device, batch=batch, load=False)
    setup = time.perf_counter() - t0
    run.frame()
    wp.synchronize_device(run.device)
    frames, t0 = 0, time.perf_counter()
    while frames < 2 or time.perf_counter() - t0 < min_time:
        run.frame()
        frames += 1
        wp.synchronize_device(run.device)
    wall = time.perf_counter() - t0
    return dict(rod_steps_per_s=batch * frames * run.substeps / wall, rod_seconds_per_s=batch * frames * FRAME_DT / wall, dt=run.dt, setup_time=setup)


def warmup(device: str) -> None:
    """Compile (or load from Warp's cache) Newton's kernels."""
    from ..problems import cantilever

    static(cantilever(2.0), {"segments": 4, "substeps": 2, "iterations": 1}, device, 2 * FRAME_DT)
