"""warp_tube on the benchmark problems, through the ``warp_tube.Simulation`` API a user calls.

- :func:`static`: a static problem from rest, timed through ``Simulation.step`` and
  ``centerline_points`` (``api="simulation"``) or through the centerline solver's ``integrate``
  (``api="solver"``, what ``Simulation.step`` runs without its frame checks).
- :func:`frequency`: the first natural frequency, released in the first mode (solver API: a
  released bent tube gains kinetic energy with no work done, which ``Simulation`` treats as a
  blow-up).
- :func:`throughput`: tubes x substeps per wall second for a batch of identical tubes.

The clamp is two pinned points, the first segment lying behind the clamp (the scene contract's
``pinnedPoints = [0, 1]``).
"""

from __future__ import annotations

import time

import numpy as np

from .problems import FREQUENCY_AMPLITUDE, FREQUENCY_PERIODS, RodProblem, measure_frequency, mode1_centerline, track_static

NAME = "warp_tube"
#: frames per second of the static runs (the rate of ``scenes/cantilever.usda``).
FPS = 24.0


def available():
    """(True, "") : warp_tube is always there."""
    return True, ""


def versions() -> dict:
    import warp as wp

    from ..version import __version__

    return {"warp_tube": __version__, "warp-lang": wp.config.version}


def scene(problem: RodProblem, segments: int, damping: float, duration: float, world_frames: float = FPS, load: bool = True):
    """The problem as a :class:`~warp_tube.scene.spec.Scene` of one tube (metres, SI)."""
    from ..scene.spec import ForceSpec, Scene, SimulationSettings, StageInfo, TubeParams, TubeSpec

    pts = problem.rest_centerline(segments, behind=1)
    tube = TubeSpec("/World/Tube", pts, [len(pts)], np.full(len(pts), problem.radius),
                    TubeParams(density=problem.density, youngs_modulus=problem.youngs_modulus, damping=damping), pinned=[0, 1])  # fmt: skip
    forces = ()
    if load and np.any(problem.force):
        forces = (ForceSpec("/World/Push", 0, len(pts) - 1, [0.0], [problem.force], assistant_line=False),)
    gravity = (0.0, -problem.gravity, 0.0) if problem.gravity else None
    stage = StageInfo(meters_per_unit=1.0, time_codes_per_second=world_frames, frames_per_second=world_frames,
                      end_time_code=round(duration * world_frames), authored=("metersPerUnit",))  # fmt: skip
    return Scene((tube,), forces, SimulationSettings(gravity=gravity), stage)


class _SimulationRun:
    def __init__(self, problem, segments, device, duration):
        from ..sim.simulation import Simulation

        self.sim = Simulation(scene(problem, segments, problem.damping, duration), device=device, surface=False)
        self.frame_dt = self.sim.frame_dt

    def frame(self):
        self.sim.step()

    def tip(self):
        return self.sim.centerline_points()[0][-1]

    def describe(self):
        return f"{self.sim.integrator}, {self.sim.substeps} substeps per 1/{FPS:g} s frame"


class _SolverRun:
    """The same scene advanced by the centerline solver directly, one frame's substeps a call."""

    def __init__(self, problem, segments, device, duration):
        from ..centerline.explicit import SemiImplicitEulerSolver
        from ..centerline.stability import critical_time_step
        from ..model.tube import build_model
        from ..centerline.policy import SAFETY

        sc = scene(problem, segments, problem.damping, duration)
        self.model = m = build_model(sc, device=device)
        self.solver = SemiImplicitEulerSolver(m)
        self.frame_dt = sc.stage.frame_dt
        self.substeps = int(np.ceil(self.frame_dt / (SAFETY * critical_time_step(m.host)) - 1e-9))
        self.state, self.other, self.control = m.state(), m.state(), m.control()
        if np.any(problem.force):
            f = np.zeros((1, m.node_count, 3))
            f[0, -1] = problem.force
            self.control.node_f_ext.assign(f)

    def frame(self):
        self.solver.integrate(self.state, self.other, self.control, self.frame_dt / self.substeps, self.substeps)
        self.state, self.other = self.other, self.state

    def tip(self):
        return self.state.node_q.numpy()[0, -1]

    def describe(self):
        return f"semiImplicitEuler, {self.substeps} substeps per 1/{FPS:g} s frame"


def static(problem: RodProblem, config: dict, device: str, duration: float) -> dict:
    """Time to the answer and final error of ``problem`` with ``config`` (``segments``, ``api``)."""
    cls = _SolverRun if config.get("api") == "solver" else _SimulationRun
    if cls is _SolverRun and problem.gravity:
        raise ValueError("the solver-API run takes no gravity")
    return track_static(lambda: cls(problem, config["segments"], device, duration), problem, duration)


def frequency(problem: RodProblem, config: dict, device: str) -> dict:
    """First natural frequency error of the undamped tube released in its first mode."""
    from ..centerline.explicit import SemiImplicitEulerSolver
    from ..centerline.stability import critical_time_step
    from ..model.tube import build_model
    from ..centerline.policy import SAFETY

    n = config["segments"]
    model = build_model(scene(problem, n, 0.0, 1.0, load=False), device=device)
    solver = SemiImplicitEulerSolver(model)
    dt = SAFETY * critical_time_step(model.host)
    pts, _ = mode1_centerline(problem, n, 1, FREQUENCY_AMPLITUDE)
    state, other, control = model.state(), model.state(), model.control()
    hi = pts.astype(np.float32)
    state.node_q.assign(hi[None])
    state.node_q_lo.assign((pts - hi).astype(np.float32)[None])
    period = 2 * np.pi / problem.omega1
    chunk = max(1, int(period / dt / 400))
    box = [state, other]

    def step():
        solver.integrate(box[0], box[1], control, dt, chunk)
        box.reverse()
        return float(box[0].node_q.numpy()[0, -1, 1])

    return {"frequency_error": measure_frequency(step, problem, dt * chunk, FREQUENCY_PERIODS * period)}


def throughput(problem: RodProblem, config: dict, batch: int, device: str, min_time: float = 0.5) -> dict:
    """Tube-steps per wall second of ``batch`` identical tubes (``api``: ``solver`` or ``simulation``).

    Times whole frames of 1/24 s (the solver's frame of substeps in one call, as ``Simulation.step``
    runs it) after one warm-up frame, until ``min_time`` [s] has passed (at least 2 frames).
    Returns ``rod_steps_per_s`` (tubes x substeps / s), ``rod_seconds_per_s`` (tubes x simulated
    seconds / wall second), ``dt`` [s] and ``setup_time`` [s].
    """
    import warp as wp

    from ..sim.simulation import Simulation

    t0 = time.perf_counter()
    sim = Simulation(scene(problem, config["segments"], problem.damping, 1.0), device=device, world_count=batch, surface=False)
    setup = time.perf_counter() - t0
    if config.get("api") == "solver":
        box = [sim.state, sim.next_state]

        def frame():
            sim.solver.integrate(box[0], box[1], sim.control, sim.dt, sim.substeps)
            box.reverse()
    else:
        frame = sim.step
    frame()
    wp.synchronize_device(sim.device)
    frames, t0 = 0, time.perf_counter()
    while frames < 2 or time.perf_counter() - t0 < min_time:
        frame()
        frames += 1
        wp.synchronize_device(sim.device)
    wall = time.perf_counter() - t0
    return dict(rod_steps_per_s=batch * frames * sim.substeps / wall, rod_seconds_per_s=batch * frames * sim.frame_dt / wall,
                dt=sim.dt, setup_time=setup)  # fmt: skip


def warmup(device: str) -> None:
    """Compile (or load from Warp's kernel cache) every kernel the runs use."""
    from .problems import CURVED, cantilever

    import dataclasses

    from ..sim.simulation import Simulation

    p = cantilever(2.0)
    static(p, {"segments": 4}, device, 2.0 / FPS)
    static(CURVED, {"segments": 4}, device, 2.0 / FPS)
    # `auto` takes implicit Euler for the finer tubes: its kernels too (each problem's features).
    for problem in (p, CURVED):
        sc = scene(problem, 4, problem.damping, 2.0 / FPS)
        sc = dataclasses.replace(sc, settings=dataclasses.replace(sc.settings, integrator="implicitEuler"))
        sim = Simulation(sc, device=device, surface=False)
        sim.step()
        sim.step()
    static(p, {"segments": 4, "api": "solver"}, device, 2.0 / FPS)
    throughput(p, {"segments": 4}, 2, device, min_time=0.0)
