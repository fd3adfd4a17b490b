"""A batch's bookkeeping on a thread of its own, beside the simulation and the writers.

Each finished chunk (its outputs complete) is recorded in the journal (:mod:`warp_tube.batch.journal`)
and its lines of ``summary.csv`` are made, on one thread, while the simulation goes on with the
next chunks; the summary is written at the end from those lines. Records reach the journal in
the order the chunks finish; one that has not reached it when a batch stops only means that
chunk is simulated again by ``--resume``.
"""

from __future__ import annotations

import concurrent.futures as cf

from .outputs import summary_lines

__all__ = ["Books"]


class Books:
    """The journal records and summary lines of a batch's finished chunks, made on a thread.

    Args:
        journal: the batch's :class:`~warp_tube.batch.journal.Journal`.
        variants: the batch's :class:`~warp_tube.batch.variants.Variants`.
    """

    def __init__(self, journal, variants):
        self.journal = journal
        self.variants = variants.variants
        self._pool = cf.ThreadPoolExecutor(1, thread_name_prefix="batch-books")
        self._futures: list[cf.Future] = []
        self._lines: dict = {}  # chunk id -> (its batch indices, its summary lines)

    def record(self, chunk_id: int, indices: tuple[int, ...], record: dict) -> None:
        """Record finished chunk ``chunk_id`` (variants ``indices``; ``record`` as the journal
        keeps it, not changed afterwards) and make its summary lines, on the thread."""
        self._futures.append(self._pool.submit(self._keep, chunk_id, indices, record))

    def _keep(self, chunk_id: int, indices: tuple[int, ...], record: dict) -> None:
        self.journal.record(chunk_id, record)
        rows = {i: record["rows"][str(i)] for i in indices}
        self._lines[chunk_id] = (indices, summary_lines([self.variants[i] for i in indices], rows))

    def wait(self) -> None:
        """Until every chunk handed over is recorded (raises what recording one raised)."""
        futures, self._futures = self._futures, []
        for f in futures:
            f.result()

    def summary_body(self) -> str | None:
        """Every variant's summary lines in batch order, made from the chunks' (after
        :meth:`wait`), or None where they do not make it up: chunks resumed from an earlier run
        (not made here), or groups whose chunks interleave in batch order."""
        parts = sorted(self._lines.values(), key=lambda p: p[0][0])
        expect = 0
        for indices, _ in parts:
            if list(indices) != list(range(expect, expect + len(indices))):
                return None
            expect += len(indices)
        if expect != len(self.variants):
            return None
        return "".join(text for _, text in parts)

    def close(self) -> None:
        self._pool.shutdown(wait=True)
