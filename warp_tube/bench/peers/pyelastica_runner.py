"""PyElastica (Cosserat rods, CPU, NumPy + Numba) on the benchmark problems.

Set-up as PyElastica's documentation and examples recommend (the Timoshenko beam tutorial):
``CosseratRod.straight_rod`` (or its ``position``/``directors`` arguments for a curved rod, with
``rest_kappa`` set to the initial curvature), ``OneEndFixedBC`` on the first node and director,
``EndpointForces`` at the tip (ramped over one time step, the shortest ramp it accepts),
``GravityForces``, ``AnalyticalLinearDamper`` with ``uniform_damping_constant`` (mass-proportional
damping [1/s], the same as warp_tube's), ``PositionVerlet`` (the suggested default stepper), default
shear modulus E / 3. The time step is ``cfl x dl / sqrt(E / rho)``; 0.5 is the largest of 0.5 / 0.9
that stays stable here (the tutorial's ``dt = 0.07 dl`` is 0.99 of that for its material).

Clamps (``clamp`` in a configuration):

- ``"documented"``: the rod starts at the clamp and ``OneEndFixedBC`` fixes its first node and
  first director, as in the examples. The first element cannot turn, so the rod bends from its
  second node on: the tip error falls only as 1 / segments.
- ``"behind"`` (tuned by hand): one more element lies behind the clamp (fixed as above) and the
  bending stiffness of the first Voronoi region is doubled, since half of it lies in the rigid
  element. This is the clamp warp_tube itself uses (a rigid segment behind two pinned points);
  the tip error then falls as 1 / segments^2.
"""

from __future__ import annotations

import time

import numpy as np

from ..problems import FREQUENCY_AMPLITUDE, FREQUENCY_PERIODS, RodProblem, measure_frequency, mode1_centerline, track_static

NAME = "pyelastica"
#: frame at which the tip is read [s]
FRAME_DT = 1.0 / 60.0


def available():
    """(installed, why not)."""
    try:
        import elastica  # noqa: F401
    except Exception as e:  # noqa: BLE001 (any import failure means "not available", said in the report)
        return False, (f"PyElastica not importable ({type(e).__name__}: {e}); install it with "
                       'pip install "warp-tube[peers]" (from a checkout: pip install -e ".[peers]")')
    return True, ""


def versions() -> dict:
    from importlib.metadata import version

    return {"pyelastica": version("pyelastica"), "numba": version("numba")}


def _directors(theta: np.ndarray) -> np.ndarray:
    """Directors, shape (3, 3, E): rows d1 = +z (normal), d2 = d3 x d1, d3 = tangent at angle theta in the xy-plane."""
    c, s = np.cos(theta), np.sin(theta)
    d = np.zeros((3, 3, len(theta)))
    d[0, 2] = 1.0
    d[1, 0], d[1, 1] = s, -c
    d[2, 0], d[2, 1] = c, s
    return d


def _build(problem: RodProblem, config: dict, damping: float, load: bool, points=None):
    """(simulator, rod, dt): the problem as a PyElastica system, finalized."""
    import elastica as ea

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    n = config["segments"]
    behind = 1 if config.get("clamp") == "behind" else 0
    if points is None:
        points = problem.rest_centerline(n, behind)
    seg = np.diff(points, axis=0)
    theta = np.arctan2(seg[:, 1], seg[:, 0])
    dl = problem.length / n
    dt0 = config.get("cfl", 0.5) * dl / np.sqrt(problem.youngs_modulus / problem.density)
    dt = FRAME_DT / int(np.ceil(FRAME_DT / dt0))
    sim = Sim()
    rest = problem.rest_centerline(n, behind)
    rod = ea.CosseratRod.straight_rod(
        n + behind, rest[0].copy(), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), problem.length + behind * dl,
        problem.radius, problem.density, youngs_modulus=problem.youngs_modulus,
        position=np.ascontiguousarray(points.T), directors=_directors(theta),
    )  # fmt: skip
    if problem.rest_curvature:
        from elastica._rotations import _inv_rotate

        rest_seg = np.diff(rest, axis=0)
        rest_dirs = _directors(np.arctan2(rest_seg[:, 1], rest_seg[:, 0]))
        rod.rest_kappa[:] = _inv_rotate(rest_dirs) / rod.rest_voronoi_lengths
    if behind:
        rod.bend_matrix[..., 0] *= 2.0
    sim.append(rod)
    if damping:
        sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=damping, time_step=dt)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
    if load and np.any(problem.force):
        sim.add_forcing_to(rod).using(ea.EndpointForces, np.zeros(3), problem.force.copy(), ramp_up_time=dt)
    if load and problem.gravity:
        sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0.0, -problem.gravity, 0.0]))
    sim.finalize()
    return sim, rod, dt


class _Run:
    def __init__(self, problem, config):
        import elastica as ea

        self.sim, self.rod, self.dt = _build(problem, config, problem.damping, True)
        self.stepper = ea.PositionVerlet()
        self.steps = int(round(FRAME_DT / self.dt))
        self.frame_dt = FRAME_DT
        self.t = 0.0

    def frame(self):
        for _ in range(self.steps):
            self.t = self.stepper.step(self.sim, self.t, self.dt)

    def tip(self):
        return self.rod.position_collection[:, -1]

    def describe(self):
        return f"PositionVerlet, {self.steps} steps per 1/60 s frame (dt {self.dt:.3g} s)"


def static(problem: RodProblem, config: dict, device: str, duration: float) -> dict:
    """Time to the answer and final error (the CPU always: PyElastica has no GPU path)."""
    return track_static(lambda: _Run(problem, config), problem, duration)


def frequency(problem: RodProblem, config: dict, device: str) -> dict:
    import elastica as ea

    n = config["segments"]
    behind = 1 if config.get("clamp") == "behind" else 0
    pts, _ = mode1_centerline(problem, n, behind, FREQUENCY_AMPLITUDE)
    sim, rod, dt = _build(problem, config, 0.0, False, points=pts)
    stepper = ea.PositionVerlet()
    period = 2 * np.pi / problem.omega1
    chunk = max(1, int(period / dt / 400))
    clock = [0.0]

    def step():
        for _ in range(chunk):
            clock[0] = stepper.step(sim, clock[0], dt)
        return float(rod.position_collection[1, -1])

    return {"frequency_error": measure_frequency(step, problem, dt * chunk, FREQUENCY_PERIODS * period)}


def throughput(problem: RodProblem, config: dict, batch: int, device: str, min_time: float = 0.5) -> dict:
    """Rod-steps per wall second of ``batch`` rods in one simulator (damped, unloaded)."""
    import elastica as ea

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Damping):
        pass

    t0 = time.perf_counter()
    n = config["segments"]
    dl = problem.length / n
    dt = config.get("cfl", 0.5) * dl / np.sqrt(problem.youngs_modulus / problem.density)
    sim = Sim()
    for k in range(batch):
        rod = ea.CosseratRod.straight_rod(n, np.array([0.0, 0.0, 0.1 * k]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]),
                                          problem.length, problem.radius, problem.density, youngs_modulus=problem.youngs_modulus)  # fmt: skip
        sim.append(rod)
        sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=problem.damping, time_step=dt)
        sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
    sim.finalize()
    stepper = ea.PositionVerlet()
    setup = time.perf_counter() - t0
    t = stepper.step(sim, 0.0, dt)
    steps, t0 = 0, time.perf_counter()
    while steps < 2 or time.perf_counter() - t0 < min_time:
        t = stepper.step(sim, t, dt)
        steps += 1
    wall = time.perf_counter() - t0
    return dict(rod_steps_per_s=batch * steps / wall, rod_seconds_per_s=batch * steps * dt / wall, dt=dt, setup_time=setup)


def warmup(device: str) -> None:
    """Numba's compilation (cached on disk by PyElastica where it can)."""
    from ..problems import cantilever

    static(cantilever(2.0), {"segments": 6}, "cpu", 2 * FRAME_DT)
