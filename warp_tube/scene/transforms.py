"""A tube prim's transforms: its points to world space, and warnings for what the scene cannot
follow (an uneven scale, an animated transform)."""

from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger("warp_tube.scene.usd")

__all__ = ["to_world", "warn_about_transforms"]


def warn_about_transforms(prim, matrix: np.ndarray, pattr_sampled: bool, where: str, varying: dict | None = None) -> None:
    """Warn where a tube's transforms do what the scene cannot follow: a scale that is not the
    same along every axis (widths take its geometric mean: a round section stays round), and an
    animated transform on a tube whose points are not time-sampled (the rest shape and pins are
    taken at the first frame; only time-sampled points move pins, through the transform).

    Args:
        prim: the tube prim.
        matrix: its local-to-world matrix at the first frame (4, 4), row vectors (:func:`to_world`).
        pattr_sampled: whether its points are time-sampled.
        where: the prim and attribute, for the message.
        varying: prim path -> whether its own transform may vary in time, kept over a scene's tubes
            (they mostly share their ancestors).
    """
    from pxr import UsdGeom

    m = np.asarray(matrix, dtype=np.float64)[:3, :3]
    g = m @ m.T  # a uniform scale s (with any rotation): s^2 I
    d = np.diag(g)
    if d.min() > 0.0 and (d.max() > d.min() * (1.0 + 2e-6) or np.abs(g - np.diag(d)).max() > 1e-6 * d.max()):
        sv = np.linalg.svd(m, compute_uv=False)
        log.warning("%s: its transform scales unevenly (by %s along its principal axes): widths are scaled by the "
                    "geometric mean %.4g", where, ", ".join(f"{x:.4g}" for x in sv), float(np.prod(sv)) ** (1.0 / 3.0))  # fmt: skip
    if pattr_sampled:
        return
    varying = {} if varying is None else varying
    p = prim
    while p and not p.IsPseudoRoot():
        key = p.GetPath()
        moves = varying.get(key)
        if moves is None:
            x = UsdGeom.Xformable(p)
            moves = varying[key] = bool(x and x.TransformMightBeTimeVarying())
        if moves:
            log.warning("%s: the transform of %s is animated, which the simulation does not follow (rest shape and pins "
                        "at the first frame); time-sample the points of the pinned points to move them", where, p.GetPath())  # fmt: skip
            return
        p = p.GetParent()


def to_world(prim, pts: np.ndarray, time) -> tuple[np.ndarray, float, np.ndarray]:
    """Points (P, 3) to world space; also the transform's mean length scale and its matrix (4, 4)."""
    from pxr import UsdGeom

    m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64)
    out = pts @ m[:3, :3] + m[3, :3]
    scale = abs(np.linalg.det(m[:3, :3])) ** (1.0 / 3.0)
    return out, scale, m
