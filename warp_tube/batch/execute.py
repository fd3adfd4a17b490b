"""Where a batch's chunks run on one host, and the writers that write them.

- :func:`run_here`: one device, in this process; a pool of writers
  (:class:`~warp_tube.batch.writer_pool.Writers`) writes each
  chunk while the next one is simulated;
- :func:`run_pooled`: one worker process per device (the GPUs of a host, or N CPU processes), each
  simulating chunks into memory-mapped arrays that the writers read (``arrays``: each writing its
  own chunks);
- beyond one host, :func:`warp_tube.batch.cluster.run_dask`.

Each calls ``context["finish"](chunk_id, rows, outputs)`` when a chunk's outputs are complete, and
adds its timings to the batch's result.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import math
import os
import shutil
import threading
import time

import numpy as np

from ..scene.spec import SceneError
from .engine import TIMERS, chunk_shapes, simulate_chunk
from .folder import buffer_folder
from .outputs import WriteTask, write
from .writer_pool import (Writers, children_deaf_to_ctrl_c, ignore_sigint, spawn_context, terminate_pool, timed_write,
                          timed_write_when_ready)
from .rows import Rows

__all__ = ["SimWorkers", "run_here", "run_pooled", "add_timings", "with_rows", "write_tasks"]


_worker_device = None
_worker_done = None  # the queue a simulating process reports its written chunks on


def _init_sim_worker(devices, done, batch_pid=None):
    """Take a device and get ready to simulate on it: import the simulation and start Warp and
    the device (a CUDA context), while the batch's variants are still being read; end with the
    batch's process ``batch_pid`` (:func:`~warp_tube.batch.writer_pool.watch_batch`)."""
    global _worker_device, _worker_done
    ignore_sigint(batch_pid)
    _worker_device, _worker_done = devices.get(), done
    import warp as wp

    from ..runtime.warp_setup import init_warp
    from ..sim.simulation import resolve_device  # noqa: F401  (the simulation's imports)
    from ..surface import builder  # noqa: F401

    init_warp()
    wp.config.log_level = wp.LOG_WARNING
    wp.synchronize_device(wp.get_device(_worker_device))


def _ready():
    return _worker_device


class SimWorkers:
    """One simulating process per device, started (and each device made ready) when the batch
    starts, so that they are up by the time its variants are read.

    Args:
        devices: one device name per process ("cuda:0", "cuda:1", ... or "cpu" each).

    Attributes:
        done: where a process that writes its own chunks reports each one written:
            ``(chunk id, outputs, seconds)``, or ``(chunk id, None, message)`` if writing failed.
    """

    def __init__(self, devices: list[str]):
        ctx = spawn_context()
        queue = ctx.Queue()
        for d in devices:
            queue.put(d)
        self.done = ctx.Queue()
        self.pool = cf.ProcessPoolExecutor(len(devices), mp_context=ctx, initializer=_init_sim_worker,
                                           initargs=(queue, self.done, os.getpid()))  # fmt: skip
        with children_deaf_to_ctrl_c():
            for _ in devices:  # start them now (one new process per waiting task)
                self.pool.submit(_ready)

    def terminate(self):
        """Stop simulating at once (an interrupted batch)."""
        if self.pool is not None:
            terminate_pool(self.pool)
            self.pool = None

    def shutdown(self):
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None


def _sim_task(payload):
    """A worker process simulates one chunk into memory-mapped arrays in the buffer folder."""
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    scenes, choice, frames, every, surface, buffer_dir, slot = payload
    run = simulate_chunk(scenes, choice, _worker_device, frames, every, surface, allocate=_slot_allocator(buffer_dir, slot))
    run.ready.result()  # the frames are in the slot files
    paths = {name: a.filename for name, a in run.arrays.items()}
    for a in run.arrays.values():
        a.flush()
    return run.rows, paths, run.timings


_worker_ring = None  # a simulating process's output arrays, two chunks' in turn
_worker_writing: dict = {}  # chunk id -> its write futures, in a simulating process
_worker_writers = None  # and its writer threads


def _sim_write_task(payload):
    """A worker process simulates one chunk and writes it itself (the arrays layout: each
    variant's frames go straight into the batch's arrays, from this process's memory). The task
    returns once the chunk is simulated; the chunk's writing goes on in this process's writer
    threads while the next chunk simulates, and is reported on the done queue when complete."""
    global _worker_ring, _worker_writers
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    chunk_id, scenes, choice, frames, every, surface, tasks, threads = payload
    if _worker_ring is None:
        _worker_ring = BufferRing(2)
        _worker_writers = cf.ThreadPoolExecutor(threads, thread_name_prefix="batch-writer")
    pending = _worker_writing.get(_worker_ring.owner())  # (a writer thread removes it when done)
    if pending is not None:  # the arrays this chunk reuses are still being written
        cf.wait(pending)
    run = simulate_chunk(scenes, choice, _worker_device, frames, every, surface, allocate=_worker_ring.allocator(chunk_id))
    t0 = time.perf_counter()
    futures = [_worker_writers.submit(timed_write_when_ready, run.ready, t) for t in with_rows(tasks, run.rows, run.arrays)]
    _worker_writing[chunk_id] = futures
    left = [len(futures)]
    lock = threading.Lock()

    def written(_):
        with lock:
            left[0] -= 1
            if left[0]:
                return
        _worker_writing.pop(chunk_id, None)
        try:
            outputs = [o for f in futures for o in f.result()[0]]
        except Exception as e:  # reported to the batch, which stops with it
            _worker_done.put((chunk_id, None, f"writing chunk {chunk_id}: {type(e).__name__}: {e}"))
            return
        _worker_done.put((chunk_id, outputs, time.perf_counter() - t0))

    for f in futures:
        f.add_done_callback(written)
    return run.rows, None, run.timings


def _hand_to_processes(ready: cf.Future, arrays: dict, tasks: list, pool):
    """Once the chunk's frames are in its memory-mapped ``arrays``, flush them and have the
    writer processes ``pool`` write ``tasks`` (filled in with the arrays' file names); returns
    every task's outputs and the writers' summed time, as one :func:`timed_write`."""
    ready.result()
    for a in arrays.values():
        a.flush()
    names = {name: a.filename for name, a in arrays.items()}
    futures = [pool.submit(timed_write, dataclasses.replace(t, arrays=names)) for t in tasks]
    outputs, spent = [], 0.0
    for f in futures:
        out, s = f.result()
        outputs += out
        spent += s
    return outputs, spent


def _slot_allocator(folder: str, slot: int):
    """Memory-mapped arrays in buffer slot ``slot`` of ``folder``: the slot's files as an earlier
    chunk left them when their shapes match (pages already there, not faulted in and zeroed
    again), new ones otherwise (their pages allocated on a thread meanwhile: :func:`_fill_file`)."""
    from numpy.lib.format import open_memmap

    def allocate(shapes: dict) -> dict:
        out = {}
        for name, shape in shapes.items():
            path = os.path.join(folder, f"slot_{slot:03d}.{name}.npy")
            a = np.load(path, mmap_mode="r+") if os.path.exists(path) else None
            if a is None or a.shape != tuple(shape) or a.dtype != np.float32:
                a = open_memmap(path, mode="w+", dtype=np.float32, shape=shape)
                _filler().submit(_fill_file, path)
            out[name] = a
        return out

    return allocate


_fill_thread = None


def _filler() -> cf.ThreadPoolExecutor:
    global _fill_thread
    if _fill_thread is None:
        _fill_thread = cf.ThreadPoolExecutor(1, thread_name_prefix="batch-buffer-pages")
    return _fill_thread


def _fill_file(path: str) -> None:
    """Allocate the pages of a new (sparse) buffer file at once (``posix_fallocate``, which on
    tmpfs is ~20x cheaper than faulting 2 GB in page by page from the threads copying frames into
    it: 0.18 against 3.3 s of a core). Its content stays as it was; where the platform or the file
    system has no such call, the pages are allocated as they are touched."""
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError:  # removed meanwhile
        return
    try:
        os.posix_fallocate(fd, 0, os.fstat(fd).st_size)
    except (OSError, AttributeError):
        pass
    finally:
        os.close(fd)


class BufferRing:
    """Output arrays for the chunks of one process, reused in turn.

    A chunk's frames are copied into memory an earlier chunk used instead of fresh pages that the
    kernel must fault in and zero on first touch (which held those copies to about 1 GB/s):
    arrays kept in this process's memory (writer threads), or the slot files of
    :func:`_slot_allocator` (writer processes open them by name), kept mapped here from chunk to
    chunk (mapped again, each 2 GB chunk paid ~0.5 s of page faults in the copying threads).
    ``slots`` chunks' arrays exist at once: before a slot comes round again, the caller waits until
    the writers of the chunk that used it (:meth:`owner`) are done.

    Args:
        slots: chunks' arrays kept.
        folder: the folder of the slot files, or None for arrays in memory.
    """

    def __init__(self, slots: int, folder: str | None = None):
        self.held: list = [None] * slots
        self.owners: list = [None] * slots
        self.folder = folder
        self.turn = 0

    def owner(self):
        """The chunk whose arrays the next allocator reuses (None: a slot never used)."""
        return self.owners[self.turn]

    def remove(self, chunk: int) -> None:
        """Remove the files of the slot chunk ``chunk`` used (its writers are done, and no later
        chunk will use it); nothing for arrays in memory."""
        if self.folder is None or chunk not in self.owners:
            return
        k = self.owners.index(chunk)
        self.owners[k] = None
        self.held[k] = None
        for name in os.listdir(self.folder):
            if name.startswith(f"slot_{k:03d}."):
                os.remove(os.path.join(self.folder, name))

    def allocator(self, chunk: int):
        """The allocator of chunk ``chunk``'s arrays (``{name: shape} -> {name: float32 array}``)."""
        k = self.turn
        self.turn = (self.turn + 1) % len(self.held)
        self.owners[k] = chunk
        files = _slot_allocator(self.folder, k) if self.folder is not None else None

        def allocate(shapes: dict) -> dict:
            held = self.held[k]
            if held is None or {name: a.shape for name, a in held.items()} != {n: tuple(s) for n, s in shapes.items()}:
                self.held[k] = None  # (the slot's old mappings go first)
                if files is not None:
                    held = files(shapes)
                else:
                    held = {name: np.empty(shape, dtype=np.float32) for name, shape in shapes.items()}
                self.held[k] = held
            return held

        return allocate

    def close(self) -> None:
        """Let the arrays go (before their files are removed)."""
        self.held = [None] * len(self.held)


def with_rows(tasks: list[WriteTask], rows, arrays: dict) -> list[WriteTask]:
    """Fill the write tasks of a chunk with the simulation's rows and arrays."""
    out = []
    for t in tasks:
        out.append(WriteTask(spec=t.spec, chunk=t.chunk, variants=t.variants, positions=t.positions,
                             rows=rows.take(t.positions), arrays=arrays))  # fmt: skip
    return out


def write_tasks(chunk, context, parts: int) -> list[WriteTask]:
    """A chunk's variants split into ``parts`` write tasks (the grid: one), rows filled in later."""
    variants, spec = context["variants"].variants, context["spec"]
    idx = list(chunk.indices)
    parts = 1 if spec.layout == "grid" else max(1, min(parts, len(idx)))
    bounds = np.linspace(0, len(idx), parts + 1).round().astype(int)
    # Variants made by plain values differ from the first only in materials and forces, which
    # writing does not read: each task holds the first's scene for all of them, pickled once for a
    # writer process instead of once a variant (4,096 a chunk: ~0.1 s of the interpreter's lock).
    shared = variants[0].scene if context["variants"].plain else None
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b > a:
            vs = tuple((i, variants[i].name, shared or variants[i].scene) for i in idx[a:b])
            out.append(WriteTask(spec=spec, chunk=chunk.id, variants=vs, positions=tuple(range(a, b)), rows=Rows({}), arrays={}))
    return out


def run_here(todo, device, context, result) -> None:
    """Simulate the chunks in this process while a pool of writer processes writes them."""
    import warp as wp

    from ..sim.simulation import resolve_device

    wp.config.log_level = wp.LOG_WARNING
    device = resolve_device(device)
    writers: Writers = context["writers"]
    pool = writers.pool
    buffers = None
    pending: dict = {}  # chunk id -> (futures, rows)
    ring = None  # the chunks' arrays, two in turn: one being written while the next is simulated
    handoff = None  # threads handing chunks to writer processes once their frames are copied back
    cleanup = None  # a thread removing the last chunks' buffer files
    bar = context["bar"]

    def settle(block: bool) -> float:
        """Record the chunks whose writers are done (all, waiting for them, with ``block``);
        returns the seconds spent recording them (``BatchResult.books_s``, not waiting)."""
        spent_here = 0.0
        for cid in list(pending):
            futures, rows = pending[cid]
            if not block and not all(f.done() for f in futures):
                continue
            outputs = []
            for f in futures:
                out, spent = f.result()
                outputs += out
                result.write_s += spent
            del pending[cid]
            t = time.perf_counter()
            context["finish"](cid, rows, outputs)
            spent_here += time.perf_counter() - t
        return spent_here

    try:
        for chunk in todo:
            scenes = context["variants"].scenes(chunk.indices)
            choice = context["choices"][chunk.indices[0]]
            allocate = None
            if pool is not None and ring is None:
                if writers.processes:  # the writers read the arrays from files
                    shapes = chunk_shapes(scenes, context["frames"], context["every"], context["surface"], context["spec"].vertices)
                    buffers = buffer_folder(sum(4 * math.prod(s) for s in shapes.values()), context["spec"].work_dir)
                ring = BufferRing(2, buffers)
            if ring is not None:
                t0, books = time.perf_counter(), 0.0
                while ring.owner() in pending:  # its slot's last chunk is still being written
                    cf.wait(pending[ring.owner()][0])
                    books += settle(block=False)
                result.write_wait_s += time.perf_counter() - t0 - books
                allocate = ring.allocator(chunk.id)
            t0 = time.perf_counter()
            kept = context.get("kept")
            run = simulate_chunk(scenes, choice, device, context["frames"], context["every"], context["surface"],
                                 allocate=allocate, progress=bar.frames,
                                 per_node=kept.take(chunk.indices) if kept is not None else None)  # fmt: skip
            result.simulate_s += time.perf_counter() - t0
            add_timings(result, run.timings)
            result.write_wait_s += run.timings["flush_wait_s"]  # (waiting for the output's copy back)
            tasks = write_tasks(chunk, context, max(writers.count, 1))
            if pool is None:
                t0 = time.perf_counter()
                run.ready.result()
                outputs = []
                for task in with_rows(tasks, run.rows, run.arrays):
                    outputs += write(task)
                result.write_s += time.perf_counter() - t0
                result.write_wait_s += time.perf_counter() - t0  # written here: the simulation waits
                context["finish"](chunk.id, run.rows, outputs)
                continue
            filled = with_rows(tasks, run.rows, run.arrays)
            if writers.processes:  # handed over once the frames are in the files, without waiting here
                if handoff is None:
                    handoff = cf.ThreadPoolExecutor(2, thread_name_prefix="batch-handoff")
                futures = [handoff.submit(_hand_to_processes, run.ready, run.arrays, filled, pool)]
            else:
                futures = [pool.submit(timed_write_when_ready, run.ready, t) for t in filled]
            del run.arrays
            pending[chunk.id] = (futures, run.rows)
            settle(block=False)
            t0, books = time.perf_counter(), 0.0
            while len(pending) >= 2:  # at most two chunks wait for writers
                # (on the futures not done yet: a chunk partly written would otherwise return at once, a spin)
                cf.wait([f for fs, _ in pending.values() for f in fs if not f.done()], return_when=cf.FIRST_COMPLETED)
                books += settle(block=False)
            result.write_wait_s += time.perf_counter() - t0 - books
        # The last chunks: each one's buffer files removed as soon as its writers are done, on a
        # thread of their own (freeing gigabytes of pages takes ~0.1 s a chunk), while the others
        # are still being written.
        t0, books = time.perf_counter(), 0.0
        done: set = {c for c in (ring.owners if ring is not None else ()) if c is not None} - set(pending)
        while True:
            if buffers is not None and done:
                cleanup = cleanup or cf.ThreadPoolExecutor(1, thread_name_prefix="batch-buffers")
                for cid in done:
                    cleanup.submit(ring.remove, cid)
            if not pending:
                break
            cf.wait([f for fs, _ in pending.values() for f in fs if not f.done()], return_when=cf.FIRST_COMPLETED)
            waiting = set(pending)
            books += settle(block=False)
            done = waiting - set(pending)
        result.write_wait_s += time.perf_counter() - t0 - books
    except KeyboardInterrupt:
        # Keep what is complete: the chunks already simulated are written to the end.
        try:
            settle(block=True)
        finally:
            raise
    finally:
        if handoff is not None:
            handoff.shutdown(wait=True)
        if cleanup is not None:
            cleanup.shutdown(wait=True)
        if ring is not None:
            ring.close()
        if buffers is not None:
            shutil.rmtree(buffers, ignore_errors=True)


def run_pooled(todo, devices, workers: SimWorkers, context, result) -> None:
    """The simulating processes ``workers`` (one per device) simulate chunks. USD layouts: into
    memory-mapped slot files that the pool of writer processes writes from; ``arrays``: each
    process writes its chunks itself, with its own writer threads, from its own memory (no copy
    through files, and the writing is spread over the processes)."""
    writers: Writers = context["writers"]
    by_workers = context["spec"].layout == "arrays"
    threads = max(2, writers.count // len(devices))
    own = None
    if writers.pool is None and not by_workers:  # the simulating processes hand their arrays over: someone writes them
        own = writers = Writers(context["spec"].layout, 1)
    pool = writers.pool
    sims = workers.pool
    buffers = None
    if not by_workers:
        first = context["variants"].scenes(todo[0].indices)
        shapes = chunk_shapes(first, context["frames"], context["every"], context["surface"], context["spec"].vertices)
        buffers = buffer_folder(sum(4 * math.prod(s) for s in shapes.values()) * len(devices), context["spec"].work_dir)
    queue_chunks = list(todo)
    simulating: dict = {}  # future -> chunk
    writing: dict = {}  # chunk id -> (futures, rows)
    free_slots = list(range(2 * len(devices)))  # buffer slots; a chunk's is free again once it is written
    slot_of: dict = {}  # chunk id -> its buffer slot
    bar = context["bar"]
    t0, books0 = time.perf_counter(), result.books_s

    early: dict = {}  # chunk id -> (outputs, seconds): reported written before its simulation's result was seen

    def finish_written(cid: int, outputs: list, spent: float):
        _, rows = writing.pop(cid)
        result.write_s += spent
        context["finish"](cid, rows, outputs)

    def settle_written(block: bool):
        """Finish the chunks the simulating processes report written (waiting for one if ``block``)."""
        import queue

        while writing or not block:
            try:
                cid, outputs, spent = workers.done.get(timeout=1.0) if block else workers.done.get_nowait()
            except queue.Empty:
                if block and not any(p.is_alive() for p in getattr(sims, "_processes", {}).values()):
                    raise SceneError("the simulating processes stopped before writing their chunks") from None
                if block:
                    continue
                return
            if outputs is None:
                raise RuntimeError(spent)
            if cid not in writing:  # its simulation's result is not in yet: finished when it is
                early[cid] = (outputs, spent)
                continue
            finish_written(cid, outputs, spent)
            block = False

    def submit_sim():
        while by_workers and queue_chunks and len(simulating) + len(writing) < 3 * len(devices):
            c = queue_chunks.pop(0)
            scenes = context["variants"].scenes(c.indices)
            tasks = write_tasks(c, context, threads)
            payload = (c.id, scenes, context["choices"][c.indices[0]], context["frames"], context["every"], context["surface"],
                       tasks, threads)  # fmt: skip
            simulating[sims.submit(_sim_write_task, payload)] = c
        while queue_chunks and free_slots and len(simulating) + len(writing) < 2 * len(devices):
            c = queue_chunks.pop(0)
            scenes = context["variants"].scenes(c.indices)
            slot_of[c.id] = free_slots.pop()
            payload = (scenes, context["choices"][c.indices[0]], context["frames"], context["every"], context["surface"], buffers,
                       slot_of[c.id])  # fmt: skip
            simulating[sims.submit(_sim_task, payload)] = c

    try:
        submit_sim()
        while simulating or writing:
            if by_workers:
                cf.wait(list(simulating), timeout=0.05, return_when=cf.FIRST_COMPLETED)
                settle_written(block=not simulating)
            else:
                waiting = list(simulating) + [f for fs, _ in writing.values() for f in fs]
                cf.wait([f for f in waiting if not f.done()], return_when=cf.FIRST_COMPLETED)  # (done ones: no spin)
            for fut in [f for f in simulating if f.done()]:
                c = simulating.pop(fut)
                rows, paths, timings = fut.result()  # paths None: the worker writes the chunk itself
                add_timings(result, timings)
                bar.frames(len(c.indices) * max(context["frames"] - 1, 1))
                if by_workers:
                    writing[c.id] = ((), rows)  # reported on the done queue once written
                    if c.id in early:
                        finish_written(c.id, *early.pop(c.id))
                    continue
                tasks = with_rows(write_tasks(c, context, max(1, writers.count // len(devices))), rows, paths)
                writing[c.id] = ([pool.submit(timed_write, t) for t in tasks], rows)
            for cid in [cid for cid, (fs, _) in writing.items() if fs and all(f.done() for f in fs)]:
                fs, rows = writing.pop(cid)
                outputs = []
                for f in fs:
                    out, spent = f.result()
                    outputs += out
                    result.write_s += spent
                free_slots.append(slot_of.pop(cid))  # its files stay for the next chunk
                context["finish"](cid, rows, outputs)
            submit_sim()
    except KeyboardInterrupt:
        # Stop simulating at once; the chunks already simulated are written to the end and kept
        # (those the simulating processes write themselves: the ones they report written).
        queue_chunks.clear()
        for f in simulating:
            f.cancel()
        if by_workers:
            settle_written(block=False)
            writing.clear()
        workers.terminate()
        try:
            for cid, (fs, rows) in list(writing.items()):
                outputs = []
                for f in fs:
                    outputs += f.result()[0]
                context["finish"](cid, rows, outputs)
        finally:
            raise
    finally:
        # (the chunks simulated so far, also where the batch was interrupted)
        result.simulate_s += sum(result.timings[k] for k in TIMERS if k not in ("sync_s", "flush_wait_s"))  # (waits: not the simulation's)
        if own is not None:
            own.shutdown()
        if buffers is not None:
            shutil.rmtree(buffers, ignore_errors=True)
        loop_s = time.perf_counter() - t0 - (result.books_s - books0)  # (recording the chunks: not waiting)
        result.write_wait_s += 0.0 if not result.simulate_s else max(0.0, loop_s - result.simulate_s / len(devices))


def add_timings(result, timings: dict) -> None:
    for k, v in timings.items():
        result.timings[k] = result.timings.get(k, 0.0) + v
