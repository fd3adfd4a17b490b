"""A batch's finished chunks recorded as they finish: journal records and summary lines.

When every output of a chunk is complete, two things are made of its variants' summary fields:
its lines of ``summary.csv`` (:func:`~warp_tube.batch.outputs.summary_lines`) and its journal
record (:mod:`warp_tube.batch.journal`, what ``--resume`` reads), which keeps those lines as text
beside the fields the batch reads back (index, status, reason, contact frame, outputs): each
number is formatted once, for the summary, not a second time for the journal. The summary is the
chunks' lines joined in batch order (:meth:`Bookkeeper.summary_text`), the same bytes as lines
made at the end of the batch; the batch's last step only joins them.

Both are made in the simulating process as each chunk finishes. Made on a thread of their own they
competed with the next chunk's build for Python's lock: on an H100 host (16,384 variants, four
chunks) the build took 0.31-0.33 s against 0.19-0.20 s, everything but the kernels and writing
1.07-1.18 s against 0.80-0.82 s.
"""

from __future__ import annotations

from .journal import Journal
from .outputs import SUMMARY_FIELDS, summary_lines
from .rows import batch_columns

__all__ = ["Bookkeeper", "KEPT_FIELDS", "csv_records"]

#: the summary fields a journal record keeps as lists (what the batch reads back: its tally, the
#: outputs kept when resuming); the others are in its summary lines (``summary``)
KEPT_FIELDS = ("index", "status", "reason", "contact_frame", "output")


def csv_records(text: str) -> list[str]:
    """``text`` (CSV rows ending in ``\\n``) as one string per row, each with its ``\\n``: a line
    break inside a quoted field (an odd count of quotes before it) does not end a row."""
    out: list[str] = []
    part, quotes = "", 0
    for line in text.split("\n")[:-1]:
        part += line + "\n"
        quotes += line.count('"')
        if quotes % 2 == 0:
            out.append(part)
            part, quotes = "", 0
    if part:
        raise ValueError("CSV text ends inside a quoted field")
    return out


class Bookkeeper:
    """Journal records and summary lines of a batch's finished chunks.

    Args:
        journal: the batch's journal.
        variants: the batch's variants (``Variants.variants``), in batch order.
    """

    def __init__(self, journal: Journal, variants: list):
        self.journal = journal
        self.variants = variants

    def record(self, chunk_id: int, record: dict) -> dict:
        """Record chunk ``chunk_id`` (``record``: ``rows``, the summary fields of its variants in
        chunk order, and ``layer``): the journal record, on disk when this returns, and returned,
        its ``rows`` reduced to :data:`KEPT_FIELDS` and its summary lines in ``summary``."""
        kept = dict(record, rows={k: record["rows"][k] for k in KEPT_FIELDS if k in record["rows"]},
                    summary=self._lines(record))  # fmt: skip
        self.journal.record(chunk_id, kept)
        return kept

    def _lines(self, record: dict) -> str:
        rows = record["rows"]
        index = [int(i) for i in rows["index"]]  # (older journals: indices as strings)
        if all(a < b for a, b in zip(index, index[1:])):  # a chunk's variants, in batch order: its columns as they are
            n = len(index)
            columns = {f: rows.get(f, [""] * n) for f in ("tip", *SUMMARY_FIELDS)}
        else:
            index, columns = batch_columns([record], ("tip", *SUMMARY_FIELDS))
        return summary_lines([self.variants[i] for i in index], columns)

    def summary_text(self, records: dict) -> str:
        """``summary.csv``'s lines of every variant in batch order, from the chunks' journal
        ``records`` (chunk id -> record; lines made here for a record without them, written by
        an earlier version)."""
        texts = {c: rec["summary"] if "summary" in rec else self._lines(rec) for c, rec in records.items()}
        order = sorted(records, key=lambda c: int(records[c]["rows"]["index"][0]) if records[c]["rows"]["index"] else -1)
        index = [int(i) for c in order for i in records[c]["rows"]["index"]]
        if index == list(range(len(index))):
            return "".join(texts[c] for c in order)
        # chunks of groups interleaved in batch order: their lines, one per variant, in batch order
        lines = []
        for c, rec in records.items():
            rows = csv_records(texts[c])
            if len(rows) != len(rec["rows"]["index"]):
                raise RuntimeError(f"chunk {c}: {len(rows)} summary lines for {len(rec['rows']['index'])} variants")
            lines += zip(map(int, rec["rows"]["index"]), rows)  # (older journals: indices as strings)
        lines.sort(key=lambda pair: pair[0])
        return "".join(line for _, line in lines)
