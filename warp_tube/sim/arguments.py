"""What a :class:`~warp_tube.sim.simulation.Simulation` is given, checked before it builds or
runs: the scene (a Scene, not a path; one built in Python gets the rest-shape warnings a USD
stage gets when read) and a run's output name."""

from __future__ import annotations

import os

import numpy as np

from ..scene.ranges import check_scene_ranges
from ..scene.shape_notes import check_world_precision, warn_about_shape
from ..scene.spec import Scene, SceneError

__all__ = ["checked_scene", "checked_output", "checked_progress"]


def checked_scene(scene) -> Scene:
    """``scene`` itself; TypeError where it is not a :class:`Scene` (a path: ``load_scene`` reads
    one). A scene built in Python (``source`` ``"<python>"``) is checked and warned of as the USD
    reader checks a stage's tubes (:func:`warp_tube.scene.shape_notes.check_world_precision`,
    :func:`~warp_tube.scene.shape_notes.warn_about_shape`): SceneError where float32 world
    coordinates cannot hold its points."""
    if not isinstance(scene, Scene):
        hint = " (a scene file: warp_tube.load_scene(path) reads it)" if isinstance(scene, (str, os.PathLike)) else ""
        raise TypeError(f"scene: a {type(scene).__name__}: expected a warp_tube.Scene{hint}")
    if scene.source == "<python>":
        check_scene_ranges(scene)
        mpu = scene.stage.meters_per_unit
        for t in scene.tubes:
            check_world_precision(f"{t.path}.points", t.points, t.curve_counts)
            warn_about_shape(f"{t.path}.points", t.points / mpu, t.points, t.curve_counts, t.radius, t.pinned, t.anchors,
                             f"{t.path}.anchorPoints")  # fmt: skip
    return scene


def checked_output(output):
    """A run's ``output``: None (no file) or a non-empty path; SceneError for an empty name,
    TypeError for anything else than a path."""
    if output is not None and not isinstance(output, (str, os.PathLike)):
        raise TypeError(f"output {output!r}: a {type(output).__name__}: expected a file path (str or os.PathLike) or None")
    if output is not None and os.fspath(output) == "":
        raise SceneError("output '': an empty file name: expected a .usdc, .usda or .usd path, or None for no file")
    return output


def checked_progress(progress):
    """A run's ``progress``: None, True or False, or a function ``progress(done, total)``;
    TypeError for anything else."""
    if progress is None or isinstance(progress, (bool, np.bool_)) or callable(progress):
        return progress
    raise TypeError(f"progress {progress!r}: a {type(progress).__name__}: expected None, True or False, or a function "
                    "progress(done, total)")
