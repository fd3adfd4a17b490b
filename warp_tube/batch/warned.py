"""What reading a batch's variants warns of, said once per message and naming the variant.

The scene reader warns of what it reads (a force on a pinned point, an anchor with no stiffness).
In a batch, what it says of the scene itself is said once; what a row's values make it say is said
once, naming the first row (its line and column) that gave it and how many others did, not once
per row or with no row named.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from .table import Table

__all__ = ["HeldWarnings", "warned_where", "say_warnings", "merged_warnings", "warn_same_choices", "same_scene"]

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


def warn_same_choices(axes: list, bases: dict) -> None:
    """Warn of a crossed variantSet (``axes``: :class:`~warp_tube.batch.variants.VariantSetAxis`)
    whose choices all give the same scene (``bases``: each combination's scene, by its choices):
    what it sets is decided by a stronger opinion (the
    attribute authored on the prim itself, or in a stronger layer), so its variants are one."""
    first = next(iter(bases), None)  # (the other sets' choices each row keeps)
    if first is None:
        return
    for k, axis in enumerate(axes):
        if len(axis.choices) < 2:
            continue
        row = [bases.get(first[:k] + (choice,) + first[k + 1:]) for choice in axis.choices]
        if any(b is None for b in row) or not all(same_scene(row[0], b) for b in row[1:]):
            continue
        log.warning("variantSet %s: its %d choices give the same scene: what it sets is decided by a stronger opinion "
                    "(the attribute authored on the prim itself, or in a stronger layer), so its variants are the same "
                    "simulation", axis.label, len(axis.choices))  # fmt: skip


def same_scene(a, b) -> bool:
    """Whether two scenes (or parts of them) are equal field for field, arrays element for
    element (where they came from, ``source``, aside)."""
    if a is b:
        return True
    if dataclasses.is_dataclass(a):
        return type(a) is type(b) and all(same_scene(getattr(a, f.name), getattr(b, f.name))
                                          for f in dataclasses.fields(a) if f.name != "source")  # fmt: skip
    if isinstance(a, (tuple, list)):
        return isinstance(b, (tuple, list)) and len(a) == len(b) and all(map(same_scene, a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(same_scene(a[key], b[key]) for key in a)
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return False
