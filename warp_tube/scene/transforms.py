"""A tube prim's transforms: its points to world space, and warnings for what the scene cannot
follow (an uneven scale, an animated transform)."""

from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger("warp_tube.scene.usd")

__all__ = ["to_world", "section_scale", "uneven", "warn_about_layer_units", "warn_about_transforms"]


def warn_about_transforms(prim, matrix: np.ndarray, pattr_sampled: bool, where: str, varying: dict | None = None) -> None:
    """Warn where a tube's transforms do what the scene cannot follow: a scale that is not the
    same along every axis (a round section becomes an ellipse: taken as the circle of its area,
    :func:`section_scale`), and an
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
    if uneven(m):
        sv = np.linalg.svd(m, compute_uv=False)
        log.warning("%s: its transform scales unevenly (by %s along its principal axes): a round section becomes an "
                    "ellipse, taken as the circle of its area (each point's radius scaled by sqrt(det / the scale "
                    "along the tube there))", where, ", ".join(f"{x:.4g}" for x in sv))  # fmt: skip
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


def uneven(m: np.ndarray) -> bool:
    """Whether the linear part ``m`` (3, 3) of a transform scales unevenly (not a rotation, with or
    without a mirror, times one scale), beyond round-off."""
    g = m @ m.T  # a uniform scale s (with any rotation): s^2 I
    d = np.diag(g)
    return bool(d.min() > 0.0 and (d.max() > d.min() * (1.0 + 2e-6) or np.abs(g - np.diag(d)).max() > 1e-6 * d.max()))


def section_scale(pts: np.ndarray, counts: np.ndarray, matrix: np.ndarray) -> np.ndarray | None:
    """Per point, the factor by which an uneven transform scales a round section's radius, or None
    where the transform scales evenly (every radius takes the one scale, :func:`to_world`).

    The transform takes a thin slab of the tube across its tangent ``t`` (prim space) to one of
    ``|det M|`` times its volume and ``|M t|`` times its length, so its section across the new
    axis has ``|det M| / |M t|`` times the area: the circle of that area has ``sqrt(|det M| / |M
    t|)`` times the radius (mass and stretching follow the area exactly; bending takes the
    ellipse as that circle). ``t`` is the bisector of a point's two edges (its edge at a curve's ends).

    Args:
        pts: points in the prim's space (P, 3).
        counts: points per curve (C,).
        matrix: the local-to-world transform (4, 4), row vectors (:func:`to_world`).
    """
    m = np.asarray(matrix, dtype=np.float64)[:3, :3]
    if not uneven(m):
        return None
    edge = np.diff(pts, axis=0)
    edge /= np.maximum(np.linalg.norm(edge, axis=1, keepdims=True), 1e-300)
    last = np.cumsum(counts) - 1  # a curve's last point: no edge to the next curve
    inside = np.ones(len(pts) - 1, dtype=bool)
    inside[last[:-1]] = False
    edge[~inside] = 0.0
    t = np.zeros_like(pts)
    t[:-1] += edge
    t[1:] += edge
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    return np.sqrt(abs(np.linalg.det(m)) / np.maximum(np.linalg.norm(t @ m, axis=1), 1e-300))


def to_world(prim, pts: np.ndarray, time, file: str = "") -> tuple[np.ndarray, float, np.ndarray]:
    """Points (P, 3) to world space; also the transform's mean length scale and its matrix (4, 4).

    Raises:
        SceneError: a transform of the prim or an ancestor that usd-core cannot compute (an xformOp
            of the wrong type), that is not finite, or that has a zero scale; naming ``file``, that
            prim and its ``xformOpOrder``.
    """
    from pxr import Tf, UsdGeom

    try:
        m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64)
    except Tf.ErrorException:
        m = None
    if m is None or not _usable(m):
        _raise_for_transform(prim, time, file)
    out = pts @ m[:3, :3] + m[3, :3]
    scale = abs(np.linalg.det(m[:3, :3])) ** (1.0 / 3.0)
    return out, scale, m


def warn_about_layer_units(prim, points_attr, matrix: np.ndarray, stage_mpu: float, stage_up: str, where: str) -> None:
    """Warn where a tube's points come from a layer (a reference, payload or sublayer) whose own
    ``metersPerUnit`` or ``upAxis`` differs from the stage's: USD does not convert them, so the
    points are taken in the stage's units and axes. No warning where the tube's transform makes up
    for it (scales by the ratio of the units, turns the layer's up axis to the stage's).

    Args:
        prim: the tube prim.
        points_attr: its ``points`` attribute.
        matrix: its local-to-world matrix at the first frame (4, 4), row vectors (:func:`to_world`).
        stage_mpu, stage_up: the stage's metersPerUnit and upAxis ("Y" or "Z").
        where: the prim and attribute, for the message.
    """
    specs = points_attr.GetPropertyStack()
    if not specs:
        return
    layer = specs[0].layer
    root = prim.GetStage().GetRootLayer()
    if layer == root or layer == prim.GetStage().GetSessionLayer():
        return
    info = layer.pseudoRoot
    name = layer.realPath or layer.identifier
    m = np.asarray(matrix, dtype=np.float64)[:3, :3]
    scale = abs(np.linalg.det(m)) ** (1.0 / 3.0)
    if info.HasInfo("metersPerUnit"):
        mpu = float(info.GetInfo("metersPerUnit"))
        if mpu > 0 and abs(mpu / stage_mpu - 1.0) > 1e-6 and abs(scale * stage_mpu / mpu - 1.0) > 1e-3:
            log.warning("%s: comes from %s, whose metersPerUnit is %g, but the stage's is %g: USD does not convert "
                        "units between layers, so its points are taken in the stage's units (%g times their size; "
                        "a scale of %g on the prim that brings it in makes up for it)",
                        where, name, mpu, stage_mpu, stage_mpu / mpu, mpu / stage_mpu)  # fmt: skip
    if info.HasInfo("upAxis"):
        up = str(info.GetInfo("upAxis")).upper()
        axis = {"Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}
        if up in axis and up != stage_up.upper():
            turned = axis[up] @ m
            if np.dot(turned, axis[stage_up.upper()]) < 0.999 * np.linalg.norm(turned):
                log.warning("%s: comes from %s, whose upAxis is %s, but the stage's is %s: USD does not turn layers "
                            "to the stage's up axis, so the tube lies as authored (rotate the prim that brings it in "
                            "to make up for it)", where, name, up, stage_up.upper())  # fmt: skip


def _usable(m: np.ndarray) -> bool:
    """A finite affine matrix (row vectors: last column (0, 0, 0, 1)) whose linear part keeps
    volumes (relative to its size) away from zero."""
    if not np.isfinite(m).all() or not _affine(m):
        return False
    size = np.abs(m[:3, :3]).max()
    return size > 0.0 and abs(np.linalg.det(m[:3, :3] / size)) > 1e-12


def _raise_for_transform(prim, time, file: str):
    """SceneError naming the prim (``prim`` or the nearest ancestor) whose own transform is wrong."""
    import re

    from pxr import Tf, UsdGeom

    from .attributes import where
    from .spec import SceneError

    p, what = prim, "cannot be computed"
    while p and not p.IsPseudoRoot():
        x = UsdGeom.Xformable(p)
        if x:
            try:
                local = np.array(x.GetLocalTransformation(time), dtype=np.float64)
            except Tf.ErrorException as e:
                said = re.findall(r": '(.*?)'\s*(?=\n\s*Error in|\Z)", str(e), re.S)
                said = re.sub(r"\s*Returning identity matrix\.?", "", said[0] if said else str(e).strip())
                what = f"cannot be computed ({said})"
                break
            if not np.isfinite(local).all():
                what = "is not finite"
                break
            if not _affine(local):
                what = f"is projective (last column {np.round(local[:, 3], 6).tolist()}, not [0, 0, 0, 1])"
                break
            if not _usable(local):
                what = "has a zero scale"
                break
        p = p.GetParent()
    else:
        p = prim
    raise SceneError(f"{where(file, p, 'xformOpOrder')}: its transform {what} (it places the tube {prim.GetPath()}): "
                     "expected finite, affine xformOps of their own types, with a non-zero scale")  # fmt: skip


def _affine(m: np.ndarray) -> bool:
    """Whether the 4x4 row-vector matrix ``m`` is affine (a projective part would bend straight
    segments and has no length scale for the widths)."""
    return bool(np.allclose(m[:, 3], (0.0, 0.0, 0.0, 1.0), rtol=0.0, atol=1e-12 * max(1.0, float(np.abs(m).max()))))
