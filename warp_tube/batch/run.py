"""``warp-tube batch``: thousands of variants of a scene in one run.

:func:`run_batch` reads every variant (:mod:`warp_tube.batch.variants`; nothing runs if any is
bad), groups them into chunks that run as the worlds of one model (:mod:`warp_tube.batch.plan`),
simulates the chunks (:mod:`warp_tube.batch.engine`) and writes them (:mod:`warp_tube.batch.outputs`)
with a pool of writer processes, so the next chunk simulates while the last one is written.

Where chunks run:

- one device (``--device``, or a host with one GPU, or the CPU with ``--workers 1``): in this
  process;
- several GPUs of the host: one worker process per GPU (all of them, or ``--workers N``);
- the CPU with ``--workers N``: N worker processes (Warp's CPU backend runs one thread each);
- ``--scheduler ADDRESS``: the chunks are tasks of a Dask distributed cluster; each task
  simulates on its worker's default device (or ``--device``) and writes its outputs into the batch
  folder, which every worker must see at the same path.

Finished chunks are recorded (:mod:`warp_tube.batch.journal`) as their outputs complete; an
interrupted batch keeps them and ``--resume`` goes on from there.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import math
import multiprocessing
import os
import signal
import time
from concurrent.futures.process import BrokenProcessPool

from ..runtime.collector import collector_paused, thaw
from ..runtime.interrupts import (Terminated, deferred_interrupts, interrupt_for, interrupt_received, kept_interrupts,
                                  raise_if_interrupted, stopped_by)  # fmt: skip
from ..runtime.replay import SIM_LOCK, holding
from ..scene.spec import SceneError
from ..scene.usd import MAX_FRAMES
from ..sim.budget import whole_number
from ..sim.output import unwritten_frames
from .engine import SURFACE_OUTPUTS, output_frames
from .result import BatchResult, _strained
from .bookkeeping import PROCESS_VARIANTS, Bookkeeper
from .recorder import Recorder
from .cluster import SchedulerLost, check_dask, check_scheduler_address, dask_client, run_dask
from .execute import SimWorkers, run_here, run_pooled
from .framestore import prepare_copies, release_windows
from .worlds import release_builders
from .folder import (check_inputs_not_outputs, check_out_dir, named_files, named_paths, outputs_kept, remove_stray_partials,
                     scene_dependencies, scene_files)
from .writer_pool import INLINE_WRITE_S, Writers, inline_write_seconds, writer_count
from .journal import Journal, file_digest
from .lock import BatchLock
from .main_module import may_start_processes
from .outputs import (LAYOUTS, OutputSpec, check_batch_fits, finish_arrays, grid_offsets, output_spec, prepare_arrays,
                      surface_topology, write_grid_root, write_summary)  # fmt: skip
from .plan import by_identity, group_key, plain_group_keys, plan_chunks
from .prepare import prepare_batch
from .progress import Progress
from .rows import Rows, batch_columns, record_count

log = logging.getLogger(__name__)

__all__ = ["run_batch", "BatchResult", "BatchInterrupted", "DEFAULT_CHUNK_CPU", "DEFAULT_CHUNK_CUDA"]

#: variants per chunk by default on the CPU and on a GPU (a chunk's output arrays stay in memory,
#: or in /dev/shm, until written: 4,096 variants x 61 frames of a 20 x 16 tube are ~2 GB)
DEFAULT_CHUNK_CPU = 1024
DEFAULT_CHUNK_CUDA = 4096
#: tables of fewer rows (or none) start their writer processes, if any, once the batch's size is
#: known (:data:`~warp_tube.batch.writer_pool.INLINE_WRITE_S`); larger ones while they are read
DEFER_ROWS = 256


class BatchInterrupted(KeyboardInterrupt):
    """The batch was interrupted; ``result`` says what was finished (kept for ``--resume``),
    ``signum`` by which signal (SIGINT for Ctrl-C; SIGTERM, SIGHUP)."""

    def __init__(self, result, signum: int = signal.SIGINT):
        super().__init__("interrupted")
        self.result = result
        self.signum = int(signum)


def _devices(device, workers, scheduler, cpu_default: int = 1) -> list[str]:
    from ..sim.simulation import resolve_device

    if workers is not None and workers < 1:
        raise SceneError(f"--workers {workers}: expected at least 1")
    from ..runtime.warp_setup import init_warp

    init_warp()  # quietly, as every command starts Warp
    if scheduler:
        check_dask()
        return ["dask"]
    import warp as wp

    if device is not None:
        dev = resolve_device(device)
        if dev == "cpu":
            return ["cpu"] * _cpu_workers(workers, cpu_default)
        if workers not in (None, 1):
            raise SceneError(f"--workers {workers} with --device {device}: one device runs one worker; leave out --device to use every GPU")
        return [dev]
    gpus = wp.get_cuda_device_count()
    if gpus:
        n = workers or gpus
        if n > gpus:
            raise SceneError(f"--workers {n}: this host has {gpus} GPU(s); a GPU runs one worker (--device cpu for CPU workers)")
        return [f"cuda:{i}" for i in range(n)]
    return ["cpu"] * _cpu_workers(workers, cpu_default)


#: a CPU batch written as arrays runs a worker process on each core where its table has at least
#: this many rows a worker (the simulation sets its time, and each worker writes its own chunks:
#: on 2 cores 1,024 variants x 61 frames took 4.2 s against 6.1-6.6 s in one process); files and a
#: grid keep one (their writer processes set the time, and need the cores: 6.0-6.7 s either way)
CPU_WORKER_ROWS = 512


def _cpu_workers(workers: int | None, default: int = 1) -> int:
    """CPU worker processes for ``--workers`` (``default`` where not given): at most one per core
    this process may use (each runs one thread; more only compete for the cores), with a warning
    where more were asked for."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # (not on every system)
        cores = os.cpu_count() or 1
    if workers is not None and workers > cores:
        log.warning("--workers %d: this host gives this process %d CPU core(s); running %d worker(s) (each runs one thread)",
                    workers, cores, cores)  # fmt: skip
        return cores
    return workers or max(1, min(default, cores))


def _default_cpu_workers(layout: str, tab) -> int:
    """CPU workers a batch runs without ``--workers`` (see :data:`CPU_WORKER_ROWS`)."""
    if layout != "arrays" or tab is None:
        return 1
    return max(1, len(tab.rows) // CPU_WORKER_ROWS)


@holding(SIM_LOCK)  # (a simulation or another batch in another thread waits)
def run_batch(scene: str, out_dir: str, table: str | None = None, *, variant_sets: str | list[str] | None = None,
              layout: str = "files", every: int = 1, frames: int | None = None, surface: bool | None = None,
              device: str | None = None, workers: int | None = None, writers: int | None = None,
              chunk: int | None = None, scheduler: str | None = None, resume: bool = False, progress: bool | str = False,
              on_chunk=None) -> BatchResult:  # fmt: skip
    """Run a batch (see the module docstring and README, "Batch").

    Args:
        scene: the scene file.
        out_dir: the batch folder (created; must not hold another batch unless ``resume``).
        table: the variants table (CSV), or None.
        variant_sets: ``all``, or the scene's variantSets to cross with the table: a list of names
            (``["shape"]``, ``["/World/Tube{shape}"]``) or one comma-separated string as the
            command line takes it.
        layout: "files", "grid" or "arrays".
        every: write every ``every``-th frame.
        frames: frames per variant, frame 0 (rest) included (default: the scene's).
        surface: write the Surface (default: yes for files and grid, no for arrays).
        device: "cpu" or "cuda:N" (default: every GPU, else the CPU).
        workers: processes on the CPU, or how many GPUs (default: all GPUs; on the CPU one, or one a
            core for ``arrays`` with :data:`CPU_WORKER_ROWS` table rows a core or more).
        writers: writer processes, threads for ``arrays`` (default: the host's cores left over,
            at least 1, at most 8 threads for ``arrays``; none where a batch's USD outputs would
            be written in less than :data:`~warp_tube.batch.writer_pool.INLINE_WRITE_S` by one
            process, estimated from its size; 0: write in the simulating process).
        chunk: variants per chunk (default :data:`DEFAULT_CHUNK_CPU` / :data:`DEFAULT_CHUNK_CUDA`,
            fewer so that every worker gets two chunks).
        scheduler: a Dask scheduler address, to run the chunks on a Dask cluster.
        resume: go on with the unfinished batch in ``out_dir``.
        progress: True: progress bars (a terminal); ``"lines"``: a plain line every 30 s with the
            variant-frames and variants done and the time left (a log file); False: none.
        on_chunk: called with each chunk's id when it is finished (recorded).

    Returns:
        The :class:`BatchResult`.

    Raises:
        SceneError: bad input or request; nothing was run and nothing written.
        BatchInterrupted: interrupted; the finished chunks are kept.
    """
    if getattr(multiprocessing.current_process(), "_inheriting", False):  # a spawned process importing __main__
        raise SceneError('run_batch: called again by a process the batch started, as it imports the main module: '
                         'in a script, call it under if __name__ == "__main__":')  # fmt: skip
    for name, value in (("scene", scene), ("table", table), ("out_dir", out_dir)):
        if not (isinstance(value, (str, os.PathLike)) or (value is None and name == "table")):
            hint = " (a Scene object: write it with warp_tube.scene.usd.save_scene, then pass the file)" if name == "scene" else ""
            raise SceneError(f"run_batch: {name} is a {type(value).__name__}: expected a path{hint}")
    if scheduler is None and not (workers == 1 and writers == 0):
        # A script calling the batch outside if __name__ == "__main__": refused whether or not this
        # batch starts processes (a small table's may not; the same script on a larger one would).
        asked = "worker" if workers not in (None, 1) else "writer" if writers not in (None, 0) or layout != "arrays" else "worker"
        may_start_processes(asked, False)
    if variant_sets is not None and not isinstance(variant_sets, str):
        variant_sets = ",".join(str(v) for v in variant_sets) or None
    elif variant_sets is not None and not variant_sets.strip():
        raise SceneError("--variant-sets '': expected all, or SET or /PRIM{SET} names")
    late: list = []  # the signal that came while the complete result was being saved (then kept)
    try:
        # From the start: a Ctrl-C that usd-core swallows (raised inside an import it makes for a
        # stage it opens) still stops the batch at its next check, instead of being lost.
        with kept_interrupts():
            result = _batch(scene, out_dir, table, late, variant_sets=variant_sets, layout=layout, every=every,
                            frames=frames, surface=surface, device=device, workers=workers, writers=writers, chunk=chunk,
                            scheduler=scheduler, resume=resume, progress=progress, on_chunk=on_chunk)  # fmt: skip
    except (BrokenProcessPool, OSError, EOFError):
        # The signal reached the writer and worker processes (and their fork server) too: a pool
        # that broke or a connection refused after it is the user's stop, not a failure.
        signum = interrupt_received()
        if signum is None:
            raise
        raise interrupt_for(signum) from None
    if late and late[0]:
        log.warning("%s while the batch's complete result was being saved: the save was finished: the outputs in %s "
                    "are complete", stopped_by(Terminated(late[0][0])), result.out_dir)  # fmt: skip
    return result


def _batch(scene, out_dir, table, late: list, *, variant_sets, layout, every, frames, surface, device, workers, writers,
           chunk, scheduler, resume, progress, on_chunk) -> BatchResult:  # fmt: skip
    """:func:`run_batch` once its arguments' types are checked (``late``: see :func:`_run_batch`)."""
    from .table import read_table
    t_start = time.perf_counter()
    if not str(os.fspath(out_dir)).strip():
        raise SceneError("-o '': expected a folder name (the batch folder)")
    out_dir = os.path.abspath(os.fspath(out_dir))
    if layout not in LAYOUTS:
        raise SceneError(f"--layout {layout}: expected one of {', '.join(LAYOUTS)}")
    # (as Simulation.run takes them: 2.0 is 2; 2.5, "3" and True are refused, not run as 2, 1 or a TypeError)
    every = whole_number("every", every)
    frames, chunk, workers, writers = (None if v is None else whole_number(name, v) for name, v in
                                       (("frames", frames), ("chunk", chunk), ("workers", workers), ("writers", writers)))  # fmt: skip
    if every < 1:
        raise SceneError(f"--every {every}: expected at least 1")
    if frames is not None and not 1 <= frames <= MAX_FRAMES + 1:
        raise SceneError(f"--frames {frames}: expected 1 to {MAX_FRAMES + 1:,}")
    if chunk is not None and chunk < 1:
        raise SceneError(f"--chunk {chunk}: expected at least 1")
    if scheduler is not None:  # ('' too: not a silent run here)
        check_scheduler_address(scheduler)
    if writers is not None and writers < 0:
        raise SceneError(f"--writers {writers}: expected 0 or more")
    surface = (layout != "arrays") if surface is None else bool(surface)
    check_inputs_not_outputs(out_dir, [("the scene", scene), ("the variants table", table)])
    with collector_paused():  # (a tuple per row: see runtime.collector)
        tab = read_table(table) if table is not None else None
    layers, named = scene_dependencies(scene), named_paths(tab)
    check_inputs_not_outputs(out_dir, [("a layer or asset the scene uses", p) for p in layers]
                              + [("a file the table names", p) for p in named.values()])  # fmt: skip
    check_out_dir(out_dir, resume)
    devices = _devices(device, workers, scheduler, _default_cpu_workers(layout, tab))
    if len(devices) > 1 and not scheduler and not may_start_processes("worker", workers is not None):
        devices = devices[:1]  # (a script on stdin: simulated in this process)
    sims = 0 if scheduler else len(devices)
    sim_workers = SimWorkers(devices) if sims > 1 else None  # up while the variants are read
    lock = BatchLock(out_dir)
    frozen_before = gc.get_freeze_count()
    with contextlib.ExitStack() as saving:  # held from when the result is complete to the end of the clean-up
        return _batch_pools(scene, out_dir, table, tab, devices, sim_workers, t_start, lock, frozen_before, saving, late,
                            layers=layers, named=named, writers=writers, sims=sims, variant_sets=variant_sets, layout=layout,
                            every=every, frames=frames, surface=surface, device=device, chunk=chunk, scheduler=scheduler,
                            resume=resume, progress=progress, on_chunk=on_chunk)  # fmt: skip


def _batch_pools(scene, out_dir, table, tab, devices, sim_workers, t_start, lock, frozen_before, saving, late, *, layers,
                 named, writers, sims, variant_sets, layout, every, frames, surface, device, chunk, scheduler, resume,
                 progress, on_chunk) -> BatchResult:  # fmt: skip
    """:func:`_batch` from its writer pool on (see :func:`_run_batch` for ``saving`` and ``late``)."""
    writer_pool = recorder = result = None
    try:
        count = 0 if scheduler else writer_count(writers, sims, layout)
        # A small batch of USD outputs: whether its writing is worth starting processes for is
        # decided once its size is known (a large table's writers start now, while it is read).
        deferred = count if count and writers is None and layout != "arrays" and (tab is None or len(tab.rows) < DEFER_ROWS) else 0
        if count and not deferred and layout != "arrays" and not may_start_processes("writer", writers is not None):
            count = 0  # (a script on stdin: written in this process)
        writer_pool = Writers(layout, 0 if deferred else count)
        if tab is not None and len(tab.rows) >= PROCESS_VARIANTS:
            recorder = Recorder()  # (starting while the variants are read)
        result = _run_batch(scene, out_dir, table, tab, devices, writer_pool, sim_workers, t_start, lock,
                            variant_sets=variant_sets, layout=layout, every=every, frames=frames, surface=surface,
                            device=device, chunk=chunk, scheduler=scheduler, resume=resume, progress=progress,
                            on_chunk=on_chunk, layers=layers, named=named, recorder=recorder, deferred=deferred,
                            saving=saving, late=late)  # fmt: skip
        writer_pool.terminate()  # (every write returned: its files are complete)
    except BaseException:
        if sim_workers is not None:  # bad input or interrupted: do not wait for them
            sim_workers.terminate()
        raise
    finally:
        # (each step whatever the one before raised, in the reverse order: a second Ctrl-C in the writers' end had left the lock)
        with contextlib.ExitStack() as ends:
            ends.callback(release_windows)  # (the device buffers kept for the frames' windows)
            ends.callback(release_builders)  # (the surface builders kept for the next chunk)
            ends.callback(thaw, frozen_before)  # (the batch's objects, kept out of the collector's passes)
            ends.callback(lock.release)  # (after the writers: their files are complete or gone)
            # Stopped: what a writer killed mid-file left (a SIGTERM to the process group reaches the
            # writer processes too, which Ctrl-C and a hangup do not stop), once every writer is gone.
            ends.callback(lambda: result is None and remove_stray_partials(out_dir))
            if recorder is not None:
                # (after the records it was given are made; when the batch ended, they are back: drained)
                ends.callback(lambda: recorder.close(wait=result is None))
            if sim_workers is not None:
                ends.callback(sim_workers.shutdown)
            if writer_pool is not None:
                ends.callback(writer_pool.shutdown)
    result.wall_s = time.perf_counter() - t_start  # (the writers' and workers' ends included)
    return result


def _run_batch(scene, out_dir, table, tab, devices, writer_pool, sim_workers, t_start, lock, *, variant_sets, layout, every,
               frames, surface, device, chunk, scheduler, resume, progress, on_chunk, layers, named, recorder,
               deferred=0, saving=None, late=None) -> BatchResult:  # fmt: skip
    """The batch. Once every chunk is finished, interrupts are held back on ``saving`` (closed after
    the clean-up; ``late`` gets the list naming one that came): the complete result is kept and its
    work folder and lock removed, as ``run`` keeps a complete output, not left half done."""

    bar = Progress(progress)
    if len(devices) == 1 and not scheduler:  # (simulated in this process: its copying set up meanwhile)
        prepare_copies(devices[0])
    readers = writer_pool.pool if writer_pool.processes else None  # idle until the first chunk is simulated
    try:
        variants, choices, kept = prepare_batch(scene, tab, variant_sets, bar, readers, writer_pool.count,
                                                keep_nodes=len(devices) == 1 and not scheduler, freeze=True)  # (built in this process)
    except KeyboardInterrupt:
        writer_pool.terminate()  # (they may be reading parts of the table: not worth waiting for)
        raise
    bar.close_reading()
    first = variants.variants[0].scene
    n_frames = first.stage.frame_count if frames is None else int(frames)
    memo: dict = {}
    with collector_paused(freeze=True):  # (one small key per variant: see runtime.collector)
        if variants.plain:
            keys = plain_group_keys(variants.variants[0].scene, choices, memo)
        else:
            keys = [group_key(v.scene, c, memo) for v, c in zip(variants.variants, choices)]
    journal = Journal(out_dir)
    if chunk is None:
        base = DEFAULT_CHUNK_CUDA if devices[0].startswith("cuda") else DEFAULT_CHUNK_CPU
        parallel = len(devices) if devices != ["dask"] else 4
        chunk = max(1, min(base, math.ceil(len(variants) / (2 * parallel))))
        if resume and journal.exists():  # the chunks of the batch being resumed
            import json

            with open(journal.state_path, encoding="utf-8") as f:
                chunk = int(json.load(f).get("chunk", chunk))
    plan = plan_chunks(keys, chunk)
    F_idx = output_frames(n_frames, every)
    time_codes = tuple(first.stage.start_time_code + k for k in F_idx)
    signature = dict(version=1, scene=os.path.abspath(scene), scene_sha256=file_digest(scene),
                     table=os.path.abspath(table) if table else None, table_sha256=file_digest(table),
                     variant_sets=variant_sets, layout=layout, every=every, frames=n_frames, surface=surface,
                     chunk=chunk, variants=len(variants))  # fmt: skip
    table_digests, scene_digests = named_files(named), scene_files(layers)
    if table_digests:  # (left out where there are none: a batch begun before they were recorded resumes)
        signature["table_files"] = table_digests
    if scene_digests:
        signature["scene_files"] = scene_digests
    if len(F_idx) == 1 and n_frames > 1:
        log.warning("--every %d: of frames 0 to %d only frame 0 is written", every, n_frames - 1)
    elif F_idx[-1] < n_frames - 1:  # as warp-tube run says it
        log.warning("--every %d: %s", every, unwritten_frames(F_idx[-1] + 1, n_frames - 1, F_idx[-1]))
    result = BatchResult(out_dir=out_dir, variants=len(variants), groups=len({c.group for c in plan}), chunks=len(plan),
                         devices=devices if devices != ["dask"] else [f"dask {scheduler}"], frames=len(F_idx))  # fmt: skip
    with collector_paused(freeze=True):  # per variant its points and vertices
        counts = _counts(variants.variants[:1], surface) * len(variants) if variants.plain else _counts(variants.variants, surface)
    spec = output_spec(variants, counts, layout, out_dir, journal.dir, surface, time_codes)
    if not resume:
        check_batch_fits(spec, counts, chunk)
    if deferred and inline_write_seconds(len(variants), len(F_idx), spec.points, spec.vertices) >= INLINE_WRITE_S \
            and may_start_processes("writer", False):  # fmt: skip
        writer_pool.start(deferred)  # (else it is written here: less than the processes' start)
    result.prepare_s = time.perf_counter() - t_start

    if resume and not journal.exists():  # the batch there finished: nothing to do
        journal.check_finished(signature)
        result = _finished(out_dir, result, t_start)
        if os.path.isdir(journal.dir):  # (what a batch stopped while removing it left: its record is gone)
            lock.acquire()
            journal.remove_leftover()
        return result
    if scheduler:
        dask_client(scheduler).close()  # the scheduler answers: checked before anything is written
    os.makedirs(out_dir, exist_ok=True)
    lock.acquire()  # before anything is written there (released by run_batch, however it ends)
    done = outputs_kept(journal.begin(signature, resume), layout, out_dir, journal.dir)
    remove_stray_partials(out_dir)
    if layout == "arrays":
        prepare_arrays(spec, resume=bool(done))
    if layout == "grid":
        os.makedirs(os.path.join(out_dir, "grid"), exist_ok=True)
    records = dict(done)
    for rec in done.values():
        result.resumed += record_count(rec)
    todo = [c for c in plan if c.id not in done]
    bar.start(sum(len(c.indices) for c in todo) * max(n_frames - 1, 1), len(variants), result.resumed)

    books = Bookkeeper(journal, variants.variants, recorder)

    def finish(chunk_id: int, rows: Rows, outputs: list):
        t = time.perf_counter()
        c = plan[chunk_id]
        rec = {"rows": {"index": list(c.indices), **rows.columns, "output": list(outputs)},
               "layer": f"grid/chunk_{chunk_id:05d}.usdc" if layout == "grid" and any(outputs) else ""}  # fmt: skip
        records[chunk_id] = books.record(chunk_id, rec)
        bar.variants_done(len(c.indices))
        result.books_s += time.perf_counter() - t
        if on_chunk is not None:
            on_chunk(chunk_id)

    # the surface's arrays the chunks make: the arrays layout writes its points alone
    parts = (("points",) if layout == "arrays" else SURFACE_OUTPUTS) if surface else ()
    context = dict(variants=variants, plan=plan, choices=choices, kept=kept, frames=n_frames, every=every, surface=parts,
                   spec=spec, writers=writer_pool, device=device, scheduler=scheduler, bar=bar, finish=finish)  # fmt: skip
    try:
        if not todo:
            pass
        elif scheduler:
            run_dask(todo, context, result)
        elif len(devices) == 1:
            run_here(todo, devices[0], context, result)
        else:
            run_pooled(todo, devices, sim_workers, context, result)
        raise_if_interrupted()  # (one that a finalizer or usd-core dropped: before the result is saved)
    except (BrokenProcessPool, SchedulerLost, OSError, EOFError):
        signum = interrupt_received()
        if signum is None:  # a process killed from outside, a scheduler gone: what finished stays resumable
            bar.close()
            books.drain()
            raise
        # (after a Ctrl-C: the pool broke because the signal reached its processes)
        _interrupted(result, bar, books, records, variants, t_start, signum)
    except KeyboardInterrupt as e:
        _interrupted(result, bar, books, records, variants, t_start, getattr(e, "signum", signal.SIGINT))
    if saving is not None:
        late.append(saving.enter_context(deferred_interrupts()))
    bar.close()
    t = time.perf_counter()
    books.drain()
    result.books_s += time.perf_counter() - t
    _finish_outputs(spec, variants, counts, records, first, out_dir, books)
    journal.finish()
    _tally(result, records, variants)
    result.wall_s = time.perf_counter() - t_start
    return result


def _interrupted(result, bar, books, records, variants, t_start, signum):
    """Raise :class:`BatchInterrupted` for a batch stopped by ``signum``, what it finished recorded."""
    bar.close()
    books.drain()  # every chunk recorded as finished is in the journal
    _tally(result, records, variants)
    result.pending = len(variants) - sum(record_count(r) for r in records.values())
    result.wall_s = time.perf_counter() - t_start
    raise BatchInterrupted(result, signum) from None


def _finished(out_dir: str, result: BatchResult, t_start: float) -> BatchResult:
    """The result of resuming a batch that had finished: its summary, read back."""
    import csv

    path = os.path.join(out_dir, "summary.csv")
    if not os.path.exists(path):
        raise SceneError(f"{out_dir}: no unfinished batch (.batch) and no summary.csv: nothing to resume")
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
    if not {"name", "status", "reason"} <= set(reader.fieldnames or ()):
        raise SceneError(f"{out_dir}: no batch there to resume ({path} is not a batch's summary)")
    outputs = dict.fromkeys(n for r in rows for n in r.get("output", "").split())
    gone = [n for n in outputs if not os.path.exists(os.path.join(out_dir, n))]
    if gone:
        log.warning("--resume: %s, written by the finished batch there, is missing (%d output file(s) missing): "
                    "a finished batch is not written again; run it into another folder",
                    os.path.join(out_dir, gone[0]), len(gone))  # fmt: skip
    result.resumed = len(rows)
    result.ok = sum(r["status"] == "ok" for r in rows)
    result.failed = len(rows) - result.ok
    result.failures = [(r["name"], r["reason"]) for r in rows if r["status"] != "ok"]
    result.contacts = [(r["name"], int(r["contact_frame"])) for r in rows if r.get("contact_frame", "") != ""]
    result.strained = _strained([r["name"] for r in rows], [r["status"] for r in rows], [r.get("max_stretch", "") for r in rows])
    result.wall_s = time.perf_counter() - t_start
    return result


def _tally(result: BatchResult, records: dict, variants) -> None:
    index, cols = batch_columns(records.values(), ("status", "reason", "contact_frame", "max_stretch"))
    vs = variants.variants
    result.strained = _strained([vs[i].name for i in index], cols["status"], cols["max_stretch"])
    result.ok = cols["status"].count("ok")
    result.failed = len(index) - result.ok
    result.failures = [(vs[i].name, r) for i, s, r in zip(index, cols["status"], cols["reason"]) if s != "ok"]
    result.contacts = [(vs[i].name, int(f)) for i, f in zip(index, cols["contact_frame"]) if f != ""]


def _counts(variants, surface: bool) -> list[tuple[int, int]]:
    """Per variant its centerline points and surface vertices (0 without the surface), all tube
    prims together; worked out once per set of tube arrays (a batch's variants share them)."""
    memo: dict = {}
    out = []
    for v in variants:
        tubes = v.scene.tubes
        arrays = tuple(a for t in tubes for a in (t.points, t.radius, t.spoke_lengths, t.curve_counts))
        extra = tuple(x for t in tubes for x in (t.params.spokes, t.params.caps))
        out.append(by_identity(memo, arrays, extra, _points_and_vertices if surface else _points, tubes))
    return out


def _points(tubes) -> tuple[int, int]:
    return sum(len(t.points) for t in tubes), 0


def _points_and_vertices(tubes) -> tuple[int, int]:
    return sum(len(t.points) for t in tubes), sum(surface_topology(t).vertex_count for t in tubes)


def _columns(counts: list, surface: bool) -> tuple[list, list]:
    """:func:`_counts` as the points of every variant and their vertices (none without the surface)."""
    return [p for p, _ in counts], ([n for _, n in counts] if surface else [])


def _finish_outputs(spec: OutputSpec, variants, counts: list, records: dict, first_scene, out_dir: str, books: Bookkeeper) -> None:
    index, cols = batch_columns(records.values(), ("status", "output", "max_displacement_m"))
    vs = variants.variants
    if index != list(range(len(vs))):
        raise RuntimeError(f"the batch's records hold {len(index)} variants, not each of its {len(vs)} once")
    if spec.layout == "arrays":
        scenes = ([vs[0].scene] * len(vs) if variants.plain else [v.scene for v in vs]) if spec.surface else None
        finish_arrays(spec, index, [v.name for v in vs], *_columns(counts, spec.surface), first_scene.stage, scenes)
    if spec.layout == "grid":
        layers = [records[c]["layer"] for c in sorted(records) if records[c]["layer"]]
        shown = [i for i, o in enumerate(cols["output"]) if o]  # (a failed variant's finished frames included)
        offsets = grid_offsets(spec, vs, shown, cols, records, first_scene.stage.meters_per_unit)
        write_grid_root(spec, first_scene.stage, layers, [vs[i].name for i in shown], offsets)
    write_summary(os.path.join(out_dir, "summary.csv"), variants.parameter_columns(), books.summary_text(records))
