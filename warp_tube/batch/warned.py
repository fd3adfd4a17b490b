"""What reading a batch's variants warns of, said once per message and naming the variant.

The scene reader warns of what it reads (a force on a pinned point, an anchor with no stiffness).
In a batch, what it says of the scene itself is said once; what a row's values make it say is said
once, naming the first row (its line and column) that gave it and how many others did, not once
per row or with no row named.
"""

from __future__ import annotations

import logging

from .table import Table

__all__ = ["HeldWarnings", "warned_where", "say_warnings", "merged_warnings"]

log = logging.getLogger(__name__)


class HeldWarnings(logging.Filter):
    """The reader's warnings while a batch reads its variants: those of the scene as it is (read
    with no row's values) pass once each; a variant's are held, by message, with the first variant
    that gave it and how many did, to be said once naming them (not once unnamed, or per row)."""

    def __init__(self):
        super().__init__()
        self.index = self.name = None  # the variant being read and what names it in a message, or None: the scene
        self.said: set = set()
        self.held: dict = {}  # message -> [first index, where, how many]
        self.given: list = []  # the messages of the variant being read

    def filter(self, record) -> bool:
        if record.levelno < logging.WARNING:
            return True
        message = record.getMessage()
        if self.name is None or message in self.said:
            new = message not in self.said
            self.said.add(message)
            return new
        self.given.append(message)
        self.add(message, self.index, self.name(message), 1)
        return False

    def add(self, message: str, index: int, where: str | None, count: int) -> None:
        """Hold ``message`` of variant ``index`` named by ``where`` (None: a message of the table's,
        said once as it is), given ``count`` times."""
        held = self.held.get(message)
        if held is None:
            self.held[message] = [index, where, count]
        elif where is not None:
            held[2] += count
            if index < held[0]:
                held[:2] = index, where

    def reading(self, index: int | None = None, name=None) -> list:
        """The messages of variant ``index`` are held from now on (None: the scene's pass), each
        named by ``name(message)``; returns the list of them."""
        self.index, self.name, self.given = index, name, []
        return self.given


def warned_where(table: Table, r: int, chosen: str, message: str) -> str:
    """Where a warning of row ``r`` is named: its row, line and the column the message names."""
    col = next((col for col in table.columns if col.target in message), None)
    return f"{table.where(r, col)}{' with ' + chosen if chosen else ''}"


def say_warnings(variants) -> None:
    """Say what reading the variants warned of: each message once, naming the first variant that
    gave it and how many others did."""
    other = "variant(s)" if variants.axes or variants.table is None else "row(s)"
    for message, _, where, count in sorted(variants.warnings, key=lambda w: w[1]):
        if where is None:
            log.warning("%s", message)
            continue
        more = f", and {count - 1} other {other}" if count > 1 else ""
        log.warning("%s%s: %s", where, more, message)


def merged_warnings(parts) -> tuple:
    """The warnings of variants read in parts (:attr:`Variants.warnings` of each), as one read's."""
    held = HeldWarnings()
    for part in parts:
        for w in part.warnings:
            held.add(*w)
    return tuple((m, *h) for m, h in held.held.items())
