"""The batch's writer pool, in a module of its own: the writer processes import this one, not the
simulation (Warp, SciPy), so that each starts in about half the time and leaves the batch's own
process more of the host while it reads the variants.

Where the platform has it, the processes are forked from a server process (multiprocessing's
``forkserver``) that imported usd-core and NumPy once: a pool of N processes then pays for that
import once instead of N times (each process still imports warp_tube's writing, ~0.03 s), which on
a host of 16 cores had slowed the batch's own reading and building beside them; and later batches
of the same process find the server running.

Processes write the USD layouts (usd-core holds Python's lock while it writes); threads write
arrays (``os.pwrite`` and NumPy copies release it).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import select
import signal
import threading
import time

from .outputs import WriteTask, write

__all__ = ["Writers", "writer_count", "inline_write_seconds", "INLINE_WRITE_S", "ARRAY_WRITER_THREADS", "ignore_sigint",
           "watch_batch", "terminate_pool", "children_deaf_to_ctrl_c", "timed_write", "timed_write_when_ready", "writer_context", "spawn_context"]


def terminate_pool(pool: cf.ProcessPoolExecutor) -> None:
    """Stop a process pool's processes at once and let it go without waiting for their work."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        proc.terminate()
    for proc in processes:
        proc.join(timeout=5)
    # Its manager thread closes the pool's wake-up pipe once it sees the processes gone; at exit
    # Python writes to that pipe without the pool's lock (3.11), and a batch ending meanwhile
    # printed "Exception ignored ... Bad file descriptor" after its last line.
    if manager is not None and manager is not threading.current_thread():
        manager.join(timeout=5)


@contextlib.contextmanager
def children_deaf_to_ctrl_c():
    """SIGINT blocked in this (the main) thread over the block: the processes a pool starts in it
    inherit it blocked until their initializer ignores it (a Ctrl-C to the process group while a
    spawned one imported its modules printed its traceback); one arriving meanwhile is delivered
    here when the block ends."""
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def ignore_sigint(batch_pid: int | None = None):
    """Worker processes leave Ctrl-C to the batch, which stops them in order; and end when the
    batch's process ``batch_pid`` ends without stopping them (:func:`watch_batch`), or None."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if batch_pid is not None:
        watch_batch(batch_pid)


def watch_batch(pid: int) -> None:
    """End this process when process ``pid`` (the batch that started it) has ended.

    A pool's process waits for work on a queue it holds both ends of, so it never sees the batch
    go: a batch killed with SIGKILL (or by the system, short of memory) left its writer processes,
    their fork server and multiprocessing's resource tracker running for ever. A thread here waits
    for the batch's process to end (on a pidfd where Linux has them, else checking every second)
    and ends this one at once; what a writer left half-written is a hidden temporary file, which
    ``--resume`` removes."""

    def wait() -> None:
        try:
            fd = os.pidfd_open(pid)
        except (AttributeError, OSError):  # (not Linux, or the batch has ended already)
            fd = None
        if fd is not None:
            select.select([fd], [], [])  # readable once the process has ended
        else:
            while True:
                try:
                    os.kill(pid, 0)
                except ProcessLookupError:
                    break
                except PermissionError:
                    pass
                time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=wait, name="batch-watch", daemon=True).start()


class Writers:
    """The writer pool: processes for USD layouts (usd-core holds the GIL while it writes),
    threads for arrays (``os.pwrite`` and NumPy copies release it); for a large table started
    before the variants are read, so the processes are up by the time the first chunk is
    simulated (started once the variants were read instead, on an H100 host, they took as long
    from the first chunks' build as they had from the reading: 16,384 variants, everything but the
    kernels and writing 2.29 / 2.32 s against 2.19 / 2.40 s); for a small one once its size is
    known (:meth:`start`), if its writing is worth their start (:data:`INLINE_WRITE_S`)."""

    def __init__(self, layout: str, count: int):
        self.count = 0
        self.processes = layout != "arrays"
        self.pool = None
        self._starter = None
        self.start(count)

    def start(self, count: int) -> None:
        """Start ``count`` writers (none: the batch writes in its simulating process), once."""
        if count == 0 or self.pool is not None:
            return
        self.count = count
        if self.processes:
            self.pool = cf.ProcessPoolExecutor(count, mp_context=writer_context(), initializer=ignore_sigint,
                                               initargs=(os.getpid(),))  # fmt: skip
            # Started now (one new process per waiting task), from a thread: the first start waits
            # for the fork server's imports (~0.3 s), which the batch's reading need not wait for.
            self._starter = threading.Thread(target=_start, args=(self.pool, count), name="batch-writer-start", daemon=True)
            self._starter.start()
        else:
            self.pool = cf.ThreadPoolExecutor(count, thread_name_prefix="batch-writer")

    def _started(self):
        """Wait until every process was asked to start (before the pool is stopped)."""
        if self._starter is not None:
            self._starter.join()
            self._starter = None

    def shutdown(self):
        self._started()
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)

    def terminate(self):
        """Stop the processes at once: interrupted while they read the table (nothing of theirs is
        kept), or once every write has returned (its files complete), rather than wait for each to
        exit in turn (13 on an H100 host: ~0.3 s); threads are left to finish."""
        self._started()
        if self.processes and self.pool is not None:
            terminate_pool(self.pool)
            self.pool = None


#: what a writer process imports before its first chunk
WRITER_MODULES = ("pxr.Sdf", "pxr.Usd", "pxr.UsdGeom", "pxr.Vt", "warp_tube.io.writer")
#: what the fork server imports for them: the libraries alone (most of the import time), never
#: warp_tube, which the server would find by its own ``sys.path`` (the current folder first, not
#: the batch's: Python before 3.13 does not hand it over), perhaps another copy than the batch's
SERVER_MODULES = ("numpy", "pxr.Sdf", "pxr.Usd", "pxr.UsdGeom", "pxr.Vt")


def writer_context():
    """The multiprocessing context the writer processes start in: ``forkserver``, its server
    importing :data:`SERVER_MODULES`, where the platform has it; else ``spawn``."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return spawn_context()
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(SERVER_MODULES))  # (read when the server starts: once a process)
    _helpers_deaf_to_hangup(ctx)
    return ctx


def spawn_context():
    """The ``spawn`` multiprocessing context, its resource tracker started deaf to SIGHUP."""
    ctx = multiprocessing.get_context("spawn")
    _helpers_deaf_to_hangup(ctx)
    return ctx


def _helpers_deaf_to_hangup(ctx) -> None:
    """Start multiprocessing's resource tracker (and ``ctx``'s fork server) with SIGHUP blocked, as
    the processes they start inherit it. A closed terminal hangs up the whole process group; the
    batch stops its processes in order, as for Ctrl-C, and needs these two to outlive the signal
    (the tracker ignores SIGINT and SIGTERM itself: killed by SIGHUP, it was started again and
    printed a traceback for every semaphore the first had registered). Blocked, not ignored, in
    this process meanwhile: a hangup arriving then is delivered once it is unblocked."""
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        return
    from multiprocessing import resource_tracker

    # SIGINT too: a Ctrl-C to the process group while the fork server imports usd-core killed it
    # with a traceback, and the writers it was to start then failed as if killed from outside.
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGHUP, signal.SIGINT})
    try:
        resource_tracker.ensure_running()
        if ctx.get_start_method() == "forkserver":
            from multiprocessing import forkserver

            # (again: starting the tracker unblocks SIGINT and SIGTERM, whatever they were before)
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGHUP, signal.SIGINT})
            forkserver.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _start(pool: cf.ProcessPoolExecutor, count: int) -> None:
    """Start ``count`` processes of ``pool`` (each importing what writing needs)."""
    try:
        for _ in range(count):
            pool.submit(warm_writer)
    except RuntimeError:  # the pool was shut down meanwhile (bad input, interrupted), or broke
        pass
    except (OSError, EOFError):  # no process could start, the fork server gone (the writes, started on demand, report it)
        pass


def warm_writer():
    """Import what writing needs, so that the first chunk does not wait for it."""
    import importlib

    for name in WRITER_MODULES:
        importlib.import_module(name)


def timed_write(task: WriteTask):
    t0 = time.perf_counter()
    out = write(task)
    return out, time.perf_counter() - t0


def timed_write_when_ready(ready: cf.Future, task: WriteTask):
    """:func:`timed_write` once the chunk's frames are in its arrays (``ready``)."""
    ready.result()
    return timed_write(task)


#: a batch of USD outputs is written in its simulating process, not by writer processes, where that
#: would take less than this [s]: about what starting the processes costs (the fork server's imports
#: ~0.3 s on a 2-core CPU), which a batch of a few small variants would spend for nothing
INLINE_WRITE_S = 0.3
#: usd-core writing from one process, per output file and per point of a written frame (its
#: Centerline points, Surface points and normals) [s]: ``benchmarks/bench_batch.py``'s floor on the
#: 2-core CPU, 200 variants of 1,432 points a frame: 0.46-0.57 ms a variant of 1 frame, 2.42-2.50 ms
#: of 61
FILE_S, POINT_S = 5e-4, 2.3e-8


def inline_write_seconds(variants: int, frames: int, points: int, vertices: int) -> float:
    """About how long one process takes to write ``variants`` USD outputs of ``frames`` written
    frames, ``points`` centerline points and ``vertices`` surface vertices each [s]."""
    return variants * (FILE_S + frames * (points + 2 * vertices) * POINT_S)


#: writer threads for the arrays layout by default: its writes wait on the disk, not the cores, and
#: more threads only contend with the simulating thread for the GIL between their copies
ARRAY_WRITER_THREADS = 8


def writer_count(writers, sims: int, layout: str = "files") -> int:
    """Writers by default: the cores the simulating processes leave (at most 32), less one core in
    eight for their copying threads (16 cores, one GPU: 13 writer processes, which on an H100
    host took less wall time than 15, the simulating process no longer slowed by them), or for
    arrays at most :data:`ARRAY_WRITER_THREADS` threads; ``writers`` when given."""
    if writers is not None:
        return writers
    total = os.cpu_count() or 2
    cores = max(1, min(32, total - sims - total // 8))
    return min(cores, ARRAY_WRITER_THREADS) if layout == "arrays" else cores
