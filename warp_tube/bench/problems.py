"""Builders shared by the benchmark problems and the tests: a clamped straight rod and a settle loop."""

from __future__ import annotations

import numpy as np


def straight_points(n_points, length, pinned_behind=True):
    """Points along +x; with ``pinned_behind`` the first segment lies behind x = 0 (a clamp)."""
    l = length / (n_points - 2 if pinned_behind else n_points - 1)
    x = (np.arange(n_points) - (1 if pinned_behind else 0)) * l
    return np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)


def settle(sim_solver, model, state, control, dt, chunk, tol, max_chunks=4000, average=10):
    """Equilibrium positions [m], shape (world, node, 3), of a damped run.

    Runs ``chunk`` substeps at a time until the largest node move per chunk is below ``tol`` [m],
    then averages the positions over ``average`` more chunks (a float32 state keeps jittering by
    ~1e-6 of its size around equilibrium).
    """
    other = model.state()
    prev = state.node_q.numpy().copy()
    for _ in range(max_chunks):
        sim_solver.integrate(state, other, control, dt, chunk)
        state, other = other, state
        q = state.node_q.numpy()
        if np.abs(q - prev).max() < tol:
            acc = np.zeros_like(q, dtype=np.float64)
            for _ in range(average):
                sim_solver.integrate(state, other, control, dt, chunk)
                state, other = other, state
                acc += state.node_q.numpy()
            return acc / average
        prev = q.copy()
    raise AssertionError("did not settle")




# -- the fixed problem set of ``warp-tube bench`` ----------------------------------------------------

from dataclasses import dataclass  # noqa: E402

#: an answer counts when the tip is within this fraction of the tube's length of the reference.
ANSWER_TOLERANCE = 2.0e-3
#: mass-proportional damping of the static problems, as a fraction of critical damping of the
#: first bending mode (every code gets the same modal damping ratio).
DAMPING_RATIO = 0.75


@dataclass(frozen=True)
class RodProblem:
    """A planar tube clamped at the origin along +x, loaded at its free end (SI units).

    Attributes:
        name: short name used in tables and ``results.json``.
        length: free length L [m] (from the clamp to the tip).
        radius: cross-section radius r [m] (solid circular section).
        youngs_modulus: E [Pa].
        density: rho [kg/m^3].
        rest_curvature: uniform rest curvature [1/m] in the xy-plane (0: straight).
        gravity: acceleration along -y [m/s^2] (0: none).
        tip_force: dead load at the tip in units of EI / L^2, (x, y).
    """

    name: str
    length: float
    radius: float
    youngs_modulus: float
    density: float
    rest_curvature: float = 0.0
    gravity: float = 0.0
    tip_force: tuple = (0.0, 0.0)

    @property
    def area(self) -> float:
        """Cross-section area [m^2]."""
        return np.pi * self.radius**2

    @property
    def EI(self) -> float:
        """Bending stiffness [N m^2]."""
        return self.youngs_modulus * np.pi * self.radius**4 / 4.0

    @property
    def EA(self) -> float:
        """Axial stiffness [N]."""
        return self.youngs_modulus * self.area

    @property
    def mass_per_length(self) -> float:
        """[kg/m]."""
        return self.density * self.area

    @property
    def omega1(self) -> float:
        """First bending angular frequency of the straight clamped-free beam [rad/s]."""
        from .references import BETA1

        return BETA1**2 * np.sqrt(self.EI / (self.mass_per_length * self.length**4))

    @property
    def damping(self) -> float:
        """Mass-proportional damping coefficient [1/s] giving :data:`DAMPING_RATIO` on mode 1."""
        return 2.0 * DAMPING_RATIO * self.omega1

    @property
    def static_duration(self) -> float:
        """Simulated time of a static run [s]: the first mode's transient decays to ~4e-6 of the
        load's deflection (exp(-12.5)); 15 s for the cantilever."""
        return 12.5 / (DAMPING_RATIO * self.omega1)

    @property
    def force(self) -> np.ndarray:
        """Tip force [N], shape (3,)."""
        return np.array([self.tip_force[0], self.tip_force[1], 0.0]) * self.EI / self.length**2

    def reference_tip(self) -> np.ndarray:
        """Equilibrium tip (x, y) [m] from :func:`~warp_tube.bench.references.planar_rod_tip`."""
        from .references import planar_rod_tip

        return planar_rod_tip(self.length, self.EI, self.EA, self.rest_curvature,
                              self.mass_per_length * self.gravity, self.force[:2])  # fmt: skip

    def rest_centerline(self, segments: int, behind: int = 0) -> np.ndarray:
        """Rest points [m], shape (segments + 1 + behind, 3): ``segments`` equal free segments from
        the clamp at the origin, plus ``behind`` segments of the same length straight behind it
        along -x (a clamp modelled as pinned points or a fixed body)."""
        ds = self.length / segments
        s = np.arange(-behind, segments + 1) * ds
        k = self.rest_curvature
        pts = np.zeros((len(s), 3))
        free = s > 0
        pts[~free, 0] = s[~free]
        if k == 0.0:
            pts[free, 0] = s[free]
        else:
            pts[free, 0] = np.sin(k * s[free]) / k
            pts[free, 1] = (1.0 - np.cos(k * s[free])) / k
        return pts


def cantilever(load: float) -> RodProblem:
    """The elastica benchmark: L = 1 m, r/L = 0.02, E = 1 MPa, 1000 kg/m^3, tip load PL^2/EI =
    ``load`` along -y, no gravity."""
    return RodProblem(f"cantilever PL^2/EI={load:g}", 1.0, 0.02, 1.0e6, 1000.0, tip_force=(0.0, -float(load)))


#: a curved tube under gravity and a push: L = 0.2 m, r = 1 cm, E = 1 MPa, 1000 kg/m^3, rest curvature
#: 1 rad over its length (bending up), gravity 9.81 m/s^2 (weight w L^3 / EI = 3.14) and an upward push
#: 1.5 EI / L^2 at the tip.
CURVED = RodProblem("curved tube, gravity and push", 0.2, 0.01, 1.0e6, 1000.0, rest_curvature=5.0, gravity=9.81, tip_force=(0.0, 1.5))
#: the static cantilever loads PL^2/EI of the accuracy suite.
CANTILEVER_LOADS = (1.0, 2.0, 5.0)
#: the problem of the frequency and throughput measurements (the straight cantilever, no load).
FREQUENCY_PROBLEM = cantilever(0.0)
#: frequency runs: release amplitude (tip, fraction of L) and simulated time [s] (2.2 periods).
FREQUENCY_AMPLITUDE = 1.0e-3
FREQUENCY_PERIODS = 2.2
#: batch sizes of the throughput sweep (tubes of 20 free segments), full and ``--quick``; 8,192 and
#: 16,384 cover the range where the GPU comparison with Newton is made.
BATCH_SIZES = (1, 8, 64, 512, 4096, 8192, 16384, 65536)
QUICK_BATCH_SIZES = (1, 8, 64)


def mode1_centerline(problem: RodProblem, segments: int, behind: int, amplitude: float) -> tuple[np.ndarray, np.ndarray]:
    """A straight cantilever bent into its first mode without stretching it.

    Returns points [m], shape (segments + 1 + behind, 3), and the tangent angle of each segment
    [rad], shape (segments + behind,): each free segment keeps its length and turns to the mode's
    slope at its midpoint; the tip is displaced by about ``amplitude`` L along +y.
    """
    from .references import mode1

    pts = problem.rest_centerline(segments, behind)
    L = problem.length
    ds = L / segments
    mid = (np.arange(segments) + 0.5) * ds / L
    h = 1e-6
    theta_free = np.arctan(amplitude * (mode1(mid + h) - mode1(mid - h)) / (2 * h))
    theta = np.concatenate([np.zeros(behind), theta_free])
    start = behind
    pts[start + 1 :, 0] = np.cumsum(ds * np.cos(theta_free))
    pts[start + 1 :, 1] = np.cumsum(ds * np.sin(theta_free))
    return pts, theta


@dataclass
class Trace:
    """Tip error against wall time of one run: ``wall`` [s] since the run's start (set-up included)
    and ``error`` [fraction of L], one per frame, shape (F,) each."""

    wall: list
    error: list

    def answer_time(self, tol: float = ANSWER_TOLERANCE) -> float | None:
        """Wall time [s] of the first frame from which the error stays within ``tol`` to the end of
        the run, or None when the last frame is outside."""
        err = np.asarray(self.error)
        if len(err) == 0 or not err[-1] <= tol:
            return None
        bad = np.nonzero(~(err <= tol))[0]
        k = 0 if len(bad) == 0 else int(bad[-1]) + 1
        return float(self.wall[k])


def track_static(build, problem: RodProblem, duration: float) -> dict:
    """Run a static problem from rest with its load applied at t = 0 and time it.

    ``build()`` returns a runner with ``frame_dt`` [s], ``frame()`` (advance one frame) and
    ``tip()`` (tip (x, y) [m]), and optionally ``describe()`` (a line on how it was set up). Timed from before ``build()``: set-up, frames and reading the tip
    every frame are all in the wall time. Returns ``error`` (final tip error / L), ``answer_time``
    [s] (or None), ``setup_time`` [s], ``run_wall`` (the whole run [s]), ``wall_per_simulated_s`` and
    ``frames``.
    """
    import time

    ref = problem.reference_tip()
    t0 = time.perf_counter()
    run = build()
    setup = time.perf_counter() - t0
    frames = int(round(duration / run.frame_dt))
    trace = Trace([], [])
    for _ in range(frames):
        run.frame()
        tip = np.asarray(run.tip(), dtype=np.float64)
        trace.wall.append(time.perf_counter() - t0)
        trace.error.append(float(np.linalg.norm(tip[:2] - ref) / problem.length))
    total = trace.wall[-1]
    out = dict(error=trace.error[-1], answer_time=trace.answer_time(), setup_time=setup, run_wall=total,
               wall_per_simulated_s=(total - setup) / (frames * run.frame_dt), frames=frames)  # fmt: skip
    if hasattr(run, "describe"):
        out["setup"] = run.describe()
    return out


def measure_frequency(step, problem: RodProblem, dt: float, duration: float) -> float:
    """Relative error of the first natural frequency against Euler-Bernoulli.

    ``step()`` advances ``dt`` [s] and returns the tip's y [m]; the frequency is the mean spacing
    of the tip's upward zero crossings (linearly interpolated) over ``duration`` [s].
    """
    n = int(duration / dt)
    ys = np.array([step() for _ in range(n)])
    t = np.arange(1, n + 1) * dt
    i = np.nonzero((ys[:-1] < 0) & (ys[1:] >= 0))[0]
    if len(i) < 2:
        raise RuntimeError(f"frequency: {len(i)} upward zero crossings in {duration:g} s, need 2")
    tc = t[i] + (t[i + 1] - t[i]) * (-ys[i]) / (ys[i + 1] - ys[i])
    f = (len(tc) - 1) / (tc[-1] - tc[0])
    return float(f / (problem.omega1 / (2 * np.pi)) - 1.0)
