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

import concurrent.futures as cf
import dataclasses
import math
import multiprocessing
import os
import shutil
import signal
import tempfile
import time
from dataclasses import dataclass, field

import numpy as np

from ..scene.spec import SceneError
from .engine import TIMERS, chunk_shapes, output_frames, simulate_chunk
from .journal import Journal, file_digest
from .outputs import (
    LAYOUTS,
    OutputSpec,
    WriteTask,
    finish_arrays,
    prepare_arrays,
    surface_topology,
    write,
    write_grid_root,
    write_summary,
)
from .plan import group_key, plan_chunks, run_choice, run_choices

__all__ = ["run_batch", "BatchResult", "BatchInterrupted", "DEFAULT_CHUNK_CPU", "DEFAULT_CHUNK_CUDA"]

#: variants per chunk by default on the CPU and on a GPU (a chunk's output arrays stay in memory,
#: or in /dev/shm, until written: 4,096 variants x 61 frames of a 20 x 16 tube are ~2 GB)
DEFAULT_CHUNK_CPU = 1024
DEFAULT_CHUNK_CUDA = 4096
#: files a batch writes into its folder (an existing one means a batch is there already)
BATCH_FILES = ("summary.csv", "centerline.npy", "surface.npy", "arrays.json", "grid.usda")


class BatchInterrupted(KeyboardInterrupt):
    """The batch was interrupted; ``result`` says what was finished (kept for ``--resume``)."""

    def __init__(self, result):
        super().__init__("interrupted")
        self.result = result


@dataclass
class BatchResult:
    """What a batch did.

    Attributes:
        out_dir: the batch folder.
        variants: variants in the batch.
        ok, failed: variants finished in this run (or before, when resuming), by status.
        resumed: variants finished by an earlier run and skipped.
        pending: variants not finished (an interrupted batch).
        groups, chunks: how the variants were run.
        devices: where the chunks ran ("dask" for a cluster).
        wall_s: the whole command [s]; prepare_s: reading and checking the variants and planning;
        simulate_s: simulating (wall, in this process; the sum over workers otherwise);
        write_s: the writer tasks' time, summed over writers; write_wait_s: waiting for writers
            after the last chunk was simulated.
        timings: the simulation's own split (build, kernels, readback, control, checks, copy, rerun), summed.
        failures: (variant name, reason) of the failed variants.
    """

    out_dir: str
    variants: int = 0
    ok: int = 0
    failed: int = 0
    resumed: int = 0
    pending: int = 0
    groups: int = 0
    chunks: int = 0
    devices: list = field(default_factory=list)
    wall_s: float = 0.0
    prepare_s: float = 0.0
    simulate_s: float = 0.0
    write_s: float = 0.0
    write_wait_s: float = 0.0
    frames: int = 0
    timings: dict = field(default_factory=lambda: dict.fromkeys(TIMERS, 0.0))
    failures: list = field(default_factory=list)

    def text(self) -> str:
        t = self.timings
        lines = [
            f"variants     {self.variants} in {self.groups} group(s), {self.chunks} chunk(s) on {', '.join(self.devices) or '-'}",
            f"finished     {self.ok} ok, {self.failed} failed" + (f" ({self.resumed} from before)" if self.resumed else ""),
            f"frames       {self.frames} per variant",
            f"wall time    {self.wall_s:.2f} s: reading {self.prepare_s:.2f} s, simulating {self.simulate_s:.2f} s "
            f"(kernels {t['kernels_s']:.2f} s, checks {t['checks_s']:.2f} s), waiting for writers {self.write_wait_s:.2f} s",
            f"output       {self.out_dir}",
        ]  # fmt: skip
        if self.pending:
            lines.append(f"unfinished   {self.pending} variant(s): warp-tube batch ... --resume goes on")
        lines += [f"failed       {name}: {reason}" for name, reason in self.failures[:10]]
        if len(self.failures) > 10:
            lines.append(f"failed       ... and {len(self.failures) - 10} more (summary.csv)")
        return "\n".join(lines)


def _ignore_sigint():
    """Worker processes leave Ctrl-C to the batch, which stops them in order."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


_worker_device = None


def _init_sim_worker(devices):
    global _worker_device
    _ignore_sigint()
    _worker_device = devices.get()


def _sim_task(payload):
    """A worker process simulates one chunk into memory-mapped arrays in the buffer folder."""
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    scenes, choice, frames, every, surface, buffer_dir, chunk = payload
    run = simulate_chunk(scenes, choice, _worker_device, frames, every, surface, allocate=_file_allocator(buffer_dir, chunk))
    paths = {name: a.filename for name, a in run.arrays.items()}
    for a in run.arrays.values():
        a.flush()
    return run.rows, paths, run.timings


def _dask_task(payload):
    """A Dask task: simulate one chunk on the worker's device and write its outputs."""
    import warp as wp

    from ..sim.simulation import resolve_device

    wp.config.log_level = wp.LOG_WARNING
    scenes, choice, frames, every, surface, device, tasks = payload
    t0 = time.perf_counter()
    run = simulate_chunk(scenes, choice, resolve_device(device), frames, every, surface)
    t1 = time.perf_counter()
    outputs = []
    for task in _with_rows(tasks, run.rows, run.arrays):
        outputs += write(task)
    return run.rows, outputs, run.timings, t1 - t0, time.perf_counter() - t1


class _Writers:
    """The writer pool: processes for USD layouts (usd-core holds the GIL while it writes),
    threads for arrays (``os.pwrite`` and NumPy copies release it); started before the variants
    are read, so the processes are up by the time the first chunk is simulated."""

    def __init__(self, layout: str, count: int):
        self.count = count
        self.processes = layout != "arrays"
        self.pool = None
        if count == 0:
            return
        if self.processes:
            ctx = multiprocessing.get_context("spawn")
            self.pool = cf.ProcessPoolExecutor(count, mp_context=ctx, initializer=_ignore_sigint)
            for _ in range(count):  # start them now (one new process per waiting task)
                self.pool.submit(_warm_writer)
        else:
            self.pool = cf.ThreadPoolExecutor(count, thread_name_prefix="batch-writer")

    def shutdown(self):
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)


def _warm_writer():
    from pxr import Sdf, Usd, UsdGeom, Vt  # noqa: F401

    from ..io import writer  # noqa: F401


def _timed_write(task: WriteTask):
    t0 = time.perf_counter()
    out = write(task)
    return out, time.perf_counter() - t0


def _file_allocator(folder: str, chunk: int):
    from numpy.lib.format import open_memmap

    def allocate(shapes: dict) -> dict:
        return {name: open_memmap(os.path.join(folder, f"chunk_{chunk:05d}.{name}.npy"), mode="w+", dtype=np.float32, shape=shape)
                for name, shape in shapes.items()}  # fmt: skip

    return allocate


def _with_rows(tasks: list[WriteTask], rows: list, arrays: dict) -> list[WriteTask]:
    """Fill the write tasks of a chunk with the simulation's rows and arrays."""
    out = []
    for t in tasks:
        out.append(WriteTask(spec=t.spec, chunk=t.chunk, variants=t.variants, positions=t.positions,
                             rows=tuple(rows[p] for p in t.positions), arrays=arrays))  # fmt: skip
    return out


def _buffer_folder(chunk_bytes: int, work_dir: str) -> str:
    """A folder for chunks' arrays between simulation and writing: /dev/shm when it has room for
    a few chunks (memory), else the batch's working folder."""
    shm = "/dev/shm"
    try:
        st = os.statvfs(shm)
        if os.access(shm, os.W_OK) and st.f_bavail * st.f_frsize > 4 * chunk_bytes:
            return tempfile.mkdtemp(prefix="warp-tube-batch-", dir=shm)
    except OSError:
        pass
    return tempfile.mkdtemp(prefix="buffers-", dir=work_dir)


def _devices(device, workers, scheduler) -> list[str]:
    from ..sim.simulation import resolve_device

    if workers is not None and workers < 1:
        raise SceneError(f"--workers {workers}: expected at least 1")
    if scheduler:
        return ["dask"]
    import warp as wp

    if device is not None:
        dev = resolve_device(device)
        if dev == "cpu":
            return ["cpu"] * (workers or 1)
        if workers not in (None, 1):
            raise SceneError(f"--workers {workers} with --device {device}: one device runs one worker; leave out --device to use every GPU")
        return [dev]
    wp.init()
    gpus = wp.get_cuda_device_count()
    if gpus:
        n = workers or gpus
        if n > gpus:
            raise SceneError(f"--workers {n}: this host has {gpus} GPU(s); a GPU runs one worker (--device cpu for CPU workers)")
        return [f"cuda:{i}" for i in range(n)]
    return ["cpu"] * (workers or 1)


def _check_out_dir(out_dir: str, resume: bool) -> None:
    parent = os.path.dirname(out_dir) or "."
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise SceneError(f"{out_dir}: exists and is not a folder")
    if not os.path.isdir(out_dir):
        if resume:
            raise SceneError(f"{out_dir}: no such folder: nothing to resume")
        if not os.path.isdir(parent):
            raise SceneError(f"{out_dir}: folder {parent} does not exist")
        if not os.access(parent, os.W_OK):
            raise SceneError(f"{out_dir}: folder {parent} is not writable")
        return
    if not os.access(out_dir, os.W_OK):
        raise SceneError(f"{out_dir}: folder is not writable")
    journal = Journal(out_dir)
    found = [n for n in BATCH_FILES if os.path.exists(os.path.join(out_dir, n))]
    found += sorted(n for n in os.listdir(out_dir) if n.startswith("variant_"))[:1]
    if resume:
        if not journal.exists() and not found:
            raise SceneError(f"{out_dir}: no batch there to resume")
    elif journal.exists() or found:
        what = ", ".join((["an unfinished batch (.batch)"] if journal.exists() else []) + found)
        raise SceneError(f"{out_dir}: holds batch outputs already ({what}): --resume continues that batch; "
                         "or write to another folder")  # fmt: skip


def _remove_stray_partials(out_dir: str) -> None:
    """Remove partial files that an interrupted writer left (never a complete output)."""
    for folder in (out_dir, os.path.join(out_dir, "grid")):
        if os.path.isdir(folder):
            for n in os.listdir(folder):
                if n.startswith(".") and ".partial-" in n:
                    os.remove(os.path.join(folder, n))


def run_batch(scene: str, out_dir: str, table: str | None = None, *, variant_sets: str | None = None,
              layout: str = "files", every: int = 1, frames: int | None = None, surface: bool | None = None,
              device: str | None = None, workers: int | None = None, writers: int | None = None,
              chunk: int | None = None, scheduler: str | None = None, resume: bool = False, progress: bool = False,
              on_chunk=None) -> BatchResult:  # fmt: skip
    """Run a batch (see the module docstring and README, "Batch").

    Args:
        scene: the scene file.
        out_dir: the batch folder (created; must not hold another batch unless ``resume``).
        table: the variants table (CSV), or None.
        variant_sets: ``all`` or a list of the scene's variantSets to cross with the table.
        layout: "files", "grid" or "arrays".
        every: write every ``every``-th frame.
        frames: frames per variant, frame 0 (rest) included (default: the scene's).
        surface: write the Surface (default: yes for files and grid, no for arrays).
        device: "cpu" or "cuda:N" (default: every GPU, else the CPU).
        workers: processes on the CPU, or how many GPUs (default: 1 on the CPU, all GPUs).
        writers: writer processes (default: the host's cores left over, at least 1; 0: write
            in the simulating process).
        chunk: variants per chunk (default :data:`DEFAULT_CHUNK_CPU` / :data:`DEFAULT_CHUNK_CUDA`,
            fewer so that every worker gets two chunks).
        scheduler: a Dask scheduler address, to run the chunks on a Dask cluster.
        resume: go on with the unfinished batch in ``out_dir``.
        progress: show progress bars.
        on_chunk: called with each chunk's id when it is finished (recorded).

    Returns:
        The :class:`BatchResult`.

    Raises:
        SceneError: bad input or request; nothing was run and nothing written.
        BatchInterrupted: interrupted; the finished chunks are kept.
    """
    from .table import read_table

    t_start = time.perf_counter()
    out_dir = os.path.abspath(os.fspath(out_dir))
    if layout not in LAYOUTS:
        raise SceneError(f"--layout {layout}: expected one of {', '.join(LAYOUTS)}")
    if every < 1:
        raise SceneError(f"--every {every}: expected at least 1")
    if frames is not None and frames < 1:
        raise SceneError(f"--frames {frames}: expected at least 1")
    if chunk is not None and chunk < 1:
        raise SceneError(f"--chunk {chunk}: expected at least 1")
    if writers is not None and writers < 0:
        raise SceneError(f"--writers {writers}: expected 0 or more")
    surface = (layout != "arrays") if surface is None else bool(surface)
    _check_out_dir(out_dir, resume)
    devices = _devices(device, workers, scheduler)
    tab = read_table(table) if table is not None else None
    sims = 0 if scheduler else len(devices)
    writer_pool = _Writers(layout, 0 if scheduler else _writer_count(writers, sims))
    try:
        return _run_batch(scene, out_dir, table, tab, devices, writer_pool, t_start, variant_sets=variant_sets,
                          layout=layout, every=every, frames=frames, surface=surface, device=device, chunk=chunk,
                          scheduler=scheduler, resume=resume, progress=progress, on_chunk=on_chunk)  # fmt: skip
    finally:
        writer_pool.shutdown()


def _run_batch(scene, out_dir, table, tab, devices, writer_pool, t_start, *, variant_sets, layout, every, frames, surface,
               device, chunk, scheduler, resume, progress, on_chunk) -> BatchResult:  # fmt: skip

    bar = _Progress(progress)
    variants, choices = _prepare(scene, tab, variant_sets, bar)
    bar.close_reading()
    first = variants.variants[0].scene
    n_frames = first.stage.frame_count if frames is None else int(frames)
    keys = [group_key(v.scene, c, surface) for v, c in zip(variants.variants, choices)]
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
    result = BatchResult(out_dir=out_dir, variants=len(variants), groups=len({c.group for c in plan}), chunks=len(plan),
                         devices=devices if devices != ["dask"] else [f"dask {scheduler}"], frames=len(F_idx))  # fmt: skip
    spec = _output_spec(variants, layout, out_dir, journal.dir, surface, time_codes)
    result.prepare_s = time.perf_counter() - t_start

    if resume and not journal.exists():  # the batch there finished: nothing to do
        return _finished(out_dir, result, t_start)
    os.makedirs(out_dir, exist_ok=True)
    done = journal.begin(signature, resume)
    _remove_stray_partials(out_dir)
    if layout == "arrays":
        prepare_arrays(spec, resume=bool(done))
    if layout == "grid":
        os.makedirs(os.path.join(out_dir, "grid"), exist_ok=True)
    records = dict(done)
    for rec in done.values():
        result.resumed += len(rec["rows"])
    todo = [c for c in plan if c.id not in done]
    bar.start(sum(len(c.indices) for c in todo) * max(n_frames - 1, 1), len(variants), result.resumed)

    def finish(chunk_id: int, rows: list, outputs: list):
        c = plan[chunk_id]
        rec = {"rows": {str(i): _json_row(r, o) for i, r, o in zip(c.indices, rows, outputs)},
               "layer": f"grid/chunk_{chunk_id:05d}.usdc" if layout == "grid" and any(r["status"] == "ok" for r in rows) else ""}  # fmt: skip
        journal.record(chunk_id, rec)
        records[chunk_id] = rec
        bar.variants_done(len(c.indices))
        if on_chunk is not None:
            on_chunk(chunk_id)

    context = dict(variants=variants, plan=plan, choices=choices, frames=n_frames, every=every, surface=surface,
                   spec=spec, writers=writer_pool, device=device, scheduler=scheduler, bar=bar, finish=finish)  # fmt: skip
    try:
        if not todo:
            pass
        elif scheduler:
            _run_dask(todo, context, result)
        elif len(devices) == 1:
            _run_here(todo, devices[0], context, result)
        else:
            _run_pooled(todo, devices, context, result)
    except KeyboardInterrupt:
        bar.close()
        _tally(result, records, variants)
        result.pending = len(variants) - sum(len(r["rows"]) for r in records.values())
        result.wall_s = time.perf_counter() - t_start
        raise BatchInterrupted(result) from None
    bar.close()
    _finish_outputs(spec, variants, records, first, out_dir)
    journal.remove()
    _tally(result, records, variants)
    result.wall_s = time.perf_counter() - t_start
    return result


#: tables of at least this many rows per process are read by several processes
PREPARE_ROWS_PER_PROCESS = 2048
#: at most this many processes read a table
PREPARE_PROCESSES = 16


def _extract(file, prim, info):
    """The extraction hook for Mesh tubes, imported only when a scene has one."""
    from ..extract.usd import tube_from_mesh_prim

    return tube_from_mesh_prim(file, prim, info)


def _prepare_part(scene: str, table, variant_sets):
    """Read part of a table's variants and their run choices (in a worker process)."""
    import warp as wp

    from .variants import collect_variants

    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    variants, problems = collect_variants(scene, table, variant_sets, extract=_extract)
    if problems:
        return variants, problems, None
    try:
        return variants, [], _run_choices(variants)
    except SceneError as e:
        return variants, [(table.first_row, str(e))], None


def _prepare(scene: str, table, variant_sets, bar):
    """Every variant and its run choice, read by one process or, for a large table, several
    (each opening the scene and reading a part of the rows); all problems reported together."""
    from .variants import Variants, name_width, prepare_variants, raise_problems

    rows = len(table.rows) if table is not None else 1
    parts = min(PREPARE_PROCESSES, os.cpu_count() or 1, rows // PREPARE_ROWS_PER_PROCESS)
    if parts < 2:
        variants = prepare_variants(scene, table, variant_sets, extract=_extract, progress=bar.reading)
        return variants, _run_choices(variants)
    from ..scene.usd import open_stage

    open_stage(scene)  # a missing or unreadable scene: one message, before any process starts
    bounds = np.linspace(0, rows, parts + 1).round().astype(int)
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(parts, mp_context=ctx, initializer=_ignore_sigint) as ex:
        futures = [ex.submit(_prepare_part, scene, table.part(a, b), variant_sets) for a, b in zip(bounds[:-1], bounds[1:])]
        results = []
        for f in futures:
            results.append(f.result())
            bar.reading(sum(len(r[0].variants) for r in results))
    raise_problems([p for _, probs, _ in results for p in probs])
    width = name_width(sum(len(r[0].variants) for r in results))
    merged, choices = [], []
    for part, _, part_choices in results:
        merged += [dataclasses.replace(v, name=f"variant_{v.index:0{width}d}") for v in part.variants]
        choices += part_choices
    first = results[0][0]
    return Variants(scene_path=scene, table=table, axes=first.axes, variants=tuple(merged)), choices


def _run_choices(variants) -> list:
    """Each variant's integrator and substeps alone; a variant whose settings no integrator takes
    (e.g. implicit Euler with an assistant line) is a bad row, reported with the others."""
    from .variants import MAX_PROBLEMS

    scenes = [v.scene for v in variants.variants]
    try:
        return run_choices(scenes)
    except SceneError:
        pass
    problems = []  # find which variants: one at a time
    for v in variants.variants:
        try:
            run_choice(v.scene)
        except SceneError as e:
            where = variants.table.where(v.row) if variants.table is not None and v.row is not None else v.name
            chosen = ", ".join(f"{a.label} = {c}" for a, c in zip(variants.axes, v.selection))
            problems.append(f"{where}{' with ' + chosen if chosen else ''}: {e}")
            if len(problems) > MAX_PROBLEMS:
                break
    more = "\n  ... and more" if len(problems) > MAX_PROBLEMS else ""
    raise SceneError(f"problem(s) in the variants; nothing was run:\n  " + "\n  ".join(problems[:MAX_PROBLEMS]) + more)


def _finished(out_dir: str, result: BatchResult, t_start: float) -> BatchResult:
    """The result of resuming a batch that had finished: its summary, read back."""
    import csv

    path = os.path.join(out_dir, "summary.csv")
    if not os.path.exists(path):
        raise SceneError(f"{out_dir}: no unfinished batch (.batch) and no summary.csv: nothing to resume")
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    result.resumed = len(rows)
    result.ok = sum(r["status"] == "ok" for r in rows)
    result.failed = len(rows) - result.ok
    result.failures = [(r["name"], r["reason"]) for r in rows if r["status"] != "ok"]
    result.wall_s = time.perf_counter() - t_start
    return result


def _json_row(row: dict, output: str) -> dict:
    out = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in row.items()}
    out["output"] = output
    return out


def _tally(result: BatchResult, records: dict, variants) -> None:
    result.ok = result.failed = 0
    result.failures = []
    rows = {int(i): r for rec in records.values() for i, r in rec["rows"].items()}
    for i in sorted(rows):
        if rows[i]["status"] == "ok":
            result.ok += 1
        else:
            result.failed += 1
            result.failures.append((variants.variants[i].name, rows[i]["reason"]))


def _output_spec(variants, layout, out_dir, work_dir, surface, time_codes) -> OutputSpec:
    vs = variants.variants
    points = max(sum(len(t.points) for t in v.scene.tubes) for v in vs)
    vertices = max(sum(surface_topology(t).vertex_count for t in v.scene.tubes) for v in vs) if surface else 0
    first = vs[0].scene.stage
    cell, columns = 1.0, 1
    if layout == "grid":
        mpu = first.meters_per_unit
        size = max(float(np.ptp(np.concatenate([t.points for t in v.scene.tubes]), axis=0).max())
                   + 2.0 * max(float(t.radius.max()) for t in v.scene.tubes) for v in vs)  # fmt: skip
        cell = 1.5 * size / mpu
        columns = math.ceil(math.sqrt(len(vs)))
    return OutputSpec(layout=layout, out_dir=out_dir, surface=surface, time_codes=time_codes, variants=len(vs),
                      points=points, vertices=vertices, work_dir=work_dir, grid_cell=cell, grid_columns=columns,
                      up_axis=first.up_axis)  # fmt: skip


def _write_tasks(chunk, context, parts: int) -> list[WriteTask]:
    """A chunk's variants split into ``parts`` write tasks (the grid: one), rows filled in later."""
    variants, spec = context["variants"].variants, context["spec"]
    idx = list(chunk.indices)
    parts = 1 if spec.layout == "grid" else max(1, min(parts, len(idx)))
    bounds = np.linspace(0, len(idx), parts + 1).round().astype(int)
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b > a:
            vs = tuple((i, variants[i].name, variants[i].scene) for i in idx[a:b])
            out.append(WriteTask(spec=spec, chunk=chunk.id, variants=vs, positions=tuple(range(a, b)), rows=(), arrays={}))
    return out


def _writer_count(writers, sims: int) -> int:
    if writers is not None:
        return writers
    return max(1, min(32, (os.cpu_count() or 2) - sims))


def _run_here(todo, device, context, result) -> None:
    """Simulate the chunks in this process while a pool of writer processes writes them."""
    import warp as wp

    from ..sim.simulation import resolve_device

    wp.config.log_level = wp.LOG_WARNING
    device = resolve_device(device)
    writers: _Writers = context["writers"]
    pool = writers.pool
    buffers = None
    pending: dict = {}  # chunk id -> (futures, rows, paths, t_submitted)
    bar = context["bar"]

    def settle(block: bool):
        for cid in list(pending):
            futures, rows, paths = pending[cid]
            if not block and not all(f.done() for f in futures):
                continue
            outputs = []
            for f in futures:
                out, spent = f.result()
                outputs += out
                result.write_s += spent
            del pending[cid]
            for p in paths:
                os.remove(p)
            context["finish"](cid, rows, outputs)

    try:
        t_sim = 0.0
        for chunk in todo:
            scenes = [context["variants"].variants[i].scene for i in chunk.indices]
            choice = context["choices"][chunk.indices[0]]
            allocate = None
            if pool is not None and writers.processes:  # the writers read the arrays from files
                if buffers is None:
                    shapes = chunk_shapes(scenes, context["frames"], context["every"], context["surface"], context["spec"].vertices)
                    buffers = _buffer_folder(sum(4 * math.prod(s) for s in shapes.values()), context["spec"].work_dir)
                allocate = _file_allocator(buffers, chunk.id)
            t0 = time.perf_counter()
            run = simulate_chunk(scenes, choice, device, context["frames"], context["every"], context["surface"],
                                 allocate=allocate, progress=bar.frames)  # fmt: skip
            t_sim += time.perf_counter() - t0
            _add_timings(result, run.timings)
            tasks = _write_tasks(chunk, context, max(writers.count, 1))
            if pool is None:
                t0 = time.perf_counter()
                outputs = []
                for task in _with_rows(tasks, run.rows, run.arrays):
                    outputs += write(task)
                result.write_s += time.perf_counter() - t0
                result.write_wait_s += time.perf_counter() - t0  # written here: the simulation waits
                context["finish"](chunk.id, run.rows, outputs)
                continue
            if writers.processes:
                for a in run.arrays.values():
                    a.flush()
                paths = [a.filename for a in run.arrays.values()]
                arrays = {name: a.filename for name, a in run.arrays.items()}
            else:
                paths, arrays = [], run.arrays
            del run.arrays
            futures = [pool.submit(_timed_write, t) for t in _with_rows(tasks, run.rows, arrays)]
            pending[chunk.id] = (futures, run.rows, paths)
            settle(block=False)
            t0 = time.perf_counter()
            while len(pending) >= 2:  # at most two chunks wait for writers
                cf.wait([f for fs, _, _ in pending.values() for f in fs], return_when=cf.FIRST_COMPLETED)
                settle(block=False)
            result.write_wait_s += time.perf_counter() - t0
        result.simulate_s += t_sim
        t0 = time.perf_counter()
        settle(block=True)
        result.write_wait_s += time.perf_counter() - t0
    except KeyboardInterrupt:
        # Keep what is complete: the chunks already simulated are written to the end.
        try:
            settle(block=True)
        finally:
            raise
    finally:
        if buffers is not None:
            shutil.rmtree(buffers, ignore_errors=True)


def _run_pooled(todo, devices, context, result) -> None:
    """One worker process per device simulates chunks; a pool of writer processes writes them."""
    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Manager().Queue()
    for d in devices:
        queue.put(d)
    writers: _Writers = context["writers"]
    own = None
    if writers.pool is None:  # the simulating processes hand their arrays over: someone writes them
        own = writers = _Writers(context["spec"].layout, 1)
    pool = writers.pool
    sims = cf.ProcessPoolExecutor(len(devices), mp_context=ctx, initializer=_init_sim_worker, initargs=(queue,))
    first = [context["variants"].variants[i].scene for i in todo[0].indices]
    shapes = chunk_shapes(first, context["frames"], context["every"], context["surface"], context["spec"].vertices)
    buffers = _buffer_folder(sum(4 * math.prod(s) for s in shapes.values()) * len(devices), context["spec"].work_dir)
    queue_chunks = list(todo)
    simulating: dict = {}  # future -> chunk
    writing: dict = {}  # chunk id -> (futures, rows, paths)
    bar = context["bar"]
    t0 = time.perf_counter()

    def submit_sim():
        while queue_chunks and len(simulating) + len(writing) < 2 * len(devices):
            c = queue_chunks.pop(0)
            scenes = [context["variants"].variants[i].scene for i in c.indices]
            payload = (scenes, context["choices"][c.indices[0]], context["frames"], context["every"], context["surface"], buffers, c.id)
            simulating[sims.submit(_sim_task, payload)] = c

    try:
        submit_sim()
        while simulating or writing:
            waiting = list(simulating) + [f for fs, _, _ in writing.values() for f in fs]
            cf.wait(waiting, return_when=cf.FIRST_COMPLETED)
            for fut in [f for f in simulating if f.done()]:
                c = simulating.pop(fut)
                rows, paths, timings = fut.result()
                _add_timings(result, timings)
                bar.frames(len(c.indices) * max(context["frames"] - 1, 1))
                tasks = _with_rows(_write_tasks(c, context, max(1, writers.count // len(devices))), rows, paths)
                writing[c.id] = ([pool.submit(_timed_write, t) for t in tasks], rows, list(paths.values()))
            for cid in [cid for cid, (fs, _, _) in writing.items() if all(f.done() for f in fs)]:
                fs, rows, paths = writing.pop(cid)
                outputs = []
                for f in fs:
                    out, spent = f.result()
                    outputs += out
                    result.write_s += spent
                for p in paths:
                    os.remove(p)
                context["finish"](cid, rows, outputs)
            submit_sim()
        result.simulate_s += result.timings["build_s"] + sum(result.timings[k] for k in TIMERS if k != "build_s")
    except KeyboardInterrupt:
        # Stop simulating at once; the chunks already simulated are written to the end and kept.
        queue_chunks.clear()
        for f in simulating:
            f.cancel()
        for proc in list(getattr(sims, "_processes", {}).values()):
            proc.terminate()
        try:
            for cid, (fs, rows, paths) in list(writing.items()):
                outputs = []
                for f in fs:
                    outputs += f.result()[0]
                context["finish"](cid, rows, outputs)
        finally:
            raise
    finally:
        sims.shutdown(wait=True, cancel_futures=True)
        if own is not None:
            own.shutdown()
        shutil.rmtree(buffers, ignore_errors=True)
        result.write_wait_s += 0.0 if not result.simulate_s else max(0.0, time.perf_counter() - t0 - result.simulate_s / len(devices))


def _run_dask(todo, context, result) -> None:
    """Each chunk a task of the Dask cluster at ``scheduler``, simulating and writing there."""
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise SceneError("--scheduler needs Dask distributed: pip install 'warp-tube[dask]'") from None
    try:
        client = Client(context["scheduler"], timeout="20s")
    except (OSError, TimeoutError) as e:
        raise SceneError(f"--scheduler {context['scheduler']}: cannot reach the Dask scheduler ({e})") from None
    bar = context["bar"]
    futures = {}
    try:
        for c in todo:
            scenes = [context["variants"].variants[i].scene for i in c.indices]
            tasks = _write_tasks(c, context, 1)
            payload = (scenes, context["choices"][c.indices[0]], context["frames"], context["every"], context["surface"],
                       context["device"], tasks)  # fmt: skip
            futures[client.submit(_dask_task, payload, pure=False)] = c
        for fut in as_completed(list(futures)):
            c = futures[fut]
            rows, outputs, timings, sim_s, write_s = fut.result()
            _add_timings(result, timings)
            result.simulate_s += sim_s
            result.write_s += write_s
            bar.frames(len(c.indices) * max(context["frames"] - 1, 1))
            context["finish"](c.id, rows, outputs)
    except KeyboardInterrupt:
        client.cancel(list(futures))
        raise
    finally:
        client.close()


def _add_timings(result: BatchResult, timings: dict) -> None:
    for k, v in timings.items():
        result.timings[k] = result.timings.get(k, 0.0) + v


def _finish_outputs(spec: OutputSpec, variants, records: dict, first_scene, out_dir: str) -> None:
    rows = {int(i): r for rec in records.values() for i, r in rec["rows"].items()}
    vs = variants.variants
    if spec.layout == "arrays":
        finish_arrays(spec, list(range(len(vs))), [v.name for v in vs],
                      [sum(len(t.points) for t in v.scene.tubes) for v in vs],
                      [sum(surface_topology(t).vertex_count for t in v.scene.tubes) for v in vs] if spec.surface else [])  # fmt: skip
    if spec.layout == "grid":
        layers = [records[c]["layer"] for c in sorted(records) if records[c]["layer"]]
        ok = [v.name for v in vs if rows[v.index]["status"] == "ok"]
        write_grid_root(spec, first_scene.stage, layers, ok)
    write_summary(os.path.join(out_dir, "summary.csv"), variants.parameter_columns(), vs, rows)


class _Progress:
    """Progress bars on a terminal: reading the variants, then variant-frames simulated."""

    def __init__(self, on: bool):
        self.on = on
        self.bar = None
        self.read_bar = None
        self.total_variants = 0
        self.done_variants = 0

    def reading(self, n: int):
        if not self.on:
            return
        if self.read_bar is None:
            from tqdm import tqdm

            self.read_bar = tqdm(desc="reading variants", unit="variant", leave=False)
        self.read_bar.update(n - self.read_bar.n)

    def close_reading(self):
        if self.read_bar is not None:
            self.read_bar.close()
            self.read_bar = None

    def start(self, frames_total: int, variants: int, done: int):
        self.total_variants, self.done_variants = variants, done
        if self.on:
            from tqdm import tqdm

            self.bar = tqdm(total=frames_total, desc="simulating", unit="frame", unit_scale=True, leave=False)
            self._postfix()

    def frames(self, n: int):
        if self.bar is not None:
            self.bar.update(n)

    def variants_done(self, n: int):
        self.done_variants += n
        self._postfix()

    def _postfix(self):
        if self.bar is not None:
            self.bar.set_postfix_str(f"variants written {self.done_variants}/{self.total_variants}")

    def close(self):
        self.close_reading()
        if self.bar is not None:
            self.bar.close()
            self.bar = None
