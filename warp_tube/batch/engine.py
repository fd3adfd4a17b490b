"""Simulating one chunk: its variants as worlds of one model, frame by frame, into arrays.

:func:`simulate_chunk` advances every world with the solver and substeps each variant alone would
get (the chunk's :class:`~warp_tube.batch.plan.RunChoice`), applies each world's control, checks
each world after every frame, and copies the output frames (``k % every == 0``) into arrays the
writers read. Each frame is queued on the device before the host reads the one before it (the
checks' results in a host slot per frame), so the host's work on frame k overlaps the device's
on frame k + 1. A world that fails a check is dropped from the batch (no forces from the frame
after next; put at rest at the end of the frame already queued, so it stays finite; worlds do
not interact, so the others compute what they would alone) and, once the others are done, run
alone through ``Simulation`` exactly as ``warp-tube run`` would run it, with its retries: its
frames come from that run, and if that fails too the variant is failed with ``Simulation``'s own
message, its frames after the failure NaN.

Output arrays (stage units, float32), for ``F`` written frames and ``W`` worlds:

- ``centerline``: (F, W, N, 3), all tube prims' points of a world in prim and curve order;
- ``points``, ``normals``: (F, W, V, 3), all prims' surface vertices of a world in prim order;
- ``extent``: (F, W, prims, 2, 3), each prim's surface bounds ``[min, max]``.

The surface's three are made where they are asked for (:func:`surface_outputs`): USD outputs write
all three, the arrays layout the points alone, so its chunks neither store nor copy back the
normals and extents.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ..runtime.interrupts import raise_if_interrupted
from ..scene.spec import Scene
from ..sim.checks import wait_for_stream
from ..sim.notes import stretch
from .checks import WorldChecks
from .clock import DeviceClock
from .contacts import WorldContacts
from .control import WorldControl
from .framestore import FrameStore, done_future
from .plan import RunChoice
from .rows import Rows
from .worlds import build_worlds, initial_state

__all__ = ["ChunkRun", "simulate_chunk", "output_frames", "chunk_shapes", "surface_outputs", "SURFACE_OUTPUTS"]

TIMERS = ("build_s", "kernels_s", "launch_s", "sync_s", "readback_s", "control_s", "checks_s", "copy_s", "flush_wait_s",
          "rerun_s")  # fmt: skip


def output_frames(frames: int, every: int) -> list[int]:
    """The frames written: 0, every, 2 every, ... below ``frames``."""
    return list(range(0, frames, every))


#: the surface's output arrays: vertices [stage units], unit normals, each prim's bounds [stage units]
SURFACE_OUTPUTS = ("points", "normals", "extent")


def surface_outputs(surface) -> tuple[str, ...]:
    """The surface's output arrays asked for by ``surface``: True for all of
    :data:`SURFACE_OUTPUTS`, False (or empty) for none, or the names of some of them."""
    if surface is True:
        return SURFACE_OUTPUTS
    if not surface:
        return ()
    unknown = sorted(set(surface) - set(SURFACE_OUTPUTS))
    if unknown:
        raise ValueError(f"surface outputs {unknown}: expected some of {list(SURFACE_OUTPUTS)}")
    return tuple(n for n in SURFACE_OUTPUTS if n in surface)


def chunk_shapes(scenes: list[Scene], frames: int, every: int, surface, vertex_count: int | None) -> dict:
    """Shapes of a chunk's output arrays (see the module docstring); ``surface`` as
    :func:`surface_outputs` takes it, ``vertex_count`` a world's surface vertices (or None without)."""
    F, W = len(output_frames(frames, every)), len(scenes)
    N = sum(len(t.points) for t in scenes[0].tubes)
    out = {"centerline": (F, W, N, 3)}
    shapes = {"points": (F, W, vertex_count, 3), "normals": (F, W, vertex_count, 3), "extent": (F, W, len(scenes[0].tubes), 2, 3)}
    out.update((name, shapes[name]) for name in surface_outputs(surface))
    return out


@dataclass
class ChunkRun:
    """What simulating a chunk gave.

    Attributes:
        arrays: the output arrays by name (see the module docstring).
        rows: per variant (chunk order) its summary fields (:class:`~warp_tube.batch.rows.Rows`): status ("ok" or "failed"), reason,
            frames (written), frames_simulated, integrator, substeps, rerun (run alone),
            max_displacement_m, tip (the first tube's last point at the end, stage units, (3,)),
            kinetic_energy_J (at the end), work_J (of the forces and gravity, in all),
            contact_frame (the first frame at whose end distant parts of its tubes overlapped, or
            "": :mod:`warp_tube.batch.contacts`); a failed variant's max_displacement_m, tip,
            kinetic_energy_J and work_J are NaN (its frames and frames_simulated say how far it got).
        timings: seconds spent building, in the kernels (the device's own time), queueing
            them (``launch_s``: the host's time on a GPU; on the CPU the launches are the
            kernels' time), waiting for them (``sync_s``), copying the end state back and making
            the rows (``readback_s``), in control and checks, handing frames over to be
            copied into the arrays (``copy_s``), waiting for earlier windows of frames to be
            copied back (``flush_wait_s``: the device memory they hold) and rerunning failed
            variants alone.
        ready: done once every output frame is in ``arrays`` (they are copied back from the
            device on a thread of their own while the caller goes on): wait before reading them.
    """

    arrays: dict
    rows: Rows
    timings: dict = field(default_factory=lambda: dict.fromkeys(TIMERS, 0.0))
    ready: cf.Future = field(default_factory=done_future)


def simulate_chunk(scenes: list[Scene], choice: RunChoice, device: str, frames: int, every: int, surface,
                   allocate=None, progress=None, per_node: dict | None = None) -> ChunkRun:  # fmt: skip
    """Simulate ``scenes`` (one group) as worlds and return their output frames.

    Args:
        scenes: the chunk's variants (one topology, see :mod:`warp_tube.batch.plan`).
        choice: the integrator and substeps each of them gets alone.
        device: Warp device name.
        frames: frames to simulate, frame 0 (rest) included.
        every: write every ``every``-th frame.
        surface: rebuild the surface of the written frames and store the outputs
            :func:`surface_outputs` reads from it (True: points, normals and extents), or not (False).
        allocate: callable ``{name: shape} -> {name: float32 array}`` for the output arrays
            (default: in memory).
        progress: callable taking a number of variant-frames just simulated, or None.
        per_node: the variants' per-node parameters as planning made them
            (:meth:`~warp_tube.batch.nodes.KeptNodes.take`), or None to work them out.
    """
    from ..centerline.explicit import SemiImplicitEulerSolver
    from ..centerline.implicit import ImplicitEulerSolver

    timings = dict.fromkeys(TIMERS, 0.0)
    t0 = time.perf_counter()
    worlds = build_worlds(scenes, device, surface, per_node)
    m = worlds.model
    W = m.world_count
    solver = ImplicitEulerSolver(m) if choice.integrator == "implicitEuler" else SemiImplicitEulerSolver(m)
    state, nxt, control = initial_state(worlds)
    stage = scenes[0].stage
    frame_dt, mpu = stage.frame_dt, stage.meters_per_unit
    wc = WorldControl(worlds, control, frame_dt)
    checks = WorldChecks(worlds, scenes[0].settings.gravity, wc.moving_pins)
    contacts = WorldContacts(worlds)
    shapes = chunk_shapes(scenes, frames, every, surface, int(worlds.vertex_start[-1]) if surface else None)
    arrays = (allocate or _in_memory)(shapes)
    store = FrameStore(arrays, device)
    stream = wp.get_stream(device) if wp.get_device(device).is_cuda else None
    timings["build_s"] += time.perf_counter() - t0

    clock = DeviceClock(device)
    alive = np.ones(W, dtype=bool)
    failed: dict[int, str] = {}
    frames_simulated = np.zeros(W, dtype=np.int64)
    frames_written = np.zeros(W, dtype=np.int64)
    max_disp = np.zeros(W)
    max_stretch = np.ones(W)
    n, dt = choice.substeps, frame_dt / choice.substeps

    def launch(k: int, state, nxt, f_out: int) -> tuple:
        """Queue frame ``k`` from ``state`` into ``nxt``: the substeps, the checks' sums and the
        contact test with their copies back into host slot ``k % 2``, then the frame's stores
        (a world that fails in it is run alone: its frames replaced). Returns ``(event, stored,
        f_out)``: the event the host waits for before reading the checks (None on the CPU)."""
        t = time.perf_counter()
        wc.update(k - 1, state)
        t1 = time.perf_counter()
        mark = clock.start()
        solver.integrate(state, nxt, control, dt, n)
        checks.launch(state, nxt, control, slot=k % 2)
        contacts.launch(nxt.node_q, slot=k % 2)  # (the state at the end of frame k)
        clock.stop(mark)
        event = stream.record_event() if stream is not None else None
        t2 = time.perf_counter()
        if stream is not None:  # (on the CPU the launches run the kernels: kernels_s)
            timings["launch_s"] += t2 - t1
        stored = k % every == 0
        on_host = 0.0
        if stored:
            f_out, on_host = _store_frame(worlds, nxt, store, f_out, mpu, surface, clock)
        timings["control_s"] += t1 - t
        timings["copy_s"] += time.perf_counter() - t2 - on_host
        return event, stored, f_out

    # Frame 0 (the rest shape), then each frame queued before the one before it is read: the
    # host reads frame k's checks while the device runs frame k + 1.
    t = time.perf_counter()
    f_out, on_host = _store_frame(worlds, state, store, 0, mpu, surface, clock)
    frames_written[:] = 1
    timings["copy_s"] += time.perf_counter() - t - on_host
    flight = None
    if frames > 1:
        flight = (*launch(1, state, nxt, f_out), nxt)
        state, nxt = nxt, state
    for k in range(1, frames):
        raise_if_interrupted()  # a Ctrl-C dropped in a finalizer stops the chunk here
        event, stored, f_out, after = flight  # frame k, queued
        if k + 1 < frames:  # from frame k's end (`state`), which it reads and leaves as it is
            flight = (*launch(k + 1, state, nxt, f_out), nxt)
            state, nxt = nxt, state
        t = time.perf_counter()
        if event is not None:
            wp.synchronize_event(event)
        t1 = time.perf_counter()
        problems = checks.check(k - 1, after, alive, slot=k % 2)
        if problems:
            for w, msg in problems.items():
                alive[w] = False
                failed[w] = msg
            wc.dead[~alive] = True
            # Frame k + 1 has run them on from there: put them at rest at its end (`state`), so
            # they stay finite (their frames come from running them alone).
            wait_for_stream(device)
            _reset_worlds(state, checks.rest32, worlds.rest_q(), ~alive)
        contacts.check(k, after.node_q, alive, slot=k % 2)
        max_disp = np.where(alive, np.maximum(max_disp, checks.distance(k % 2)), max_disp)
        max_stretch = np.where(alive, np.maximum(max_stretch, checks.stretch(k % 2)), max_stretch)
        frames_simulated[alive] += 1
        frames_written[alive] += stored
        timings["sync_s"] += t1 - t
        timings["checks_s"] += time.perf_counter() - t1
        if progress is not None:
            progress(W)
    # The end state first: copied back before the last window of frames is handed over, whose copy
    # back would hold the device's copy engine (30 ms a chunk of 4,096 worlds on an H200) first.
    t = time.perf_counter()
    q, qd = state.node_q.numpy(), state.node_qd.numpy()
    timings["readback_s"] += time.perf_counter() - t
    t = time.perf_counter()
    ready = store.finish()
    wait_for_stream(device)
    clock.settle()
    timings["copy_s"] += time.perf_counter() - t - store.waited_s
    timings["flush_wait_s"] += store.waited_s
    timings["kernels_s"] += clock.seconds
    t = time.perf_counter()
    ke = checks.kinetic_energy(qd)
    first_tip = int(np.cumsum(scenes[0].tubes[0].curve_counts)[0]) - 1
    tips = (q[:, first_tip] / mpu).astype(np.float64).tolist()
    touched = [f if f >= 0 else "" for f in contacts.frame.tolist()]
    rows = Rows(dict(status=["ok"] * W, reason=[""] * W, frames=frames_written.tolist(), frames_simulated=frames_simulated.tolist(),
                     integrator=[choice.integrator] * W, substeps=[choice.substeps] * W, rerun=[False] * W,
                     max_displacement_m=max_disp.tolist(), tip=tips, kinetic_energy_J=np.asarray(ke, dtype=np.float64).tolist(),
                     work_J=np.asarray(checks.work, dtype=np.float64).tolist(), contact_frame=touched,
                     max_stretch=max_stretch.tolist()))  # fmt: skip
    timings["readback_s"] += time.perf_counter() - t
    t = time.perf_counter()
    if failed:
        ready.result()  # the worlds run alone write over their rows of the copied frames
    for w in sorted(failed):
        rows.put(w, _run_alone(scenes[w], w, device, frames, every, surface, arrays, first_tip))
    timings["rerun_s"] += time.perf_counter() - t
    return ChunkRun(arrays=arrays, rows=rows, timings=timings, ready=ready)


def _in_memory(shapes: dict) -> dict:
    return {name: np.empty(shape, dtype=np.float32) for name, shape in shapes.items()}


def _store_frame(worlds, state, store: FrameStore, f_out: int, mpu: float, surface: bool, clock: DeviceClock) -> tuple[int, float]:
    """Store ``state`` as written frame ``f_out``: its centerline and, with ``surface``, its
    rebuilt surface; returns the next written frame and the launches' own time on the CPU."""
    mark = clock.start()
    store.store(f_out, "centerline", state.node_q, mpu)  # as Simulation.centerline_points
    if surface:
        _surface_frame(worlds, state, store, f_out, mpu)
    on_host = clock.stop(mark)
    if store.count == store.window and f_out + 1 < store.frames:
        store.hand_over()  # copied back on the copying thread while the frames go on
    return f_out + 1, on_host


def _surface_frame(worlds, state, store: FrameStore, f_out: int, mpu: float) -> None:
    """Rebuild every prim's surface and store it as written frame ``f_out`` (the outputs ``store``
    holds: :func:`surface_outputs`)."""
    normals, extent = "normals" in store.buffers, "extent" in store.buffers
    for p, b in enumerate(worlds.surfaces):
        pts, nrm = b.compute(state.node_q)
        cols = slice(int(worlds.vertex_start[p]), int(worlds.vertex_start[p + 1]))
        store.store(f_out, "points", pts, mpu, columns=cols)  # as Simulation.surface
        if normals:
            store.store(f_out, "normals", nrm, 1.0, columns=cols)
        if extent:
            store.store(f_out, "extent", b.extent(), mpu, prim=p)


def _reset_worlds(state, rest32, rest, dead) -> None:
    """Put dead worlds back at rest with no velocity (so they stay finite)."""
    q = state.node_q.numpy()
    q[dead] = rest32[dead]
    lo = state.node_q_lo.numpy()
    lo[dead] = (rest[dead] - rest32[dead]).astype(np.float32)
    qd = state.node_qd.numpy()
    qd[dead] = 0.0
    state.node_q.assign(q)
    state.node_q_lo.assign(lo)
    state.node_qd.assign(qd)
    al = state.al_qd.numpy()
    al[dead] = 0.0
    state.al_qd.assign(al)


def _run_alone(scene: Scene, w: int, device: str, frames: int, every: int, surface: bool, arrays: dict, tip: int) -> dict:
    """Run variant ``scene`` alone as ``warp-tube run`` does, into world ``w`` of the arrays."""
    from ..runtime.log_filters import silenced
    from ..sim.simulation import NumericalError, Simulation

    with silenced("warp_tube.centerline.policy"):  # its integrator was warned of with the batch's
        sim = Simulation(scene, device=device, surface=surface)
    h = sim.model.host
    mpu = scene.stage.meters_per_unit
    free_mass = (h.node_mass * (h.node_inv_mass > 0))[None]
    max_disp, max_stretch, simulated, written, reason = 0.0, 1.0, 0, 0, ""
    q = sim.state.node_q.numpy()
    f_out = 0
    for k in range(frames):
        if k > 0:
            try:
                with silenced("warp_tube.sim.simulation"):  # its warnings go into the variant's row
                    sim.step()
            except NumericalError as e:
                reason = str(e)
                break
            q = sim.state.node_q.numpy()
            simulated += 1
            max_disp = max(max_disp, sim.max_displacement())
            max_stretch = max(max_stretch, float(stretch(q, h.seg_rest_length)[0]))
        if k % every == 0:
            arrays["centerline"][f_out, w] = np.concatenate(sim.centerline_points())
            if surface:
                parts = sim.surface()
                arrays["points"][f_out, w] = np.concatenate([p for p, _, _ in parts])
                if "normals" in arrays:
                    arrays["normals"][f_out, w] = np.concatenate([nrm for _, nrm, _ in parts])
                if "extent" in arrays:
                    arrays["extent"][f_out, w] = np.stack([e for _, _, e in parts])
            written += 1
            f_out += 1
    for a in arrays.values():
        a[f_out:, w] = np.nan
    qd = sim.state.node_qd.numpy()
    ke = 0.5 * float(np.einsum("wn,wnk,wnk->", free_mass, qd, qd, dtype=np.float64))
    note = f"failed a check among the worlds; ran alone ({sim.retried_frames} frame(s) redone with more substeps)"
    if sim.warnings:
        note += "; " + "; ".join(sim.warnings)
    # work_J: what Simulation's own checks counted over the frames it kept
    results = dict(max_displacement_m=float(max_disp), tip=(q[0, tip] / mpu).astype(np.float64).tolist(), kinetic_energy_J=ke,
                   work_J=float(sim.checks.work.sum()), max_stretch=max_stretch)  # fmt: skip
    if reason:  # no result: NaN, not the last finished frame's values (at rest, where frame 1 failed), which read as one
        results = dict(max_displacement_m=math.nan, tip=[math.nan] * 3, kinetic_energy_J=math.nan, work_J=math.nan,
                       max_stretch=math.nan)  # fmt: skip
    return dict(status="failed" if reason else "ok", reason=reason or note, frames=written,
                frames_simulated=simulated, integrator=sim.integrator, substeps=sim.substeps, rerun=True,
                **results, contact_frame="" if sim.contact_frame is None else sim.contact_frame)  # fmt: skip
