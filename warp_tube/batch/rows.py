"""Variants' summary fields as columns: one list per field, instead of a dict per variant.

A chunk's :class:`Rows` come from the simulation (:mod:`warp_tube.batch.engine`: status, reason,
frames written and simulated, integrator, substeps, rerun, max_displacement_m, tip,
kinetic_energy_J, work_J, contact_frame), are handed to the writers and kept by the journal as
they are (one JSON list per field, the variants' batch indices in ``index``), and the summary is
written from the batch's columns in batch order (:func:`batch_columns`).
"""

from __future__ import annotations

import operator

import numpy as np

__all__ = ["Rows", "batch_columns", "record_count"]


class Rows:
    """Summary fields of some variants (a chunk's, in chunk order), one list per field.

    ``rows[k]`` is variant ``k``'s fields as a dict; iterating gives the dicts in order.
    """

    __slots__ = ("columns",)

    def __init__(self, columns: dict[str, list]):
        self.columns = columns

    @classmethod
    def of(cls, rows: list[dict]) -> Rows:
        """Rows from a dict per variant (every dict with the same fields)."""
        fields = list(rows[0]) if rows else []
        return cls({f: [r[f] for r in rows] for f in fields})

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()), ()))

    def __getitem__(self, k: int) -> dict:
        return {f: c[k] for f, c in self.columns.items()}

    def __iter__(self):
        fields = list(self.columns)
        return (dict(zip(fields, values)) for values in zip(*self.columns.values()))

    def put(self, k: int, row: dict) -> None:
        """Replace variant ``k``'s fields with ``row``'s (which has every field)."""
        for f, c in self.columns.items():
            c[k] = row[f]

    def take(self, positions) -> Rows:
        """The rows at ``positions`` (a run of consecutive positions is one slice)."""
        positions = list(positions)
        if positions and positions == list(range(positions[0], positions[-1] + 1)):
            a, b = positions[0], positions[-1] + 1
            return Rows({f: c[a:b] for f, c in self.columns.items()})
        return Rows({f: [c[p] for p in positions] for f, c in self.columns.items()})

    def __getstate__(self):
        return self.columns

    def __setstate__(self, state):
        self.columns = state


def record_count(record: dict) -> int:
    """Variants in a journal record of a chunk (its ``rows``: ``index`` and one list per field)."""
    return len(record["rows"]["index"])


def batch_columns(records, fields) -> tuple[list[int], dict[str, list]]:
    """The records' rows (journal records of chunks) merged in batch order: the batch indices and,
    per field of ``fields``, the values (``""`` where a record lacks the field)."""
    records = list(records)
    index = [i for rec in records for i in rec["rows"]["index"]]
    sizes = [record_count(rec) for rec in records]
    columns = {}
    for f in fields:
        columns[f] = [v for rec, n in zip(records, sizes) for v in rec["rows"].get(f, [""] * n)]
    order = np.argsort(np.asarray(index, dtype=np.int64), kind="stable")
    if len(order) > 1 and not np.all(order[1:] > order[:-1]):  # chunks out of batch order (groups)
        pick = operator.itemgetter(*order.tolist())
        index = list(pick(index))
        columns = {f: list(pick(c)) for f, c in columns.items()}
    return [int(i) for i in index], columns
