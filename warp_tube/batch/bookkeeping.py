"""A batch's finished chunks recorded on a thread of their own, beside the simulation.

When every output of a chunk is complete, two things are made of its variants' summary fields:
its journal record (:mod:`warp_tube.batch.journal`, what ``--resume`` reads) and its lines of
``summary.csv``. Both are text of every variant's floats (for 16,384 variants ~0.1 s of JSON and
~0.1-0.2 s of CSV), which on a GPU is several times the kernels' own time; made on one thread, in
the order the chunks finish, they overlap the simulation of the next chunk and the writing of the
last. A chunk counts as recorded once its record is on disk: :meth:`Bookkeeper.wait` returns when
every record handed over is, and raises the first error of any.

The summary is the chunks' lines in batch order (:meth:`Bookkeeper.summary_text`), each made as
:func:`~warp_tube.batch.outputs.summary_lines` makes it: the same bytes as making it at the end.
"""

from __future__ import annotations

import concurrent.futures as cf

from .journal import Journal
from .outputs import SUMMARY_FIELDS, summary_lines
from .rows import batch_columns

__all__ = ["Bookkeeper"]


class Bookkeeper:
    """Journal records and summary lines of a batch's finished chunks.

    Args:
        journal: the batch's journal.
        variants: the batch's variants (``Variants.variants``), in batch order.
        plan: the batch's chunks (:func:`~warp_tube.batch.plan.plan_chunks`), by id.
    """

    def __init__(self, journal: Journal, variants: list, plan: list):
        self.journal = journal
        self.variants = variants
        self.plan = plan
        self.lines: dict[int, str] = {}  # chunk id -> its variants' summary lines, chunk order
        self._pending: list[cf.Future] = []
        self._thread = cf.ThreadPoolExecutor(1, thread_name_prefix="batch-records")

    def record(self, chunk_id: int, record: dict) -> None:
        """Record chunk ``chunk_id`` (journal ``record``) and make its summary lines, on the
        records' thread; raises an error of an earlier record."""
        self._raise_done()
        self._pending.append(self._thread.submit(self._record, chunk_id, record))

    def _record(self, chunk_id: int, record: dict) -> None:
        self.journal.record(chunk_id, record)
        self.lines[chunk_id] = self._lines(chunk_id, record)

    def _lines(self, chunk_id: int, record: dict) -> str:
        index, columns = batch_columns([record], ("tip", *SUMMARY_FIELDS))
        return summary_lines([self.variants[i] for i in index], columns)

    def _raise_done(self) -> None:
        done = [f for f in self._pending if f.done()]
        self._pending = [f for f in self._pending if not f.done()]
        for f in done:
            f.result()

    def wait(self) -> None:
        """Return once every record handed over is on disk (raises the first error of any)."""
        pending, self._pending = self._pending, []
        errors = [f.exception() for f in pending]
        for e in errors:
            if e is not None:
                raise e

    def close(self) -> None:
        """Wait for the records, then stop the thread."""
        try:
            self.wait()
        finally:
            self._thread.shutdown(wait=True)

    def summary_text(self, records: dict) -> str:
        """``summary.csv``'s lines of every variant in batch order, from the chunks' ``records``
        (chunk id -> journal record; lines made here for chunks recorded by an earlier run)."""
        self.wait()
        order = sorted(records, key=lambda c: records[c]["rows"]["index"][0] if records[c]["rows"]["index"] else -1)
        index = [i for c in order for i in records[c]["rows"]["index"]]
        if index != list(range(len(index))):  # chunks of groups interleaved in batch order: all at once
            index, columns = batch_columns(records.values(), ("tip", *SUMMARY_FIELDS))
            return summary_lines([self.variants[i] for i in index], columns)
        return "".join(self.lines[c] if c in self.lines else self._lines(c, records[c]) for c in order)
