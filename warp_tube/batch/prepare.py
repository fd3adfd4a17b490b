"""Reading a batch's variants and each one's integrator choice, in one process or several.

A large table (at least :data:`PREPARE_ROWS_PER_PROCESS` rows per process) is read by several
processes, each opening the scene and reading a part of the rows; problems from all parts are
reported together, in row order, before anything runs. The batch's writer processes do this
reading when it has them (they are started first and are idle until the first chunk is
simulated); otherwise processes are started for it.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import os
from concurrent.futures.process import BrokenProcessPool
from operator import attrgetter, itemgetter

import numpy as np

from ..extract.hook import mesh_prim_tube
from ..runtime.collector import collector_paused
from ..scene.spec import SceneError
from .main_module import may_start_processes
from .writer_pool import children_deaf_to_ctrl_c, ignore_sigint, spawn_context, terminate_pool
from .plan import run_choice, run_choices

log = logging.getLogger(__name__)

__all__ = ["prepare_batch", "checked_run_choices", "PREPARE_ROWS_PER_PROCESS", "PREPARE_PROCESSES"]


#: tables of at least this many rows per process are read by several processes
PREPARE_ROWS_PER_PROCESS = 1024


#: at most this many processes read a table
PREPARE_PROCESSES = 16

#: a table of plain values (:mod:`warp_tube.batch.fastread`, kept as columns) costs 10-15 us a row,
#: a few hundred times less than rows read through the stage, so a process reading part of it, which
#: pays for its start (importing usd-core and Warp, ~2 s) and for handing its variants back, needs this
#: many times more rows: none short of 4 million rows (the 2-core CPU: 300,000 plain rows read in one
#: process in 1.9-3.1 s, in two in 5.4-6.5 s; 1,000,000 rows in 8.1 s against 18.5 s)
PLAIN_ROWS_FACTOR = 2048


def _prepare_part(scene: str, table, variant_sets):
    """Read part of a table's variants and their run choices (in a worker process)."""
    from ..runtime.warp_setup import init_warp
    from .variants import collect_variants

    init_warp()  # quietly: no missing-driver line from each process on a machine without a GPU
    with collector_paused():
        variants, problems = collect_variants(scene, table, variant_sets, extract=mesh_prim_tube, say=False)  # (said with the others')
        if problems:
            return variants, problems, None
        try:
            return variants, [], checked_run_choices(variants)
        except SceneError as e:
            return variants, [(table.first_row, str(e))], None


def prepare_batch(scene: str, table, variant_sets, bar, pool: cf.ProcessPoolExecutor | None = None, pool_size: int = 0,
                  keep_nodes: bool = True, freeze: bool = False):  # fmt: skip
    """Every variant, its run choice and, where read in this process, their per-node parameters
    (:class:`~warp_tube.batch.nodes.KeptNodes`, else None), read by one process or, for a large table, several
    (each opening the scene and reading a part of the rows); all problems reported together.
    The cyclic garbage collector is held off meanwhile (:mod:`warp_tube.runtime.collector`).

    Args:
        scene, table, variant_sets: the batch's scene file, its :class:`~warp_tube.batch.table.Table`
            (or None) and variant-set selection.
        bar: the batch's :class:`~warp_tube.batch.progress.Progress`.
        pool, pool_size: running worker processes to read with (the writers) and how many they
            are, or None to start some.
        keep_nodes: keep the per-node parameters (for chunks built in this process).
        freeze: keep what was made out of the collector's later passes (``collector_paused``'s
            ``freeze``; the caller thaws them).
    """
    with collector_paused(freeze=freeze):
        return _prepare_batch(scene, table, variant_sets, bar, pool, pool_size, keep_nodes)


def reading_parts(table, variant_sets, width: int) -> int:
    """In how many parts :func:`prepare_batch` reads ``table`` with ``width`` processes at hand
    (fewer than 2: in this process)."""
    from .variants import plain_table

    rows = len(table.rows) if table is not None else 1
    per_process = PREPARE_ROWS_PER_PROCESS
    if rows >= 2 * per_process and not variant_sets and plain_table(table):
        per_process *= PLAIN_ROWS_FACTOR  # rows made from the base scene: new processes pay less often
    return min(PREPARE_PROCESSES, width, rows // per_process)


def _prepare_batch(scene, table, variant_sets, bar, pool, pool_size, keep_nodes):
    from .variants import Variants, merged_warnings, name_width, prepare_variants, raise_problems, say_warnings

    rows = len(table.rows) if table is not None else 1
    parts = reading_parts(table, variant_sets, pool_size if pool is not None else (os.cpu_count() or 1))

    def read_here():
        from .nodes import KeptNodes

        variants = prepare_variants(scene, table, variant_sets, extract=mesh_prim_tube, progress=bar.reading)
        keep = KeptNodes(len(variants.variants)) if keep_nodes else None
        choices = checked_run_choices(variants, keep)
        warn_forced(variants, choices)
        return variants, choices, keep

    if parts < 2 or (pool is None and not may_start_processes("reader", False, refuse=False)):
        return read_here()  # (a script on stdin, or one calling the batch unguarded: read here)
    from ..scene.usd import open_stage

    open_stage(scene)  # a missing or unreadable scene: one message, before any process starts
    bounds = np.linspace(0, rows, parts + 1).round().astype(int)
    own = None
    try:
        if pool is None:
            own = pool = cf.ProcessPoolExecutor(parts, mp_context=spawn_context(), initializer=ignore_sigint,
                                                initargs=(os.getpid(),))  # fmt: skip
        with children_deaf_to_ctrl_c():
            futures = [pool.submit(_prepare_part, scene, table.part(a, b), variant_sets) for a, b in zip(bounds[:-1], bounds[1:])]
        results = []
        for f in futures:
            results.append(f.result())
            bar.reading(sum(len(r[0].variants) for r in results))
    except BrokenProcessPool:
        # e.g. a main module the processes cannot import (a script piped to python): read here
        log.warning("the processes reading the table stopped; reading it in this process")
        return read_here()
    except KeyboardInterrupt:
        if own is not None:  # stop the readers now, rather than wait for their parts
            terminate_pool(own)
            own = None
        raise
    finally:
        if own is not None:
            own.shutdown(wait=True, cancel_futures=True)
    raise_problems([p for _, probs, _ in results for p in probs])
    width = name_width(sum(len(r[0].variants) for r in results))
    merged, choices = [], []
    for part, _, part_choices in results:
        merged += [v._replace(name=f"variant_{v.index:0{width}d}") for v in part.variants]
        choices += part_choices
    first = results[0][0]
    out = Variants(scene_path=scene, table=table, axes=first.axes, variants=tuple(merged),
                   plain=all(r[0].plain for r in results), warnings=merged_warnings(r[0] for r in results))  # fmt: skip
    say_warnings(out)
    warn_forced(out, choices)
    return out, choices, None


def warn_forced(variants, choices) -> None:
    """One warning for the variants whose forced timeStep exceeds their stability bound (the
    policy would give one per variant), naming how many and the first of them."""
    settings = {id(s): s for s in map(itemgetter(0), map(attrgetter("why"), choices))}.values()
    if not any(s.integrator == "semiImplicitEuler" and s.time_step is not None for s in settings):
        return  # (no variant's settings force a substep)
    forced = [(v, c) for v, c in zip(variants.variants, choices) if c.forced]
    if forced:
        v, c = forced[0]
        more = f" and {len(forced) - 1} other variant(s)" if len(forced) > 1 else ""
        log.warning("%s%s: %s: expect a blow-up (of %d variants)", v.name, more, c.reason.removeprefix("forced; "),
                    len(variants.variants))  # fmt: skip


def checked_run_choices(variants, keep=None) -> list:
    """Each variant's integrator and substeps alone; a variant whose settings no integrator takes
    (a timeStep that makes more substeps a frame than any run takes) is a bad row, reported with the others.
    ``keep``: a :class:`~warp_tube.batch.nodes.KeptNodes` for their per-node parameters, or None."""
    from .variants import MAX_PROBLEMS

    scenes = variants.scenes(range(len(variants.variants)))  # (plain ones: their columns, the scenes not made)
    try:
        return run_choices(scenes, plain=variants.plain, keep=keep)
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
    raise SceneError("problem(s) in the variants; nothing was run:\n  " + "\n  ".join(problems[:MAX_PROBLEMS]) + more)
