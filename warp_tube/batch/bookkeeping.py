"""A batch's finished chunks recorded as they finish: journal records and summary lines.

When every output of a chunk is complete, two things are made of its variants' summary fields:
its lines of ``summary.csv`` (:func:`~warp_tube.batch.outputs.summary_lines`) and its journal
record (:mod:`warp_tube.batch.journal`, what ``--resume`` reads), which keeps those lines as text
beside the fields the batch reads back (index, status, reason, contact frame, outputs): each
number is formatted once, for the summary, not a second time for the journal. The summary is the
chunks' lines joined in batch order (:meth:`Bookkeeper.summary_text`), the same bytes as lines
made at the end of the batch; the batch's last step only joins them.

A large batch (a table of at least :data:`PROCESS_VARIANTS` rows) has them made by a process of its own
(:class:`~warp_tube.batch.recorder.Recorder`): the batch's process hands it a chunk's fields and
goes on simulating; :meth:`Bookkeeper.drain` waits for the records still being made (at the end of
the batch, or when it is interrupted, so that every chunk recorded as finished is in the journal).
A smaller batch makes them in its own process as each chunk finishes.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

from .journal import Journal
from .outputs import SUMMARY_FIELDS, summary_lines
from .recorder import Recorder
from .rows import batch_columns

__all__ = ["Bookkeeper", "KEPT_FIELDS", "PROCESS_VARIANTS", "csv_records"]

log = logging.getLogger(__name__)

#: batches whose table has at least this many rows make their records in a process of their own
PROCESS_VARIANTS = 4096

#: the summary fields a journal record keeps as lists (what the batch reads back: its tally, the
#: outputs kept when resuming); the others are in its summary lines (``summary``)
KEPT_FIELDS = ("index", "status", "reason", "contact_frame", "output", "max_stretch")


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


class Named(NamedTuple):
    """What a summary line says of a variant besides its fields (``Variant``'s, without its scene)."""

    index: int
    name: str
    cells: tuple
    selection: tuple


def _lines(variants, record: dict) -> str:
    """The summary lines of ``record``'s variants (``variants``: each variant's :class:`Named`,
    or ``Variant``, by batch index)."""
    rows = record["rows"]
    index = [int(i) for i in rows["index"]]  # (older journals: indices as strings)
    if all(a < b for a, b in zip(index, index[1:])):  # a chunk's variants, in batch order: its columns as they are
        n = len(index)
        columns = {f: rows.get(f, [""] * n) for f in ("tip", *SUMMARY_FIELDS)}
    else:
        index, columns = batch_columns([record], ("tip", *SUMMARY_FIELDS))
    return summary_lines([variants[i] for i in index], columns)


def _kept(record: dict) -> dict:
    # a grid's chunk keeps its variants' displacements too: the grid's spacing is set from them at the end
    fields = (*KEPT_FIELDS, "max_displacement_m") if record.get("layer") else KEPT_FIELDS
    return dict(record, rows={k: record["rows"][k] for k in fields if k in record["rows"]})


def _record(journal: Journal, chunk_id: int, record: dict, variants) -> str:
    """Make chunk ``chunk_id``'s summary lines (``variants`` as for :func:`_lines`) and write its
    journal record with them; returns the lines."""
    lines = _lines(variants, record)
    journal.record(chunk_id, dict(_kept(record), summary=lines))
    return lines


def _record_named(journal: Journal, chunk_id: int, record: dict, named: list) -> str:
    """:func:`_record` in the recorder's process (``named``: the chunk's variants' :class:`Named`
    fields as tuples, chunk order)."""
    return _record(journal, chunk_id, record, {v[0]: Named(*v) for v in named})


class Bookkeeper:
    """Journal records and summary lines of a batch's finished chunks.

    Args:
        journal: the batch's journal.
        variants: the batch's variants (``Variants.variants``), in batch order.
        recorder: the process to make them in (:class:`~warp_tube.batch.recorder.Recorder`), or
            None to make them here.
    """

    def __init__(self, journal: Journal, variants: list, recorder: Recorder | None = None):
        self.journal = journal
        self.variants = variants
        self.recorder = recorder
        self.pending: dict = {}  # chunk id -> (its kept record, its record as given)

    def record(self, chunk_id: int, record: dict) -> dict:
        """Record chunk ``chunk_id`` (``record``: ``rows``, the summary fields of its variants in
        chunk order, and ``layer``). Returns the record as the journal keeps it, ``rows`` reduced
        to :data:`KEPT_FIELDS`, with its summary lines in ``summary``: made here and on disk when
        this returns, or, with a recorder, added to it and on disk once :meth:`drain` returns."""
        kept = _kept(record)
        if self.recorder is None or self.recorder.broken is not None:
            kept["summary"] = _record(self.journal, chunk_id, record, self.variants)
            return kept
        vs = self.variants
        named = [(v.index, v.name, v.cells, v.selection) for v in (vs[int(i)] for i in record["rows"]["index"])]
        self.recorder.submit(chunk_id, _record_named, self.journal, chunk_id, record, named)
        self.pending[chunk_id] = (kept, record)
        return kept

    def drain(self) -> None:
        """Wait for the records being made by the recorder: each on disk, its lines in the record
        :meth:`record` returned. One it could not make (it stopped, or failed) is made here."""
        pending, self.pending = self.pending, {}
        for chunk_id, (kept, record) in sorted(pending.items()):
            try:
                kept["summary"] = self.recorder.result(chunk_id)
            except RuntimeError as e:
                log.warning("chunk %d: its record was made in the batch's process instead (%s)", chunk_id, e)
                kept["summary"] = _record(self.journal, chunk_id, record, self.variants)

    def summary_text(self, records: dict) -> str:
        """``summary.csv``'s lines of every variant in batch order, from the chunks' journal
        ``records`` (chunk id -> record; lines made here for a record without them, written by
        an earlier version)."""
        texts = {c: rec["summary"] if "summary" in rec else _lines(self.variants, rec) for c, rec in records.items()}
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
