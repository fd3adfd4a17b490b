"""Where a run's frames go: output writers, found by the output file's suffix.

The frame loop (:meth:`warp_tube.sim.simulation.Simulation.run`) hands each written frame to a
writer and never imports one: the output stage (:mod:`warp_tube.io`) registers its writers here
when it is imported (``import warp_tube`` does so before a ``Simulation`` is handed out). A writer
is made as ``factory(path, scene, surfaces, start_time_code=..., inputs=...)`` and has:

- ``write_frame(time_code, centerlines, surfaces)``: one frame, in stage units (per tube prim:
  centerline points (P, 3); surface points and normals (V, 3) and extent (2, 3), or None);
- ``close() -> str``: the complete output, moved into place; returns its path;
- ``keep_partial() -> str | None``: on a run that stopped, the frames written so far saved beside
  the output under a name that says they are partial (None when there are none);
- ``abort()``: nothing kept; ``closed``: whether one of the three has run.
"""

from __future__ import annotations

import os
from typing import Callable

from ..scene.spec import SceneError

__all__ = ["register_writer", "open_writer", "writer_suffixes", "frame_range", "unwritten_frames"]

_WRITERS: dict[str, Callable] = {}


def register_writer(suffixes, factory: Callable) -> None:
    """Write outputs whose file name ends in one of ``suffixes`` (e.g. ``(".usdc",)``) with ``factory``."""
    for s in suffixes:
        _WRITERS[s.lower()] = factory


def writer_suffixes() -> list[str]:
    """The output suffixes a writer is registered for, in the order they were registered."""
    return list(_WRITERS)


def open_writer(path, scene, surfaces, **kwargs):
    """A new writer for ``path`` (see the module docstring for its arguments and methods).

    Raises:
        SceneError: no writer is registered for the file's suffix.
    """
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    factory = _WRITERS.get(suffix)
    if factory is None:
        known = ", ".join(writer_suffixes()) or "a registered writer's (import warp_tube.io)"
        raise SceneError(f"{path}: output extension {suffix or '(none)'}: expected {known}")
    return factory(path, scene, surfaces, **kwargs)


def frame_range(first: int, last: int) -> str:
    """``frame 7`` or ``frames 7 to 9``: frames ``first`` to ``last`` (included), in words."""
    return f"frame {first}" if first == last else f"frames {first} to {last}"


def unwritten_frames(first: int, last: int, last_written: int) -> str:
    """What ``--every K`` leaves out at the end of a run: ``frame 19 is simulated but not written
    (the last written is frame 18)``, ``frames 18 to 19 are ...`` for several."""
    verb = "is" if first == last else "are"
    return f"{frame_range(first, last)} {verb} simulated but not written (the last written is frame {last_written})"
