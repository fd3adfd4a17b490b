"""The variants table: a CSV file, one row per variant, one column per overridden attribute.

Header cells name ``PRIM_PATH.ATTRIBUTE`` (``/World/Tube.warptube:youngsModulus``,
``/World/Push.warptube:force``, ``/World/Tube.points``); a header starting with ``@`` makes every
value of its column a file (``@/World/Tube.points``: each cell a path to an ``.npy``, ``.csv`` or
``.txt`` array). A cell is parsed by the attribute's USD type (:mod:`warp_tube.batch.values`).
Rows are numbered from 0 (row ``r`` is variant ``r`` when no variant sets are crossed with the
table); messages give the row and its line in the file.

Tables as spreadsheets save them are read: UTF-8 with or without a byte-order mark, UTF-16 with
one, any line endings, cells separated by ``,`` or, where the header holds no comma, by ``;`` or
a tab (as some locales save CSV), spaces around cells, quoted cells running over lines, and
empty columns after the last header, empty lines, and rows of empty cells before the header or after
the last row (skipped). A workbook (``.xlsx``, ``.xls``, ``.ods``) is refused with a message
that says to save it as CSV.
"""

from __future__ import annotations

import csv
import io
import os
import re
from dataclasses import dataclass
from itertools import repeat
from operator import eq, itemgetter

from ..scene.spec import SceneError

__all__ = ["Column", "Table", "read_table"]

_PRIM_PATH = re.compile(r"^/(?:[A-Za-z_][A-Za-z0-9_]*)(?:/[A-Za-z_][A-Za-z0-9_]*)*$")
_ATTRIBUTE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(?::[A-Za-z_][A-Za-z0-9_]*)*$")
_DIGITS = re.compile(r"^[-+]?\d+$")
_FRACTION = re.compile(r"^\d+(?:[eE][-+]?\d+)?$")
#: a column pandas names for an unnamed one (its index, written by ``to_csv()`` and read back)
_UNNAMED = re.compile(r"^Unnamed: \d+$")
#: file signatures of spreadsheet workbooks (zip: .xlsx, .ods; OLE2: .xls)
_WORKBOOKS = (b"PK\x03\x04", b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1")
#: the longest cell read (the csv module's process-wide limit is raised to it)
_CELL_LIMIT = 2**31 - 1


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
        separator: the character between cells (``,``, or ``;`` or a tab as the header showed).
    """

    path: str
    columns: tuple[Column, ...]
    rows: tuple[tuple[str, ...], ...]
    lines: tuple[int, ...]
    first_row: int = 0
    separator: str = ","

    def where(self, row: int, column: Column | None = None) -> str:
        """``TABLE: row R (line L)[, column C]`` for messages (``row`` counts from ``first_row``)."""
        out = f"{self.path}: row {row} (line {self.lines[row - self.first_row]})"
        return out + (f", column {column.header}" if column is not None else "")

    def part(self, start: int, stop: int) -> "Table":
        """Rows ``start`` to ``stop`` (of this table's rows) as a table of their own."""
        return Table(self.path, self.columns, self.rows[start:stop], self.lines[start:stop], self.first_row + start,
                     self.separator)  # fmt: skip

    @property
    def folder(self) -> str:
        """The table's folder: file values are relative to it."""
        return os.path.dirname(os.path.abspath(self.path))


def _column(path: str, line: int, k: int, cell: str) -> Column:
    text = cell.strip()
    files = text.startswith("@")
    body = text[1:].strip() if files else text
    prim, dot, attr = body.rpartition(".")
    if not dot or not _PRIM_PATH.match(prim) or not _ATTRIBUTE.match(attr):
        index = (k == 0 and not text) or _UNNAMED.match(text)
        hint = ": a pandas index column? write the table with index=False (df.to_csv(path, index=False))" if index else ""
        raise SceneError(
            f"{path}: line {line}, column {k + 1} {cell!r}: expected PRIM_PATH.ATTRIBUTE, e.g. "
            f"/World/Tube.warptube:youngsModulus (or @PRIM_PATH.ATTRIBUTE for a column of file names){hint}"
        )
    return Column(header=text, prim=prim, attribute=attr, files=files)


def _text(path: str) -> str:
    """The file's text: UTF-8 (a byte-order mark dropped) or UTF-16 with its byte-order mark."""
    with open(path, "rb") as f:
        raw = f.read()
    if raw.startswith(_WORKBOOKS):
        raise SceneError(f"{path}: a spreadsheet workbook, not CSV text: save it as CSV (UTF-8), one row per variant")
    try:
        if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
            return raw.decode("utf-16")
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise SceneError(
            f"{path}: line {line}: not UTF-8 text (byte 0x{raw[e.start]:02x}): save the table as CSV UTF-8"
        ) from None


def _separator(text: str) -> str:
    """``,``; or ``;`` or a tab where the header (the first line with text) has one outside quotes
    and no comma (as spreadsheets of some locales save CSV)."""
    header = next((line for line in text.splitlines() if line.strip()), "")
    outside = "".join(header.split('"')[::2])  # (PRIM_PATH.ATTRIBUTE never holds a separator)
    if "," in outside:
        return ","
    return next((s for s in (";", "\t") if s in outside), ",")


def _hint(row: list[str], columns: int, separator: str) -> str:
    """Why a row has more cells than the header, where it can be told: a vector or array cell
    split at its commas (a piece starting with ``(`` or ``[``; named first, as its pieces may look
    like a number split by a decimal comma), or a decimal comma or thousands separator."""
    cells = [c.strip() for c in row]
    opened = next((k for k, c in enumerate(cells) if c[:1] in ("(", "[")), None)
    if opened is not None:
        closed = next((k for k in range(opened, len(cells)) if cells[k][-1:] in (")", "]")), None)
        if closed is not None and closed > opened:
            whole = (", " if separator == "," else separator).join(cells[opened : closed + 1])
            what = "commas" if separator == "," else f"{separator!r} separators"
            return f': a vector or array cell must be quoted (its {what} split it into cells): write "{whole}" in double quotes'
        return ': a vector or array cell must be quoted, e.g. "(0, 0.02, 0)" (in double quotes)'
    if separator == "," and any(_DIGITS.match(a) and _FRACTION.match(b) for a, b in zip(cells, cells[1:])):
        return ": a decimal comma (1,5) or a thousands separator (1,000) splits a number: write 1.5, 1000"
    if any(c[-1:] in (")", "]") for c in cells):
        return ': a vector or array cell must be quoted, e.g. "(0, 0.02, 0)" (in double quotes)'
    return ""


def _unclosed_quote(lines: list[str], first: int, separator: str) -> int | None:
    """The line (``lines[0]`` is line ``first``) where a quote opens a cell that no later quote
    closes, as the csv module reads ``lines`` (a quote opens a cell only at its start, spaces
    before it skipped; ``""`` inside a quoted cell is a quote), or None where every quote closes.
    The csv module reads such a cell to the end of the file without a word."""
    state, opened = "start", None
    for n, line in enumerate(lines, first):
        for ch in line:
            if state == "quoted":
                if ch == '"':
                    state = "quote"  # the closing quote, or the first of a doubled one
            elif state == "quote" and ch == '"':
                state = "quoted"
            elif ch == separator or ch in "\r\n":
                state = "start"
            elif state == "start":
                if ch == '"':
                    state, opened = "quoted", n
                elif ch != " ":
                    state = "field"
            else:
                state = "field"
    return opened if state == "quoted" else None


def _blank(line: str, separator: str) -> bool:
    """Whether ``line`` holds nothing: no cell, not even an empty one (``,``, ``""``)."""
    return not line.strip(" \r\n" if separator == "\t" else " \t\r\n")


def _records(path: str, text: str, separator: str) -> list:
    """Each CSV record of ``text``: (the line where it starts, its cells)."""
    if csv.field_size_limit() < _CELL_LIMIT:  # (131,072 characters by default: an inline array of 5,000 points)
        csv.field_size_limit(_CELL_LIMIT)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=separator, skipinitialspace=True)
    try:
        rows = list(reader)
    except csv.Error:
        rows = None  # (read again below, to name the record's line)
    if rows is not None and reader.line_num == len(rows):  # (a line a record: no cell runs over lines)
        return list(zip(range(1, len(rows) + 1), rows))
    records = []
    try:
        reader = csv.reader(io.StringIO(text, newline=""), delimiter=separator, skipinitialspace=True)
        start = 1
        for row in reader:
            records.append((start, row))
            start = reader.line_num + 1
    except csv.Error as e:
        raise SceneError(f"{path}: line {start}: not readable as CSV ({e})") from None
    return records


def read_table(path: str) -> Table:
    """Read and check the table's structure (not its values: they need the scene's types).

    Lines with nothing on them are skipped, as are rows of empty unquoted cells (``,,``) before the
    header and after the last row holding a value (a spreadsheet saves its empty rows so); any
    other row of empty cells (``""``: what pandas writes for NaN in a table of one column; ``,``
    before a later row) is a row, whose empty cells the values' check refuses: a row skipped there
    would give the later rows' values to other variants. A quoted cell may run over lines.

    Raises:
        SceneError: no such file, not CSV text, no header, a header cell that is not
            ``PRIM_PATH.ATTRIBUTE``, the same attribute twice, no rows, a row with more or fewer
            cells than the header, or a quote that is never closed.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise SceneError(f"{path}: no such file (the variants table)")
    text = _text(path)
    separator = _separator(text)
    records = _records(path, text, separator)  # (line where the record starts, cells)
    raw = None  # the file's lines as the csv module split them, where needed
    if records and '"' in text:
        raw = io.StringIO(text, newline="").readlines()
        opened = _unclosed_quote(raw[records[-1][0] - 1:], records[-1][0], separator)
        if opened is not None:
            raise SceneError(f"{path}: line {opened}: a quote (\") opens a cell there and is never closed (the rest of "
                             "the file would be read as that cell): close it, and write a quote inside a quoted cell "
                             "as two (\"\")")  # fmt: skip
    joined = list(map("".join, map(itemgetter(1), records)))
    empty = [k for k, j in enumerate(joined) if not j.strip()] if "" in joined or any(map(str.isspace, joined)) else []
    if empty:
        raw = raw if raw is not None else io.StringIO(text, newline="").readlines()
        held = [k for k in range(len(records)) if "".join(records[k][1]).strip()]
        first, last = (held[0], held[-1]) if held else (len(records), -1)
        drop = {k for k in empty if _blank(raw[records[k][0] - 1], separator)
                or ((k < first or k > last) and '"' not in raw[records[k][0] - 1])}  # fmt: skip
        records = [rec for k, rec in enumerate(records) if k not in drop]
    if not records:
        raise SceneError(f"{path}: empty: expected a header row of PRIM_PATH.ATTRIBUTE columns and a row per variant")
    head_line, header = records[0]
    width = len(header)
    while width > 0 and not header[width - 1].strip():  # empty columns after the last header
        width -= 1
    columns = tuple(_column(path, head_line, k, cell) for k, cell in enumerate(header[:width]))
    seen = {}
    for k, c in enumerate(columns):
        if c.target in seen:
            raise SceneError(f"{path}: line {head_line}: columns {seen[c.target] + 1} and {k + 1} both set {c.target}")
        seen[c.target] = k
    rows, lines = [], []
    n_columns = len(columns)
    strip = str.strip
    cells = list(map(itemgetter(1), records[1:]))
    if all(map(eq, map(len, cells), repeat(n_columns))):  # (every row a cell per column: all at once)
        rows, lines = list(map(tuple, map(map, repeat(strip), cells))), list(map(itemgetter(0), records[1:]))
    else:
        for line, row in records[1:]:
            if len(row) == n_columns:  # (most rows: a cell per column)
                rows.append(tuple(map(strip, row)))
                lines.append(line)
                continue
            r = len(rows)
            extra = [k for k in range(len(columns), len(row)) if row[k].strip()]
            if len(row) < len(columns) or (extra and extra[-1] >= len(header)):
                hint = _hint(row, len(columns), separator) if len(row) > len(columns) else ""
                raise SceneError(f"{path}: row {r} (line {line}): {len(row)} cells for {len(columns)} columns{hint}")
            if extra:
                raise SceneError(f"{path}: row {r} (line {line}), column {extra[0] + 1}: a value under an empty header cell")
            rows.append(tuple(cell.strip() for cell in row[: len(columns)]))
            lines.append(line)
    if not rows:
        raise SceneError(f"{path}: no rows: expected one row per variant under the header")
    return Table(path=path, columns=columns, rows=tuple(rows), lines=tuple(lines), separator=separator)
