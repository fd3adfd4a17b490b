"""Edits of a scene file a command has just written (see :mod:`warp_tube.scene.files`)."""

from __future__ import annotations

import numpy as np

from .spec import SceneError

__all__ = ["scale_force_samples"]


def scale_force_samples(path: str, force_path: str, factor: float) -> None:
    """Multiply every value of ``force_path``'s ``warptube:force`` (default and time samples) in the
    scene file ``path`` by ``factor``, rewriting the file atomically (a scene a command has just
    written: see :mod:`warp_tube.scene.files`)."""
    from pxr import Gf, Sdf

    from .files import write_atomically

    layer = Sdf.Layer.FindOrOpen(path)
    if layer is None:
        raise SceneError(f"{path}: cannot open")
    spec = layer.GetAttributeAtPath(Sdf.Path(force_path).AppendProperty("warptube:force"))
    if spec is None:
        raise SceneError(f"{path}: no {force_path}.warptube:force")
    if spec.default is not None:
        spec.default = Gf.Vec3f(*(float(factor) * np.asarray(spec.default, dtype=float)))
    for t in layer.ListTimeSamplesForPath(spec.path):
        value = np.asarray(layer.QueryTimeSample(spec.path, t), dtype=float)
        layer.SetTimeSample(spec.path, t, Gf.Vec3f(*(float(factor) * value)))

    def export(tmp: str):
        if not layer.Export(tmp):
            raise SceneError(f"{path}: cannot write")

    write_atomically(path, export)
    layer.Reload(force=True)
