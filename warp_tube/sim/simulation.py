"""Simulation: a scene advanced frame by frame, with output, progress and a run summary.

The frame loop only: what drives a frame (forces, pins, the assistant line) is
:mod:`warp_tube.sim.control`, which integrator runs is :mod:`warp_tube.centerline.policy`, the
checks of each frame are :mod:`warp_tube.sim.checks`.

Time: output frame ``k`` is at time code ``startTimeCode + k`` (time ``k / timeCodesPerSecond``
[s]); frame 0 is the rest state. Each frame is advanced by ``substeps`` substeps of ``dt`` [s].
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ..centerline.explicit import SemiImplicitEulerSolver
from ..centerline.policy import choose_integrator, implicit_substeps
from ..centerline.stability import critical_time_step
from ..model.tube import build_model
from ..scene.spec import Scene, SceneError
from .checks import FrameChecks
from .control import FrameControl
from .proximity import ContactMonitor

log = logging.getLogger(__name__)

__all__ = ["Simulation", "NumericalError", "RunSummary", "resolve_device"]

#: the largest substep multiplier ``auto`` tries for a frame that blew up.
MAX_RETRY_FACTOR = 16


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
        choice = choose_integrator(scene.settings, self.critical_dt, self.frame_dt, m.features.assistant_line, scene.source)
        self.integrator, self.reason = choice.integrator, choice.reason
        self.substeps = max(1, math.ceil(self.frame_dt / choice.dt - 1e-9))
        self.dt = self.frame_dt / self.substeps
        if self.integrator == "implicitEuler":
            from ..centerline.implicit import ImplicitEulerSolver

            self.solver = ImplicitEulerSolver(m)
        else:
            self.solver = SemiImplicitEulerSolver(m)
        self.state, self.next_state = m.state(), m.state()
        self.control = m.control()
        self.controls = FrameControl(scene, m, self.control)
        self.frame = 0
        self.warnings: list[str] = []
        self._prim_start = m.host["prim_node_start"]
        self._prim_count = [len(t.points) for t in scene.tubes]
        self.surfaces = self._build_surfaces() if surface else None
        self._world_q = None  # one world's positions for the surface builders, (1, node_count)
        self._contacts = ContactMonitor(m.host, device=self.device)
        self._contact_reported = False
        self._retry = self.scene.settings.integrator == "auto"
        extent = max(float(np.ptp(t.points, axis=0).max()) for t in scene.tubes)
        # float32 round-off moves points by ~1e-7 of their coordinates; springs strained that much
        # (with a 10x margin) hold the energy below which nothing counts as a blow-up.
        scale = max(extent, float(np.abs(m.host["node_rest_q"]).max()), 1e-9)
        energy_floor = float(np.sum(m.host["seg_ke"])) * (1e-6 * scale) ** 2 + 1e-30
        gravity = scene.settings.gravity if m.features.gravity else None
        self.checks = FrameChecks(m, extent=extent, energy_floor=energy_floor, gravity=gravity)
        self.retried_frames = 0
        self.max_retry_factor = 1

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
        self.controls.set_force(force, vector)

    def set_pin_targets(self, tube, positions) -> None:
        """Move a tube prim's pinned points: ``positions`` [stage units], shape (pinned, 3)."""
        self.controls.set_pin_targets(tube, positions)

    # -- stepping --------------------------------------------------------------------------------
    def step(self) -> None:
        """Advance one output frame (``substeps`` substeps).

        The frame is checked for a non-finite state, a point running away, and a kinetic energy
        above what the forces and gravity can have put in (a blow-up; not checked while pinned
        points move, whose work is not measured). With ``auto`` a failed frame is redone from its
        start with 2x, 4x, ... up to :data:`MAX_RETRY_FACTOR` x the substeps, then, if
        semi-implicit Euler still fails, with implicit Euler for the rest of the run.

        Raises:
            NumericalError: the frame still fails; :attr:`state` keeps the last good frame.
        """
        self.controls.update(self.frame, self.state)
        self.checks.pin_allowance[:] = np.inf if self.controls.moving_pins else 0.0
        factor = 1
        while True:
            n = self.substeps * factor
            self.solver.integrate(self.state, self.next_state, self.control, self.frame_dt / n, n)
            failures, frame_work = self.checks.check(self.state, self.next_state, self.control)
            if not failures:
                break
            problem = self._failure(failures[0], factor)
            if not self._retry:
                raise NumericalError(problem)
            if factor < MAX_RETRY_FACTOR:
                factor *= 2
                continue
            if not self._switch_to_implicit(problem):
                raise NumericalError(problem)
            factor = 1
        if factor > 1:
            log.info("frame %d: redone with %dx the substeps to stay stable", self.frame + 1, factor)
            self.retried_frames += 1
            self.max_retry_factor = max(self.max_retry_factor, factor)
        self.checks.accept(frame_work)
        self.state, self.next_state = self.next_state, self.state
        self.frame += 1
        if not self._contact_reported:
            self._report_contact()

    def _switch_to_implicit(self, problem: str) -> bool:
        """``auto``'s last resort for a frame semi-implicit Euler cannot take: implicit Euler
        from now on (not with an assistant line, which only the semi-implicit solver has)."""
        if self.integrator != "semiImplicitEuler" or self.model.features.assistant_line:
            return False
        from ..centerline.implicit import ImplicitEulerSolver

        msg = (f"frame {self.frame + 1}: semi-implicit Euler failed even at {MAX_RETRY_FACTOR}x the substeps "
               f"({problem.split(': ', 1)[-1]}); switched to implicit Euler")  # fmt: skip
        log.warning(msg)
        self.warnings.append(msg)
        self.solver = ImplicitEulerSolver(self.model)
        self.integrator = "implicitEuler"
        self.reason += "; switched to implicitEuler after a blow-up"
        self.substeps = implicit_substeps(self.frame_dt)
        self.dt = self.frame_dt / self.substeps
        return True

    def _failure(self, failure, factor: int) -> str:
        """The message of a failed frame."""
        dt = self.frame_dt / (self.substeps * factor)
        hint = ""
        if dt > self.critical_dt:
            hint = f" (substep {dt:.3g} s exceeds the stability bound {self.critical_dt:.3g} s)"
        elif factor > 1:
            hint = f" (after {factor}x the substeps)"
        return f"numerical failure at frame {self.frame + 1}: {failure.what} in {self._node_name(failure.node)}{hint}"

    def _report_contact(self):
        """Warn once when distant parts of tubes (world 0) come closer than two radii."""
        gap = self._contacts.deepest(self.state.node_q[0])
        if not (gap < 0.0).any():
            return
        hit = self._contacts.closest(self.state.node_q.numpy()[0].astype(np.float64), group=int(np.argmin(gap)))
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
            n = self.model.node_count
            if self._world_q is None:
                self._world_q = wp.empty((1, n), dtype=wp.vec3, device=self.device)
            wp.copy(self._world_q, q, src_offset=world * n, count=n)
            q = self._world_q
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
