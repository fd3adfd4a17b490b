"""The variants table: a CSV file, one row per variant, one column per overridden attribute.

Header cells name ``PRIM_PATH.ATTRIBUTE`` (``/World/Tube.warptube:youngsModulus``,
``/World/Push.warptube:force``, ``/World/Tube.points``); a header starting with ``@`` makes every
value of its column a file (``@/World/Tube.points``: each cell a path to an ``.npy``, ``.csv`` or
``.txt`` array). A cell is parsed by the attribute's USD type (:mod:`warp_tube.batch.values`).
Rows are numbered from 0 (row ``r`` is variant ``r`` when no variant sets are crossed with the
table); messages give the row and its line in the file.
"""

from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass

from ..scene.spec import SceneError

__all__ = ["Column", "Table", "read_table"]

_PRIM_PATH = re.compile(r"^/(?:[A-Za-z_][A-Za-z0-9_]*)(?:/[A-Za-z_][A-Za-z0-9_]*)*$")
_ATTRIBUTE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(?::[A-Za-z_][A-Za-z0-9_]*)*$")


@dataclass(frozen=True)
class Column:
    """One column: the attribute it overrides.

    Attributes:
        header: the header cell as written.
        prim: prim path, e.g. ``/World/Tube``.
        attribute: attribute name, e.g. ``warptube:youngsModulus``.
        files: every value names a file (the header starts with ``@``).
    """

    header: str
    prim: str
    attribute: str
    files: bool = False

    @property
    def target(self) -> str:
        """``PRIM_PATH.ATTRIBUTE``."""
        return f"{self.prim}.{self.attribute}"


@dataclass(frozen=True)
class Table:
    """A parsed variants table.

    Attributes:
        path: the file.
        columns: the columns, in file order.
        rows: the cells of each row (strings, one per column).
        lines: the line in the file where each row starts (1 = the header).
        first_row: the number of ``rows[0]`` in the file (a part of a table, :meth:`part`).
    """

    path: str
    columns: tuple[Column, ...]
    rows: tuple[tuple[str, ...], ...]
    lines: tuple[int, ...]
    first_row: int = 0

    def where(self, row: int, column: Column | None = None) -> str:
        """``TABLE: row R (line L)[, column C]`` for messages (``row`` counts from ``first_row``)."""
        out = f"{self.path}: row {row} (line {self.lines[row - self.first_row]})"
        return out + (f", column {column.header}" if column is not None else "")

    def part(self, start: int, stop: int) -> "Table":
        """Rows ``start`` to ``stop`` (of this table's rows) as a table of their own."""
        return Table(self.path, self.columns, self.rows[start:stop], self.lines[start:stop], self.first_row + start)

    @property
    def folder(self) -> str:
        """The table's folder: file values are relative to it."""
        return os.path.dirname(os.path.abspath(self.path))


def _column(path: str, k: int, cell: str) -> Column:
    text = cell.strip()
    files = text.startswith("@")
    body = text[1:].strip() if files else text
    prim, dot, attr = body.rpartition(".")
    if not dot or not _PRIM_PATH.match(prim) or not _ATTRIBUTE.match(attr):
        raise SceneError(
            f"{path}: line 1, column {k + 1} {cell!r}: expected PRIM_PATH.ATTRIBUTE, e.g. "
            "/World/Tube.warptube:youngsModulus (or @PRIM_PATH.ATTRIBUTE for a column of file names)"
        )
    return Column(header=text, prim=prim, attribute=attr, files=files)


def read_table(path: str) -> Table:
    """Read and check the table's structure (not its values: they need the scene's types).

    Raises:
        SceneError: no such file, no header, a header cell that is not ``PRIM_PATH.ATTRIBUTE``, the
            same attribute twice, no rows, or a row with more or fewer cells than the header.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise SceneError(f"{path}: no such file (the variants table)")
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            records = [(reader.line_num, row) for reader in [csv.reader(f)] for row in reader]
    except (UnicodeDecodeError, csv.Error) as e:
        raise SceneError(f"{path}: not a readable CSV file ({e})") from None
    # csv.reader's line_num is the line where a record ends; records span one line unless quoted.
    records = [(line, row) for line, row in records if any(cell.strip() for cell in row)]
    if not records:
        raise SceneError(f"{path}: empty: expected a header row of PRIM_PATH.ATTRIBUTE columns and a row per variant")
    header = records[0][1]
    columns = tuple(_column(path, k, cell) for k, cell in enumerate(header))
    seen = {}
    for k, c in enumerate(columns):
        if c.target in seen:
            raise SceneError(f"{path}: line 1: columns {seen[c.target] + 1} and {k + 1} both set {c.target}")
        seen[c.target] = k
    rows, lines = [], []
    for line, row in records[1:]:
        if len(row) != len(columns):
            r = len(rows)
            hint = ""
            if len(row) > len(columns) and any(c.strip()[:1] in "([" or c.strip()[-1:] in ")]" for c in row):
                hint = ': a vector or array holds commas, so quote its cell, e.g. "(0, 0.02, 0)"'
            raise SceneError(f"{path}: row {r} (line {line}): {len(row)} cells for {len(columns)} columns{hint}")
        rows.append(tuple(cell.strip() for cell in row))
        lines.append(line)
    if not rows:
        raise SceneError(f"{path}: no rows: expected one row per variant under the header")
    return Table(path=path, columns=columns, rows=tuple(rows), lines=tuple(lines))
