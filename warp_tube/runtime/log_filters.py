"""A logger's records held back, or each distinct one let through once, for the length of a block.

A batch reads and plans thousands of variants with the code that reads and plans one scene; what
that code warns of once per scene is either said once for the batch (:func:`once_each`) or held
back while the batch gives one warning of its own (:func:`silenced`).
"""

from __future__ import annotations

import contextlib
import logging

__all__ = ["silenced", "once_each"]


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


def once_each(name: str):
    """Logger ``name`` passes each distinct message once inside the block (the same warning for
    every variant is one)."""
    seen: set = set()

    def keep(record) -> bool:
        message = record.getMessage()
        if message in seen:
            return False
        seen.add(message)
        return True

    return _filtered(name, keep)
