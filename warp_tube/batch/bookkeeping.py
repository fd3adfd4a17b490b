"""A batch's finished chunks recorded as they finish: journal records and summary lines.

When every output of a chunk is complete, two things are made of its variants' summary fields:
its journal record (:mod:`warp_tube.batch.journal`, what ``--resume`` reads) and its lines of
``summary.csv``. The summary is the chunks' lines joined in batch order
(:meth:`Bookkeeper.summary_text`), each made as :func:`~warp_tube.batch.outputs.summary_lines`
makes it, so it holds the same bytes as one made at the end; the batch's last step only joins them.

Both are made in the simulating process as each chunk finishes. Made on a thread of their own they
competed with the next chunk's build for Python's lock: on an H100 host (16,384 variants, four
chunks) the build took 0.31-0.33 s against 0.19-0.20 s, everything but the kernels and writing
1.07-1.18 s against 0.80-0.82 s.
"""

from __future__ import annotations

from .journal import Journal
from .outputs import SUMMARY_FIELDS, summary_lines
from .rows import batch_columns

__all__ = ["Bookkeeper"]


class Bookkeeper:
    """Journal records and summary lines of a batch's finished chunks.

    Args:
        journal: the batch's journal.
        variants: the batch's variants (``Variants.variants``), in batch order.
    """

    def __init__(self, journal: Journal, variants: list):
        self.journal = journal
        self.variants = variants
        self.lines: dict[int, str] = {}  # chunk id -> its variants' summary lines, chunk order

    def record(self, chunk_id: int, record: dict) -> None:
        """Record chunk ``chunk_id`` (journal ``record``, on disk when this returns) and make its
        summary lines."""
        self.journal.record(chunk_id, record)
        self.lines[chunk_id] = self._lines(record)

    def _lines(self, record: dict) -> str:
        index, columns = batch_columns([record], ("tip", *SUMMARY_FIELDS))
        return summary_lines([self.variants[i] for i in index], columns)

    def summary_text(self, records: dict) -> str:
        """``summary.csv``'s lines of every variant in batch order, from the chunks' ``records``
        (chunk id -> journal record; lines made here for chunks recorded by an earlier run)."""
        order = sorted(records, key=lambda c: records[c]["rows"]["index"][0] if records[c]["rows"]["index"] else -1)
        index = [i for c in order for i in records[c]["rows"]["index"]]
        if index != list(range(len(index))):  # chunks of groups interleaved in batch order: all at once
            index, columns = batch_columns(records.values(), ("tip", *SUMMARY_FIELDS))
            return summary_lines([self.variants[i] for i in index], columns)
        return "".join(self.lines[c] if c in self.lines else self._lines(records[c]) for c in order)
