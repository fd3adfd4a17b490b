"""Counts in extraction messages: a number with its noun, singular or plural ("1 face", "3 faces")."""

from __future__ import annotations

__all__ = ["counted"]

_PLURALS = {"vertex": "vertices", "branch": "branches", "side branch": "side branches"}


def counted(n: int, noun: str, plural: str | None = None, fmt: str = "d") -> str:
    """``n`` and ``noun``, the noun plural unless ``n`` is 1: ``1 face``, ``0 faces``, ``2 vertices``.

    Args:
        n: the count.
        noun: the singular noun ("face", "vertex", "inside voxel").
        plural: the plural when it is not the noun plus "s" or one of the known ones (vertices, branches).
        fmt: format of the number (``","`` for thousands separators).
    """
    word = noun if int(n) == 1 else (plural or _PLURALS.get(noun) or f"{noun}s")
    return f"{int(n):{fmt}} {word}"
