"""A logger's records held back, or each distinct one let through once, for the length of a block.

A batch reads and plans thousands of variants with the code that reads and plans one scene; what
that code warns of once per scene is either said once for the batch (:func:`once_each`) or held
back while the batch gives one warning of its own (:func:`silenced`).
"""

from __future__ import annotations

import contextlib
import logging
import re

__all__ = ["silenced", "held", "once_each", "renamed", "same_for_many"]


@contextlib.contextmanager
def _filtered(name: str, keep):
    """Logger ``name`` passes only the records ``keep(record)`` is true for, inside the block."""
    logger = logging.getLogger(name)
    logger.addFilter(keep)
    try:
        yield
    finally:
        logger.removeFilter(keep)


def silenced(name: str):
    """Logger ``name`` passes nothing inside the block."""
    return _filtered(name, lambda record: False)


def held(name: str, records: list):
    """Logger ``name`` passes nothing inside the block: its records are kept in ``records``, for
    the caller to pass on those it chooses."""
    return _filtered(name, lambda record: records.append(record) or False)


def once_each(name: str, prefix: str = "", key=None):
    """Logger ``name`` passes each distinct message once inside the block (the same warning for
    every variant is one), each after ``prefix`` (what the block is doing, where that is not what
    the user asked for); ``key(message)``: what makes two messages the same (default: the text)."""
    seen: set = set()

    def keep(record) -> bool:
        message = record.getMessage()
        k = message if key is None else key(message)
        if k in seen:
            return False
        seen.add(k)
        if prefix:
            record.msg, record.args = prefix + message, None
        return True

    return _filtered(name, keep)


@contextlib.contextmanager
def renamed(old: str, new: str):
    """Every record that reaches a handler of the root logger names ``new`` where it would name
    ``old`` (a file edited under a temporary name, named in messages as the file it becomes)."""

    def rename(record: logging.LogRecord) -> bool:
        text = record.getMessage()
        if old in text:
            record.msg, record.args = text.replace(old, new), None
        return True

    handlers = list(logging.getLogger().handlers)
    for h in handlers:
        h.addFilter(rename)
    try:
        yield
    finally:
        for h in handlers:
            h.removeFilter(rename)


@contextlib.contextmanager
def same_for_many(name: str, subject=re.compile(r"(?<![\w.])/[^\s:.]+")):
    """Logger ``name``'s records that differ only in the prim path they name (``subject``: what a
    path looks like) pass once inside the block; at its end one more record says for how many
    other prims the same was said. A scene of 1,000 prims with the same time-sampled attribute
    gets two lines, not 1,000."""
    logger = logging.getLogger(name)
    seen: dict = {}  # key -> [the first record, how many more]

    def keep(record) -> bool:
        key = (record.levelno, subject.sub("PRIM", record.getMessage()))
        held = seen.get(key)
        if held is None:
            seen[key] = [record, 0]
            return True
        held[1] += 1
        return False

    try:
        with _filtered(name, keep):
            yield
    finally:
        for first, more in seen.values():
            if more:
                logger.log(first.levelno, "the same for %d more prim(s) of the scene", more)
