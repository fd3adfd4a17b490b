"""A logger's records held back, or each distinct one let through once, for the length of a block.

A batch reads and plans thousands of variants with the code that reads and plans one scene; what
that code warns of once per scene is either said once for the batch (:func:`once_each`) or held
back while the batch gives one warning of its own (:func:`silenced`).
"""

from __future__ import annotations

import contextlib
import logging

__all__ = ["silenced", "once_each", "renamed"]


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
