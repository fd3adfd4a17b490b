"""Simulation: a scene advanced frame by frame, with output, progress and a run summary.

The frame loop only: what drives a frame (forces, pins, the assistant line) is
:mod:`warp_tube.sim.control`, which integrator runs is :mod:`warp_tube.centerline.policy`, the
checks of each frame are :mod:`warp_tube.sim.checks`.

Time: output frame ``k`` is at time code ``startTimeCode + k`` (time ``k / timeCodesPerSecond``
[s]); frame 0 is the rest state. Each frame is advanced by ``substeps`` substeps of ``dt`` [s].

Warnings about a run (contact, a switch of integrator, a forced time step beyond the stability
bound) are logged once, with ``extra={"run_warning": True}`` so that a caller that prints them in a
summary (the command line) can leave the log record out, and kept in :attr:`Simulation.warnings`
(a forced time step's in the integrator's reason instead).
"""

from __future__ import annotations

import logging
import os
import re
import sys
import time

import numpy as np
import warp as wp

from ..centerline.explicit import SemiImplicitEulerSolver
from ..centerline.policy import MAX_SUBSTEPS, RUN_WARNING, choose_integrator, implicit_cost_ratio, implicit_substeps, substeps_for
from ..centerline.stability import critical_time_step
from ..model.tube import build_model
from ..runtime.replay import SIM_LOCK
from ..runtime.interrupts import Terminated, deferred_interrupts, held_interrupts, kept_interrupts, raise_if_interrupted
from ..scene.spec import Scene, SceneError
from .budget import CPU_SEMI_STEP_COST, LARGE_OUTPUT_BYTES, LONG_RUN_SECONDS, OUTPUT_MEMORY_FACTOR, RunBudget, check_world_count, whole_number  # noqa: F401 (re-exported)
from .checks import FrameChecks
from .control import FrameControl
from .output import frame_range, open_writer, unwritten_frames
from .proximity import ContactMonitor
from .arguments import checked_output, checked_progress, checked_scene
from .notes import model_notes, strain_message
from .summary import RunSummary

log = logging.getLogger(__name__)
__all__ = ["Simulation", "NumericalError", "RunSummary", "resolve_device"]

#: the largest substep multiplier ``auto`` tries for a frame that blew up.
MAX_RETRY_FACTOR = 16
#: environment variable that pauses a run at a known point, for the interrupt tests:
#: "compile" (before the first frame, where kernels compile) or "frame:K" (after frame K is written).
PAUSE_ENV = "WARP_TUBE_PAUSE_AT"


class NumericalError(RuntimeError):
    """The state became non-finite or ran away (CLI exit status 3)."""


def resolve_device(device=None) -> str:
    """``None`` -> the first CUDA device if there is one, else ``cpu``; checks a named device."""
    from ..runtime.warp_setup import init_warp

    init_warp()
    if device is None:
        return "cuda:0" if wp.get_cuda_device_count() > 0 else "cpu"
    name = str(device)
    if name.startswith("cuda"):
        count = wp.get_cuda_device_count()
        m = re.fullmatch(r"cuda(?::(\d+))?", name)
        if m is None:
            raise SceneError(f"device {name!r}: expected cpu, cuda or cuda:N with N = 0, 1, ...")
        idx = int(m.group(1) or 0)
        if idx >= count:
            raise SceneError(f"device {name}: no such CUDA device ({count} found): use the CPU (--device cpu; device=\"cpu\" in Python)")
        return f"cuda:{idx}"
    if name != "cpu":
        raise SceneError(f"device {name!r}: expected cpu, cuda or cuda:N")
    return name


class Simulation(RunBudget):
    """A scene on a device, advanced one output frame per :meth:`step`.

    Units: positions read and set through this class are in stage units (``metersPerUnit``),
    forces in N, times in s, :meth:`max_displacement` in m. Arrays are NumPy, one per tube prim.

    Args:
        scene: the scene (:func:`warp_tube.load_scene`, or built in Python).
        device: "cpu", "cuda", "cuda:N" or None (CUDA when available).
        world_count: copies of the scene run side by side (batch layout), each with the same input;
            a whole number, at least 1.
        surface: build the hubs-and-spokes surface (needed for :meth:`surface`,
            :meth:`surface_points` and the output's Surface meshes).

    Raises:
        SceneError: an unknown or missing device, or a ``world_count`` below 1 or not a whole number.

    Attributes:
        frame: the current output frame (0, the rest state, for a new Simulation).
        substeps: substeps per frame; ``dt``: the substep [s]; ``frame_dt``: a frame [s].
        integrator, reason: the integrator in use and why it was chosen.
        warnings: the run warnings so far (each logged once).
        last_summary: the :class:`RunSummary` of the last :meth:`run` (also of one that stopped).
        contact_frame: the first frame at whose end distant parts of the tubes (world 0) were
            closer than the sum of their radii (warned of once; contact is not modelled), or None.
        surfaces: per tube prim its surface (None with ``surface=False``): a
            :class:`~warp_tube.surface.builder.SurfaceBuilder`, or, for consecutive prims with
            the same spokes, frames and caps, a :class:`~warp_tube.surface.prims.PrimSurface` of
            the builder they share (its topology the prim's own).

    One thread at a time: :meth:`step` and :meth:`run` called from two threads run one after the
    other. A Simulation holds device arrays and cannot be pickled or copied: pickle its scene.
    """

    def __init__(self, scene: Scene, device=None, world_count: int = 1, surface: bool = True):
        with SIM_LOCK:  # (building launches on the device too)
            self._build(scene, device, world_count, surface)

    def _build(self, scene, device, world_count, surface):
        self.scene = checked_scene(scene)
        self.device = resolve_device(device)
        self._lock = SIM_LOCK  # step and run: one thread at a time, of all simulations and batches
        self.model = build_model(scene, world_count=check_world_count(world_count), device=self.device)
        m = self.model
        self.frame_dt = scene.stage.frame_dt
        spring_damping = max((t.params.spring_damping for t in scene.tubes), default=0.0)
        self.critical_dt = critical_time_step(m.host, m.features.assistant_line, spring_damping)
        choice = choose_integrator(scene.settings, self.critical_dt, self.frame_dt, implicit_cost_ratio(m), scene.source)
        self.integrator, self.reason = choice.integrator, choice.reason
        self.substeps = substeps_for(self.frame_dt, choice.dt, scene.settings, scene.source)
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
        self._prim_start = m.host.prim_node_start
        self._prim_count = [len(t.points) for t in scene.tubes]
        self.surfaces = self._build_surfaces() if surface else None
        self._world_q = None  # one world's positions for the surface builders, (1, node_count)
        self._contacts = ContactMonitor(m.host.node_rest_q, m.host.node_radius, m.host.tube_node_start, device=self.device)
        self._contact_reported = False
        self._strain_said = False  # (a segment strained beyond notes.STRAIN_FACTOR is warned of once)
        self._host_q = None  # (frame, positions) copied to the host by the last step, or None
        self.contact_frame: int | None = None
        self._retry = self.scene.settings.integrator == "auto"
        extent = max(float(np.ptp(t.points, axis=0).max()) for t in scene.tubes)
        # float32 round-off moves points by ~1e-7 of their coordinates; springs strained that much
        # (with a 10x margin) hold the energy below which nothing counts as a blow-up.
        scale = max(extent, float(np.abs(m.host.node_rest_q).max()), 1e-9)
        energy_floor = float(np.sum(m.host.seg_ke)) * (1e-6 * scale) ** 2 + 1e-30
        gravity = scene.settings.gravity if m.features.gravity else None
        self.checks = FrameChecks(m, extent=extent, energy_floor=energy_floor, gravity=gravity)
        self.retried_frames = 0
        self.last_summary: RunSummary | None = None  # the last run's (see run)
        self.max_retry_factor = 1

    def __reduce__(self):
        raise TypeError("a warp_tube Simulation holds arrays on its device and cannot be pickled or copied: pickle "
                        "its scene (sim.scene) and make a new Simulation from it, or keep centerline_points()")

    def _build_surfaces(self):
        """Per tube prim its surface; consecutive prims of one kind share a builder
        (:mod:`warp_tube.surface.prims`), kept in ``self._surface_builders``."""
        from ..surface.prims import prim_surfaces

        per_prim, self._surface_builders, self._shared_prims = prim_surfaces(self.scene.tubes, self._prim_start, self.device)
        return per_prim

    # -- interactive control ---------------------------------------------------------------------
    def set_force(self, force, vector) -> None:
        """Override a scene force from the next frame on: ``force`` is its index or prim path;
        ``vector`` [N], three finite numbers of at most 1e9 N (a list, tuple, NumPy array of shape
        (3,) or (1, 3), ``Gf.Vec3f``), in world axes; held until the next call.

        Raises:
            KeyError: no force at that prim path. IndexError: no force with that index.
            TypeError: neither an index nor a path. ValueError: not three finite numbers, or beyond 1e9 N.
        """
        self.controls.set_force(force, vector)

    def set_pin_targets(self, tube, positions) -> None:
        """Move a tube prim's pinned points, reached at the end of the next frame (linearly over it)
        and held there: ``positions`` [stage units], world space, shape (pinned, 3) with one row per
        pinned point in ascending order of its index, or a dict from each pinned point's index to its
        position (every pinned point: one left out is an error, not held).

        Raises:
            KeyError / IndexError: no such tube prim. ValueError: a wrong shape or set of points, or
            values that are not finite numbers (:meth:`FrameControl.set_pin_targets
            <warp_tube.sim.control.FrameControl.set_pin_targets>`).
        """
        self.controls.set_pin_targets(tube, positions)

    def _warn(self, msg: str) -> None:
        """A run warning: logged once (marked :data:`RUN_WARNING`) and kept in :attr:`warnings`."""
        log.warning(msg, extra=RUN_WARNING)
        self.warnings.append(msg)

    # -- stepping --------------------------------------------------------------------------------
    def step(self) -> None:
        """Advance one output frame (``substeps`` substeps).

        The frame is checked for a non-finite state, a point running away, and a kinetic energy
        above what the forces and gravity can have put in (a blow-up; not checked once pinned points
        have moved, whose work is not measured: a segment strained past 1.5x is warned of). With ``auto`` a failed frame is redone from its
        start with 2x, 4x, ... up to :data:`MAX_RETRY_FACTOR` x the substeps, then, if
        semi-implicit Euler still fails, with implicit Euler for the rest of the run.

        Raises:
            NumericalError: the frame still fails; :attr:`state` keeps the last good frame, the
                pinned points stay where that frame left them, and the integrator as it was.
        """
        with self._lock:
            self.controls.update(self.frame, self.state)
            kept = (self.solver, self.integrator, self.reason, self.substeps, self.dt, len(self.warnings))
            try:
                self._advance()
            except NumericalError:
                self.controls.undo_pins()  # the next frame starts its pins from the last good one
                # nor was auto's switch to implicit Euler kept, made for the frame that failed
                self.solver, self.integrator, self.reason, self.substeps, self.dt, n = kept
                del self.warnings[n:]
                raise
            self._host_q = None if self._strain_said else (self.frame, self.state.node_q.numpy())  # (kept for run)
            said = self._host_q and strain_message(self._host_q[1], self.model.host.seg_rest_length, self.frame, self._node_name)
            if said:
                self._strain_said = True
                self._warn(said)

    def _advance(self) -> None:
        """The frame of :meth:`step` whose control is written."""
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
            if factor < MAX_RETRY_FACTOR and 2 * factor * self.substeps <= MAX_SUBSTEPS:
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
        # one statement with no call in it: Python runs a signal's handler at calls and loop jumps,
        # so an interrupt cannot leave the state and the frame number disagreeing
        self.state, self.next_state, self.frame = self.next_state, self.state, self.frame + 1
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
        self._warn(msg)
        self.solver = ImplicitEulerSolver(self.model)
        self.integrator = "implicitEuler"
        self.reason += (f"; switched to implicitEuler at frame {self.frame + 1} after a blow-up (before: {self.substeps} "
                        f"substeps a frame, dt = {self.dt:.3g} s)")  # fmt: skip
        self.substeps = implicit_substeps(self.frame_dt)
        self.dt = self.frame_dt / self.substeps
        return True

    def _failure(self, failure, factor: int) -> str:
        """The message of a failed frame."""
        dt = self.frame_dt / (self.substeps * factor)
        hint = ""
        if self.integrator == "implicitEuler":  # (no stability bound: its substep, and a way to a smaller one)
            hint = f" (implicit Euler, substep {dt:.3g} s; a smaller warptube:timeStep may carry it through)"
        elif dt > self.critical_dt:
            hint = f" (substep {dt:.3g} s exceeds the stability bound {self.critical_dt:.3g} s)"
        elif factor > 1:
            hint = f" (after {factor}x the substeps)"
        if self.scene.settings.integrator == "semiImplicitEuler":  # (auto would have redone the frame)
            hint += "; warptube:integrator \"auto\" redoes a failed frame with more substeps, then with implicit Euler"
        return f"numerical failure at frame {self.frame + 1}: {failure.what} in {self._node_name(failure.node)}{hint}"

    def _report_contact(self):
        """Warn once when distant parts of tubes (world 0) come closer than two radii."""
        gap = self._contacts.deepest(self.state.node_q)  # (its first node_count points: world 0)
        if not (gap < 0.0).any():
            return
        hit = self._contacts.closest(self.state.node_q.numpy()[0].astype(np.float64), group=int(np.argmin(gap)))
        if hit is None:
            return
        i, j, gap = hit
        name = lambda n: self._node_name(n)  # noqa: E731
        msg = (f"frame {self.frame}: {name(i)} and {name(j)} are {-gap:.3g} m closer than the sum of their "
               "radii (distant parts touch; contact is not modelled, so they pass through each other)")  # fmt: skip
        self._warn(msg)
        self._contact_reported = True
        self.contact_frame = self.frame

    def _node_name(self, node: int) -> str:
        k = int(np.searchsorted(self._prim_start, node, side="right") - 1)
        return f"{self.scene.tubes[k].path} point {int(node - self._prim_start[k])}"

    # -- read-back -------------------------------------------------------------------------------
    def _world(self, world) -> int:
        """``world`` checked against the worlds this Simulation runs."""
        if isinstance(world, bool) or not isinstance(world, (int, np.integer)) or not 0 <= world < self.model.world_count:
            raise IndexError(f"world {world!r}: this Simulation runs {self.model.world_count} world(s), 0..{self.model.world_count - 1}")
        return int(world)

    def centerline_points(self, world: int = 0) -> list[np.ndarray]:
        """Centerline points per tube prim [stage units], each shape (P, 3).

        Raises:
            IndexError: no such world."""
        q = self.state.node_q.numpy()[self._world(world)] / self.scene.stage.meters_per_unit
        return [q[s : s + n].copy() for s, n in zip(self._prim_start, self._prim_count)]

    def surface_points(self, world: int = 0) -> list[np.ndarray]:
        """Surface vertices per tube prim [stage units], each shape (V, 3): point i spoke j at
        ``i * spokes + j``, cap vertices after all rings.

        Raises:
            RuntimeError: made with ``surface=False``. IndexError: no such world."""
        return [out[0] for out in self.surface(world)]

    def surface(self, world: int = 0):
        """Surface ``(points, normals, extent)`` per tube prim: points [stage units] and unit
        normals, each shape (V, 3), and the points' ``[min, max]`` corners [stage units], (2, 3);
        new arrays, the caller's.

        Raises:
            RuntimeError: made with ``surface=False``. IndexError: no such world."""
        from ..surface.prims import PrimSurface

        if self.surfaces is None:
            raise RuntimeError("this Simulation was made with surface=False")
        world = self._world(world)
        mpu = self.scene.stage.meters_per_unit
        q = self.state.node_q
        if q.shape[0] > 1:  # the builders serve one world: hand them that world's row
            n = self.model.node_count
            if self._world_q is None:
                self._world_q = wp.empty((1, n), dtype=wp.vec3, device=self.device)
            wp.copy(self._world_q, q, src_offset=world * n, count=n)
            q = self._world_q
        rebuilt = {}  # each builder once: (points, normals, extent) on the host
        own = wp.get_device(self.device).is_cpu  # (there numpy() views the builder's arrays, rewritten next frame)
        for b in self._surface_builders:
            pts, nrm = b.compute(q)
            rebuilt[id(b)] = (pts.numpy()[0], nrm.numpy()[0].copy() if own else nrm.numpy()[0], b.extent().numpy()[0])
        shared = {}  # the bounds of a shared builder's prims, exact, from its points
        for group in self._shared_prims:
            shared.update(zip(map(id, group.views), group.extents(rebuilt[id(group.builder)][0])))
        out = []
        for s in self.surfaces:
            if isinstance(s, PrimSurface):  # a prim's part of a shared builder
                pts, nrm = (s.take(a) for a in rebuilt[id(s.builder)][:2])
                ext = shared[id(s)]
            else:
                pts, nrm, ext = rebuilt[id(s)]
            out.append((pts / mpu, nrm, ext / mpu))
        return out

    def max_displacement(self, q: np.ndarray | None = None) -> float:
        """Largest distance of a centerline point from its rest position [m] (not stage units),
        over every world (``q``: the state's positions already on the host, (world, node, 3) [m])."""
        q = self.state.node_q.numpy() if q is None else q
        return float(np.linalg.norm(q - self.model.host.node_rest_q[None], axis=-1).max())

    # -- whole runs ------------------------------------------------------------------------------
    def run(self, frames: int | None = None, output: str | None = None, progress=None, every: int = 1,
            setup_time: float = 0.0) -> RunSummary:
        """Simulate from the current frame up to frame ``frames - 1`` and write the frames to ``output``.

        Frames keep their numbers: frame k is at time code ``startTimeCode + k`` and frame 0 is
        the rest state. A new Simulation is at frame 0, so ``run()`` writes frames 0 to the scene's
        last one. After :meth:`step` calls (or an earlier run) it is at frame k > 0: ``run``
        continues from there, writing the current state as frame k at its own time code, and the
        output's startTimeCode is that of the first frame written. ``run(frames=48)`` after 10 steps
        therefore simulates 37 more frames and writes frames 10 to 47.

        The output is written under a temporary name and renamed over ``output`` only when the
        run completes. If the run stops (numerical failure, interrupt, any exception) the frames
        finished so far are saved to ``OUT.partial.usdc`` beside ``output``
        (:func:`warp_tube.scene.files.partial_path`), :attr:`last_summary` names it (``partial``, None if
        no frame was finished), and a file already at ``output`` is left as it was.

        Args:
            frames: frames from frame 0 (rest) to the last one to reach, default the scene's frame
                count; must be more than the current frame.
            output: path of the output stage (.usdc, .usda, .usd), or None to write nothing; never
                the scene's own file.
            progress: None; True for a progress bar with its estimate of the time left (and, for a
                first frame that takes long, a status line while the kernels compile) on stderr; or
                a function called after each simulated frame as ``progress(done, total)``: frames
                simulated by this call so far and in all (``total`` is ``frames - 1 - `` the
                starting frame). An exception it raises stops the run as any other would.
            every: write every ``every``-th frame (frame numbers divisible by it).
            setup_time: seconds spent before this call that the summary counts as set-up (the CLI:
                reading the scene and building the model) [s].

        Returns:
            the :class:`RunSummary` (also kept in :attr:`last_summary`).

        Raises:
            SceneError: ``frames`` or ``every`` not a whole number or out of range, or an output that
                cannot be written or would not fit in the memory available or on its disk.
            NumericalError: after keeping the frames finished so far.
            KeyboardInterrupt: after keeping the frames finished so far.
        """

        with self._lock:
            return self._run(frames, checked_output(output), checked_progress(progress), whole_number("every", every), setup_time)

    def _run(self, frames, output, progress, every: int, setup_time: float) -> RunSummary:
        from ..runtime.interrupts import stopped_by
        from ..runtime.progress import Phase

        info = self.scene.stage
        first = self.frame
        end = info.frame_count if frames is None else whole_number("frames", frames)
        report = progress if callable(progress) else None  # (else True: the bar)
        progress = report is None and bool(progress)
        if end < 1:
            raise SceneError(f"frames {end}: expected at least 1")
        if end <= first:
            raise SceneError(f"frames {end}: this Simulation is already at frame {first}: expected more than {first}")
        if every < 1:
            raise SceneError(f"every {every}: expected at least 1")
        # the frames written, first..end-1 divisible by every: counted, not listed (--frames may be huge)
        first_written = -(-first // every) * every
        written_count = max(0, (end - 1 - first_written) // every + 1)
        writer = None
        if output and not written_count:
            which = f"none of {frame_range(first, end - 1)} is" if end - 1 > first else f"frame {first} is not"
            raise SceneError(f"every {every}: {which} a multiple of it: nothing to write")
        if output and written_count == 1 and end - first > 1:
            self._warn(f"every {every}: of frames {first} to {end - 1} only frame {first_written} is written")
        # (frames simulated after the last one written are said at the end: a run may stop before them)
        last_due = first_written + (written_count - 1) * every if output and written_count > 1 else None
        roots = list(dict.fromkeys("/" + t.path.strip("/").split("/")[0] for t in self.scene.tubes)) if output else []
        if len(roots) > 1:
            self._warn(f"the tube prims lie under {len(roots)} root prims ({', '.join(roots[:4])}{', ...' if len(roots) > 4 else ''}): "
                       f"the output's defaultPrim is {roots[0]}, and a reference to the file without a prim path brings "
                       "in only the tubes under it")  # fmt: skip
        if output:
            self._check_output_fits(written_count, output)
            inputs = [self.scene.source] if self.scene.source and os.path.exists(self.scene.source) else []
            start_tc = info.start_time_code + (first_written if written_count else first)
            t_setup = time.perf_counter()
            with Phase(f"setting up {os.path.basename(str(output))} ({len(self.scene.tubes):,} tube prims)", enabled=bool(progress), after=1.0):
                writer = open_writer(output, self.scene, self.surfaces, start_time_code=start_tc, inputs=inputs)
            setup = time.perf_counter() - t_setup
        else:
            setup = 0.0
        summary = RunSummary(
            scene=self.scene.source, device=self.device, frames=0, substeps=self.substeps, dt=self.dt,
            integrator=self.integrator, reason=self.reason, wall_time=0.0, max_displacement=0.0,
            stage_defaults=[f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in (
                ("metersPerUnit", info.meters_per_unit), ("upAxis", info.up_axis), ("timeCodesPerSecond", info.time_codes_per_second),
                ("framesPerSecond", info.frames_per_second), ("startTimeCode", info.start_time_code), ("endTimeCode", info.end_time_code))
                if k not in info.authored and self.scene.source != "<python>"],
            first_frame=first_written if written_count else first, setup_time=setup_time + setup,
            notes=model_notes(self.scene, self.model.features, self.integrator),
        )  # fmt: skip
        self.last_summary = summary
        self._announce_long_run(end - 1 - first)
        if writer:
            self._announce_large_output(written_count)
        pause = os.environ.get(PAUSE_ENV, "")
        bar = beat = None
        startup = Phase("compiling kernels (first run only) and simulating frame 1", enabled=progress, after=0.5)
        startup.__enter__()
        t0 = time.perf_counter()
        interrupts = kept_interrupts()
        interrupts.__enter__()
        try:
            for k in range(first, end):
                raise_if_interrupted()  # a Ctrl-C dropped in a finalizer stops the run here
                if k > first:
                    steps_before = self.substeps
                    self.step()
                elif pause == "compile":
                    _pause_for_tests(pause)
                with held_interrupts():  # the frame in the summary and the output both, or in neither
                    if k > first:
                        self._count_frame(summary, steps_before, t0)
                    if writer and k % every == 0:
                        self._write_frame(writer, summary, k)
                if k > first:
                    if summary.frames_simulated == 1:
                        startup.__exit__(None, None, None)
                        if progress and end - 1 - first > 1:
                            bar, beat = self._progress_bar(end - 1 - first)
                    elif bar is not None:
                        bar.update(1)
                    if report is not None:
                        report(summary.frames_simulated, end - 1 - first)
                if pause == f"frame:{k}":
                    _pause_for_tests(pause)
        except BaseException as e:
            summary.stopped = (str(e) or type(e).__name__) if not isinstance(e, KeyboardInterrupt) else stopped_by(e)
            with deferred_interrupts():  # a second Ctrl-C does not throw the partial file away
                if isinstance(e, KeyboardInterrupt):
                    try:
                        self._finish_frame(summary, writer, first, every, t0)
                    except Exception:  # (the frames before it are kept all the same)
                        log.debug("the frame in hand when the run was interrupted could not be kept", exc_info=True)
                if writer:
                    summary.partial = writer.keep_partial()
            raise
        else:
            if writer:
                if bar is not None:  # (the saving line takes its place)
                    bar.close()
                    bar = None
                with Phase(f"saving {os.path.basename(str(output))}", enabled=progress, after=1.0), deferred_interrupts() as late:
                    try:
                        summary.output = writer.close()
                    except BaseException as e:  # (the summary says the frames were not saved)
                        summary.stopped = f"cannot write {output}: {getattr(e, 'strerror', None) or e}"
                        raise
                if late:  # the run is complete: its result is kept, not thrown away
                    self._warn(f"{stopped_by(Terminated(late[0]))} while saving {output}: the save was finished: the output is complete")
        finally:
            interrupts.__exit__(None, None, None)
            summary.wall_time = time.perf_counter() - t0
            startup.__exit__(None, None, None)
            if beat is not None:
                beat.__exit__(None, None, None)
            if bar is not None:
                bar.close()
            if writer and not writer.closed:
                writer.abort()
            if last_due is not None and self.frame > last_due:
                self._warn(f"every {every}: {unwritten_frames(last_due + 1, self.frame, last_due)}")
            summary.integrator, summary.reason = self.integrator, self.reason
            summary.substeps, summary.dt = self.substeps, self.dt
            summary.warnings = list(self.warnings)
            if self.retried_frames:
                summary.warnings.append(
                    f"{self.retried_frames} frame(s) blew up and went through when redone with up to {self.max_retry_factor}x "
                    "the substeps"
                )
        return summary

    def _count_frame(self, summary: RunSummary, substeps: int, t0: float) -> None:
        """Count the frame just simulated in ``summary`` (frame 1's end closes the start-up)."""
        summary.frames_simulated += 1
        summary.substeps_simulated += substeps
        held = self._host_q
        q = held[1] if held is not None and held[0] == self.frame else self.state.node_q.numpy()
        summary.max_displacement = max(summary.max_displacement, self.max_displacement(q))
        if summary.frames_simulated == 1:
            summary.startup_time = time.perf_counter() - t0
            summary.startup_substeps = summary.substeps_simulated

    def _write_frame(self, writer, summary: RunSummary, k: int) -> None:
        """Hand the current state to ``writer`` as frame ``k`` and count it in ``summary``."""
        writer.write_frame(self.scene.stage.start_time_code + k, self.centerline_points(),
                           self.surface() if self.surfaces is not None else None)  # fmt: skip
        summary.frames += 1
        summary.last_frame = k

    def _finish_frame(self, summary: RunSummary, writer, first: int, every: int, t0: float) -> None:
        """After an interrupt: count and write the frame whose simulation had finished when it came.

        An interrupt is raised wherever the run is, so also between :meth:`step`'s return and the
        frame's counting and writing: that frame is finished, and kept as the frames before it are."""
        if self.frame > first + summary.frames_simulated:
            self._count_frame(summary, self.substeps, t0)
        if writer and not writer.closed and self.frame > first and self.frame % every == 0 and summary.last_frame != self.frame:
            self._write_frame(writer, summary, self.frame)

    def _progress_bar(self, total: int):
        """A tqdm bar over ``total`` frames, started after frame 1 (its rate and estimate leave the
        start-up out), and a heartbeat that keeps its clock moving through long frames."""
        from ..runtime.progress import frame_bar

        return frame_bar(total)


def _pause_for_tests(point: str) -> None:
    """Stop at a known point of a run (:data:`PAUSE_ENV`) until interrupted (at most 120 s)."""
    print(f"warp-tube: paused at {point} ({PAUSE_ENV})", file=sys.stderr, flush=True)
    time.sleep(120.0)
