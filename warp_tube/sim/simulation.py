"""Simulation: a scene advanced frame by frame, with output, progress and a run summary.

Time: output frame ``k`` is at time code ``startTimeCode + k`` (time ``k / timeCodesPerSecond``
[s]); frame 0 is the rest state. Each frame is advanced by ``substeps`` substeps of ``dt`` [s].
Point forces are evaluated at the middle of each frame and held over it. Time-sampled pins move
linearly between frames. The assistant line of a force is built (from the current shape) when the
force starts or turns by more than :data:`AL_REBUILD_ANGLE` from the direction it was built with,
and removed when the force becomes zero. It is offset along the force's part across the tube at
its point, and not built while the force is within :data:`AL_MIN_ANGLE` of the tube's axis.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ..model.tube import build_model
from ..scene.spec import Scene, SceneError
from ..centerline.explicit import SemiImplicitEulerSolver
from .proximity import ContactMonitor
from ..centerline.stability import critical_time_step

log = logging.getLogger(__name__)

__all__ = ["Simulation", "NumericalError", "RunSummary", "resolve_device"]

#: semi-implicit Euler runs at this fraction of its stability bound when it picks the substep.
SAFETY = 0.5
#: the assistant line is rebuilt when its force turns by more than this [rad].
AL_REBUILD_ANGLE = math.radians(45.0)
#: implicit Euler's default substep [s] (its numerical damping: 1.5% amplitude per period of a
#: 1 Hz mode at this step).
IMPLICIT_DT = 1.0 / 240.0
#: cost of an implicit substep over a semi-implicit one, per node (measured on the CPU: ~0.8 us
#: against ~0.05 us; benchmarks/bench_integrators.py).
IMPLICIT_COST_RATIO = 16.0
#: with assistant lines (solved with the centerline) the implicit substep costs this much more again
#: per line on a tube, relative to a semi-implicit substep with the same lines (measured on the CPU,
#: 41 points, one line: ~5.0 us against ~0.11 us per node, i.e. ~3 x IMPLICIT_COST_RATIO).
IMPLICIT_AL_COST = 3.0
#: the largest substep multiplier ``auto`` tries for a frame that blew up.
MAX_RETRY_FACTOR = 16
#: no assistant line is built for a force within this angle of the tube's axis [rad].
AL_MIN_ANGLE = math.radians(15.0)
#: a free point farther than this many tube lengths from its rest position is a blow-up.
RUNAWAY_LENGTHS = 1.0e3


def implicit_cost_ratio(model) -> float:
    """Cost of an implicit substep over a semi-implicit one for ``model`` (see the constants)."""
    lines = model.al_lines if model.features.assistant_line else 0
    return IMPLICIT_COST_RATIO * IMPLICIT_AL_COST**lines


class NumericalError(RuntimeError):
    """The state became non-finite or ran away (CLI exit status 3)."""


def resolve_device(device=None) -> str:
    """``None`` -> the first CUDA device if there is one, else ``cpu``; checks a named device."""
    wp.init()
    if device is None:
        return "cuda:0" if wp.get_cuda_device_count() > 0 else "cpu"
    name = str(device)
    if name.startswith("cuda"):
        count = wp.get_cuda_device_count()
        idx = int(name.split(":")[1]) if ":" in name else 0
        if idx >= count:
            raise SceneError(f"device {name}: no such CUDA device ({count} found): use --device cpu")
        return f"cuda:{idx}"
    if name != "cpu":
        raise SceneError(f"device {name!r}: expected cpu or cuda:N")
    return name


@dataclass
class RunSummary:
    """What a run did (printed by the CLI)."""

    scene: str
    device: str
    frames: int
    substeps: int
    dt: float
    integrator: str
    reason: str
    wall_time: float
    max_displacement: float
    output: str | None = None
    stopped: str | None = None
    warnings: list = field(default_factory=list)
    stage_defaults: list = field(default_factory=list)

    @property
    def steps_per_second(self) -> float:
        return self.frames_simulated * self.substeps / self.wall_time if self.wall_time > 0 else float("nan")

    frames_simulated: int = 0

    def text(self) -> str:
        lines = [
            f"scene        {self.scene}",
            f"device       {self.device}",
            f"frames       {self.frames} written ({self.frames_simulated} simulated)",
            f"integrator   {self.integrator}: {self.reason}",
            f"substeps     {self.substeps} per frame, dt = {self.dt:.3g} s",
            f"wall time    {self.wall_time:.3f} s ({self.steps_per_second:,.0f} substeps/s)",
            f"largest displacement  {self.max_displacement:.4g} m",
        ]
        if self.stage_defaults:
            lines.append("stage        unauthored, USD fallback used: " + ", ".join(self.stage_defaults))
        if self.output:
            lines.append(f"output       {self.output}")
        lines += [f"warning      {w}" for w in self.warnings]
        if self.stopped:
            lines.append(f"stopped      {self.stopped}")
        return "\n".join(lines)


class Simulation:
    """A scene on a device, advanced one output frame per :meth:`step`.

    Args:
        scene: the scene.
        device: "cpu", "cuda:N" or None (CUDA when available).
        world_count: copies of the scene run side by side (batch layout), each with the same input.
        surface: build the hubs-and-spokes surface (needed for :meth:`surface_points` and output).
    """

    def __init__(self, scene: Scene, device=None, world_count: int = 1, surface: bool = True):
        self.scene = scene
        self.device = resolve_device(device)
        self.model = build_model(scene, world_count=world_count, device=self.device)
        m = self.model
        self.frame_dt = scene.stage.frame_dt
        spring_damping = max((t.params.spring_damping for t in scene.tubes), default=0.0)
        self.critical_dt = critical_time_step(m.host, m.features.assistant_line, spring_damping)
        self.integrator, self.reason, dt = self._choose_integrator()
        self.substeps = max(1, math.ceil(self.frame_dt / dt - 1e-9))
        self.dt = self.frame_dt / self.substeps
        if self.integrator == "implicitEuler":
            from ..centerline.implicit import ImplicitEulerSolver

            self.solver = ImplicitEulerSolver(m)
        else:
            self.solver = SemiImplicitEulerSolver(m)
        self.state, self.next_state = m.state(), m.state()
        self.control = m.control()
        self.frame = 0
        self.warnings: list[str] = []
        self._force_override: dict[int, np.ndarray] = {}
        self._pin_override: dict[int, np.ndarray] = {}
        self._al_dir = np.zeros((m.force_count, 3))
        self._extent = max(float(np.ptp(t.points, axis=0).max()) for t in scene.tubes)
        self._prim_start = m.host["prim_node_start"]
        self._prim_count = [len(t.points) for t in scene.tubes]
        self.surfaces = self._build_surfaces() if surface else None
        self._pinned_nodes = [self._prim_start[k] + t.pinned for k, t in enumerate(scene.tubes)]
        self._contacts = ContactMonitor(m.host)
        self._contact_reported = False
        self._retry = self.scene.settings.integrator == "auto"
        self._work = np.zeros(world_count)
        # float32 round-off moves points by ~1e-7 of their coordinates; springs strained that much
        # (with a 10x margin) hold the energy below which nothing counts as a blow-up.
        scale = max(self._extent, float(np.abs(m.host["node_rest_q"]).max()), 1e-9)
        self._energy_floor = float(np.sum(m.host["seg_ke"])) * (1e-6 * scale) ** 2 + 1e-30
        self._moving_pins = any(t.pin_track is not None for t in scene.tubes)
        self._free_mass = m.host["node_mass"] * (m.host["node_inv_mass"] > 0)
        self._rest32 = m.host["node_rest_q"].astype(np.float32)[None]
        self.retried_frames = 0
        self.max_retry_factor = 1

    # -- set-up ----------------------------------------------------------------------------------
    def _choose_integrator(self):
        """(integrator, reason, substep [s]) for the scene's settings; see the README."""
        s = self.scene.settings
        hc = self.critical_dt
        semi_dt = SAFETY * hc
        if s.integrator == "implicitEuler":
            dt = min(s.time_step or IMPLICIT_DT, self.frame_dt)
            return "implicitEuler", f"from the scene, substep {dt:.3g} s", dt
        if s.integrator == "semiImplicitEuler":
            if s.time_step is not None:
                dt = min(s.time_step, self.frame_dt)
                if dt > hc:
                    log.warning("timeStep %.3g s exceeds the semi-implicit Euler stability bound %.3g s: expect a blow-up", dt, hc)
                    return "semiImplicitEuler", f"forced; timeStep {dt:.3g} s exceeds the stability bound {hc:.3g} s", dt
                return "semiImplicitEuler", f"from the scene, timeStep {dt:.3g} s (bound {hc:.3g} s)", dt
            if not math.isfinite(hc):
                return "semiImplicitEuler", "from the scene; nothing stiff: one substep per frame", self.frame_dt
            return "semiImplicitEuler", f"from the scene, substep {SAFETY:g} x the stability bound {hc:.3g} s", semi_dt
        # auto: the cheaper of the two, by the cost per substep and node measured for each.
        if not math.isfinite(hc):
            return "semiImplicitEuler", "auto: nothing stiff to bound the step, one substep per frame", self.frame_dt
        impl_dt = min(s.time_step or IMPLICIT_DT, self.frame_dt)
        semi_steps = math.ceil(self.frame_dt / semi_dt - 1e-9)
        impl_steps = math.ceil(self.frame_dt / impl_dt - 1e-9)
        if s.time_step is not None and s.time_step <= hc:
            return "semiImplicitEuler", f"auto: timeStep {s.time_step:.3g} s is within the stability bound {hc:.3g} s", s.time_step
        cost = implicit_cost_ratio(self.model)
        if impl_steps * cost < semi_steps:
            return "implicitEuler", (
                f"auto: stiff ({semi_steps} stable semi-implicit substeps a frame against {impl_steps} implicit "
                f"ones at ~{cost:g}x the cost each)"
            ), impl_dt
        why = f"cheaper than implicit ({impl_steps} substeps at ~{cost:g}x the cost)"
        return "semiImplicitEuler", f"auto: {semi_steps} substeps a frame at {SAFETY:g} x the stability bound {hc:.3g} s; {why}", semi_dt

    def _build_surfaces(self):
        from ..surface.builder import SurfaceBuilder

        out = []
        for k, t in enumerate(self.scene.tubes):
            lengths = t.spoke_lengths if t.spoke_lengths is not None else np.repeat(t.radius[:, None], t.params.spokes, axis=1)
            out.append(
                SurfaceBuilder(
                    tube_node_start=self._prim_start[k] + np.concatenate([[0], np.cumsum(t.curve_counts)]),
                    rest_q=t.points, spokes=t.params.spokes, spoke_lengths=lengths,
                    reference_normal=t.params.reference_normal, frames=t.params.frames, caps=t.params.caps,
                    world_count=1, device=self.device,
                )  # fmt: skip
            )
        return out

    # -- interactive control ---------------------------------------------------------------------
    def set_force(self, force, vector) -> None:
        """Override a scene force from now on: ``force`` is its index or prim path; ``vector`` [N]."""
        idx = self._force_index(force)
        self._force_override[idx] = np.asarray(vector, dtype=np.float64).reshape(3)

    def set_pin_targets(self, tube, positions) -> None:
        """Move a tube prim's pinned points: ``positions`` [stage units], shape (pinned, 3)."""
        k = self._tube_index(tube)
        p = np.asarray(positions, dtype=np.float64) * self.scene.stage.meters_per_unit
        if p.shape != (len(self.scene.tubes[k].pinned), 3):
            raise ValueError(f"pin targets of {self.scene.tubes[k].path}: shape {p.shape}, expected ({len(self.scene.tubes[k].pinned)}, 3)")
        self._pin_override[k] = p
        self._moving_pins = True

    def _force_index(self, force) -> int:
        if isinstance(force, str):
            for k, f in enumerate(self.scene.forces):
                if f.path == force:
                    return k
            raise KeyError(f"no force at {force}")
        return int(force)

    def _tube_index(self, tube) -> int:
        if isinstance(tube, str):
            for k, t in enumerate(self.scene.tubes):
                if t.path == tube:
                    return k
            raise KeyError(f"no tube at {tube}")
        return int(tube)

    # -- stepping --------------------------------------------------------------------------------
    def _forces_at(self, t: float) -> np.ndarray:
        """Force of each model force (model order) at time t [s], shape (force_count, 3)."""
        order = self.model.host["force_order"]
        out = np.zeros((len(order), 3))
        for a, k in enumerate(order):
            out[a] = self._force_override.get(int(k), None) if int(k) in self._force_override else self.scene.forces[k].at(t)
        return out

    def _update_control(self):
        m, c = self.model, self.control
        W = m.world_count
        if m.force_count:
            f = self._forces_at((self.frame + 0.5) * self.frame_dt)
            fe = np.zeros((m.node_count, 3))
            np.add.at(fe, m.host["force_node"], f)
            c.node_f_ext.assign(np.repeat(fe[None], W, axis=0))
            if m.features.assistant_line:
                self._update_assistant_lines(f)
        if any(t.pin_track is not None for t in self.scene.tubes) or self._pin_override:
            q0 = c.pin_q_end.numpy()
            q1 = q0.copy()
            for k, t in enumerate(self.scene.tubes):
                nodes = self._pinned_nodes[k]
                if k in self._pin_override:
                    q1[:, nodes] = self._pin_override[k]
                elif t.pin_track is not None:
                    q1[:, nodes] = t.pin_track[min(self.frame + 1, len(t.pin_track) - 1)]
            c.pin_q_start.assign(q0)
            c.pin_q_end.assign(q1)

    def _update_assistant_lines(self, f: np.ndarray):
        m, c, h = self.model, self.control, self.model.host
        active = c.al_active.numpy()
        changed = False
        state_q = state_qd = None
        for a in range(m.force_count):
            if not h["force_uses_al"][a]:
                continue
            mag = float(np.linalg.norm(f[a]))
            if mag == 0.0:
                if active[:, a].any():
                    active[:, a] = 0
                    changed = True
                continue
            d = f[a] / mag
            if active[0, a] and float(np.dot(d, self._al_dir[a])) >= math.cos(AL_REBUILD_ANGLE):
                continue
            if state_q is None:
                state_q = self.state.node_q.numpy().astype(np.float64) + self.state.node_q_lo.numpy()
                state_qd = self.state.node_qd.numpy()
                al_q, al_qd = self.state.al_q.numpy().astype(np.float64), self.state.al_qd.numpy()
                lens = {n: getattr(c, n).numpy() for n in ("al_link_length", "al_chord_length", "al_fwd_length", "al_bwd_length")}
            t = h["force_tube"][a]
            s, e = h["tube_node_start"][t], h["tube_node_start"][t + 1]
            # Offset towards the push: the force's part across the tube at its point (world 0).
            k = h["force_node"][a]
            tangent = state_q[0, min(k + 1, e - 1)] - state_q[0, max(k - 1, s)]
            tangent = tangent / max(np.linalg.norm(tangent), 1e-30)
            across = d - np.dot(d, tangent) * tangent
            self._al_dir[a] = d
            if np.linalg.norm(across) < math.sin(AL_MIN_ANGLE):
                if active[:, a].any():
                    active[:, a] = 0
                    changed = True
                continue
            offset_dir = across / np.linalg.norm(across)
            p0 = h["al_start"][a]
            sl = slice(p0, p0 + e - s)
            off = h["node_radius"][s:e, None] * offset_dir[None]
            # Positions in float64 (compensated: float32 + low-order part), so the line is built
            # unstrained in the kernels' arithmetic.
            x = state_q[:, s:e]
            xp = x + off[None]
            al_q[:, sl] = xp
            al_qd[:, sl] = state_qd[:, s:e]
            lens["al_link_length"][:, sl] = np.linalg.norm(xp - x, axis=-1)
            chord = np.linalg.norm(xp[:, 1:] - xp[:, :-1], axis=-1)
            lens["al_chord_length"][:, p0 : p0 + e - s - 1] = chord
            lens["al_fwd_length"][:, p0 : p0 + e - s - 1] = np.linalg.norm(x[:, 1:] - xp[:, :-1], axis=-1)
            lens["al_bwd_length"][:, p0 + 1 : p0 + e - s] = np.linalg.norm(x[:, :-1] - xp[:, 1:], axis=-1)
            active[:, a] = 1
            changed = True
        if state_q is not None:
            hi = al_q.astype(np.float32)
            self.state.al_q.assign(hi)
            self.state.al_q_lo.assign((al_q - hi).astype(np.float32))
            self.state.al_qd.assign(al_qd)
            for n, v in lens.items():
                getattr(c, n).assign(v)
        if changed:
            c.al_active.assign(active)

    def step(self) -> None:
        """Advance one output frame (``substeps`` substeps).

        The frame is checked for a non-finite state, a point running away, and a kinetic energy
        above what the forces and gravity can have put in (a blow-up). With ``auto`` a failed frame
        is redone from its start with 2x, 4x, ... up to :data:`MAX_RETRY_FACTOR` x the substeps.

        Raises:
            NumericalError: the frame still fails; :attr:`state` keeps the last good frame.
        """
        self._update_control()
        factor = 1
        while True:
            n = self.substeps * factor
            self.solver.integrate(self.state, self.next_state, self.control, self.frame_dt / n, n)
            frame_work = self._frame_work(self.state, self.next_state)
            problem = self._check(self.next_state, factor, self._work + frame_work)
            if problem is None:
                break
            if not self._retry:
                raise NumericalError(problem)
            if factor < MAX_RETRY_FACTOR:
                factor *= 2
                continue
            if not self._switch_to_implicit(problem):
                raise NumericalError(problem)
            factor = 1
        if factor > 1:
            msg = f"frame {self.frame + 1}: redone with {factor}x the substeps to stay stable"
            log.info(msg)
            self.retried_frames += 1
            self.max_retry_factor = max(self.max_retry_factor, factor)
        self._work += frame_work
        self.state, self.next_state = self.next_state, self.state
        self.frame += 1
        if not self._contact_reported:
            self._report_contact()

    def _switch_to_implicit(self, problem: str) -> bool:
        """``auto``'s last resort for a frame semi-implicit Euler cannot take: implicit Euler
        from now on."""
        if self.integrator != "semiImplicitEuler":
            return False
        from ..centerline.implicit import ImplicitEulerSolver

        msg = (f"frame {self.frame + 1}: semi-implicit Euler failed even at {MAX_RETRY_FACTOR}x the substeps "
               f"({problem.split(': ', 1)[-1]}); switched to implicit Euler")  # fmt: skip
        log.warning(msg)
        self.warnings.append(msg)
        self.solver = ImplicitEulerSolver(self.model)
        self.integrator = "implicitEuler"
        self.reason += "; switched to implicitEuler after a blow-up"
        self.substeps = max(1, math.ceil(self.frame_dt / min(IMPLICIT_DT, self.frame_dt) - 1e-9))
        self.dt = self.frame_dt / self.substeps
        return True

    def _frame_work(self, before, after) -> np.ndarray:
        """Work [J] of the point forces and gravity from ``before`` to ``after``, per world
        (forces are held over a frame, so ``f . dx`` is exact for them)."""
        h = self.model.host
        w = np.zeros(self.model.world_count)
        if self.model.force_count:
            nodes = h["force_node"]
            dq = after.node_q.numpy()[:, nodes].astype(np.float64) - before.node_q.numpy()[:, nodes]
            f = self.control.node_f_ext.numpy()[:, nodes].astype(np.float64)
            w += np.einsum("wnk,wnk->w", f, dq)
        if self.model.features.gravity:
            # Gravity's work is g . (sum m x_after - sum m x_before): two weighted sums.
            m = self._free_mass
            g = np.array(self.scene.settings.gravity, dtype=np.float64)
            w += (np.einsum("n,wnk->wk", m, after.node_q.numpy()) - np.einsum("n,wnk->wk", m, before.node_q.numpy())) @ g
        return w

    def _report_contact(self):
        """Warn once when distant parts of tubes (world 0) come closer than two radii."""
        hit = self._contacts.closest(self.state.node_q.numpy()[0])
        if hit is None:
            return
        i, j, gap = hit
        name = lambda n: self._node_name(n)  # noqa: E731
        msg = (f"frame {self.frame}: {name(i)} and {name(j)} are {-gap:.3g} m closer than the sum of their "
               "radii (distant parts touch; contact is not modelled, so they pass through each other)")  # fmt: skip
        log.warning(msg)
        self.warnings.append(msg)
        self._contact_reported = True

    def _node_name(self, node: int) -> str:
        k = int(np.searchsorted(self._prim_start, node, side="right") - 1)
        return f"{self.scene.tubes[k].path} point {int(node - self._prim_start[k])}"

    def _check(self, state, factor: int = 1, work=None) -> str | None:
        """What is wrong with a frame's end state, or None; ``work``: per-world work done up to it."""
        q = state.node_q.numpy()
        h = self.model.host
        limit = RUNAWAY_LENGTHS * max(self._extent, 1e-9)
        # One pass for the common case: finite and nowhere near the runaway distance (NaN fails
        # the comparison, so it falls through to the detailed check).
        if not (np.abs(q - self._rest32).max() < limit):
            bad = ~np.isfinite(q).all(axis=-1)
            far = ~bad & (np.linalg.norm(q - h["node_rest_q"][None], axis=-1) > limit)
            if bad.any() or far.any():
                w, node = np.argwhere(bad | far)[0]
                what = "non-finite positions" if bad.any() else f"a point more than {RUNAWAY_LENGTHS:g} tube lengths from rest"
                return self._failure(what, int(node), factor)
        # Kinetic energy cannot exceed the work put in (the springs' energy is >= 0 and damping
        # only takes energy); 10x and a floor leave room for measurement error.
        qd = state.node_qd.numpy()
        ke = 0.5 * np.einsum("n,wnk,wnk->w", self._free_mass, qd, qd, dtype=np.float64)
        work = self._work if work is None else work
        budget = 10.0 * np.maximum(work, 0.0) + self._energy_floor + self._pin_energy_allowance()
        if not (ke > budget).any():
            return None
        hot = int(np.argmax(ke - budget))
        node = int(np.argmax(np.einsum("nk,nk->n", qd[hot], qd[hot]) * h["node_mass"]))
        return self._failure("kinetic energy beyond the work the forces did (a blow-up)", node, factor)

    def _failure(self, what: str, node: int, factor: int) -> str:
        """The message of a failed frame."""
        dt = self.frame_dt / (self.substeps * factor)
        hint = ""
        if dt > self.critical_dt:
            hint = f" (substep {dt:.3g} s exceeds the stability bound {self.critical_dt:.3g} s)"
        elif factor > 1:
            hint = f" (after {factor}x the substeps)"
        return f"numerical failure at frame {self.frame + 1}: {what} in {self._node_name(int(node))}{hint}"

    def _pin_energy_allowance(self) -> float:
        """Energy that moving pins can put in [J]: not tracked as work, so allowed for generously."""
        if not self._moving_pins:
            return 0.0
        return float(np.inf)

    # -- read-back -------------------------------------------------------------------------------
    def centerline_points(self, world: int = 0) -> list[np.ndarray]:
        """Centerline points per tube prim [stage units], each shape (P, 3)."""
        q = self.state.node_q.numpy()[world] / self.scene.stage.meters_per_unit
        return [q[s : s + n].copy() for s, n in zip(self._prim_start, self._prim_count)]

    def surface_points(self, world: int = 0) -> list[np.ndarray]:
        """Surface vertices per tube prim [stage units], each shape (V, 3)."""
        return [out[0] for out in self.surface(world)]

    def surface(self, world: int = 0):
        """Surface ``(points, normals, extent)`` per tube prim: points [stage units] and unit
        normals, each shape (V, 3), and the points' ``[min, max]`` corners [stage units], (2, 3)."""
        if self.surfaces is None:
            raise RuntimeError("this Simulation was made with surface=False")
        mpu = self.scene.stage.meters_per_unit
        q = self.state.node_q
        if q.shape[0] > 1:  # the builders serve one world: hand them that world's row
            q = wp.array(q.numpy()[world : world + 1], dtype=wp.vec3, device=self.device)
        out = []
        for b in self.surfaces:
            pts, nrm = b.compute(q)
            out.append((pts.numpy()[0] / mpu, nrm.numpy()[0], b.extent().numpy()[0] / mpu))
        return out

    def max_displacement(self) -> float:
        """Largest distance of a point from its rest position [m]."""
        q = self.state.node_q.numpy()
        return float(np.linalg.norm(q - self.model.host["node_rest_q"][None], axis=-1).max())

    # -- whole runs ------------------------------------------------------------------------------
    def run(self, frames: int | None = None, output: str | None = None, progress=None, every: int = 1) -> RunSummary:
        """Simulate ``frames`` output frames (default: the scene's) and write them to ``output``.

        Args:
            frames: number of frames, frame 0 (rest) included; default the scene's frame count.
            output: path of the output stage, or None to write nothing.
            progress: None, or True for a tqdm bar.
            every: write every ``every``-th frame.

        Raises:
            NumericalError: after writing the frames finished so far.
            KeyboardInterrupt: after writing the frames finished so far.
        """
        from ..io.writer import StageWriter

        info = self.scene.stage
        frames = info.frame_count if frames is None else int(frames)
        if frames < 1:
            raise SceneError(f"frames {frames}: expected at least 1")
        if every < 1:
            raise SceneError(f"every {every}: expected at least 1")
        writer = StageWriter(output, self.scene, self.surfaces) if output else None
        summary = RunSummary(
            scene=self.scene.source, device=self.device, frames=0, substeps=self.substeps, dt=self.dt,
            integrator=self.integrator, reason=self.reason, wall_time=0.0, max_displacement=0.0,
            output=writer.path if writer else None,
            stage_defaults=[k for k in ("metersPerUnit", "upAxis", "timeCodesPerSecond", "startTimeCode", "endTimeCode")
                            if k not in info.authored],
        )  # fmt: skip
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=frames - 1, unit="frame", desc="simulating", leave=False)
        t0 = time.perf_counter()
        try:
            for k in range(frames):
                if k > 0:
                    self.step()
                    summary.frames_simulated += 1
                    summary.max_displacement = max(summary.max_displacement, self.max_displacement())
                    if bar:
                        bar.update(1)
                if writer and k % every == 0:
                    writer.write_frame(info.start_time_code + k, self.centerline_points(),
                                       self.surface() if self.surfaces is not None else None)  # fmt: skip
                    summary.frames += 1
        except (NumericalError, KeyboardInterrupt) as e:
            summary.stopped = str(e) or "interrupted"
            raise
        finally:
            summary.wall_time = time.perf_counter() - t0
            if bar:
                bar.close()
            if writer:
                writer.close()
            summary.warnings = list(self.warnings)
            if self.retried_frames:
                summary.warnings.append(
                    f"{self.retried_frames} frame(s) blew up at {self.substeps} substeps and were redone with up to "
                    f"{self.max_retry_factor}x as many"
                )
            self.last_summary = summary
        return summary
