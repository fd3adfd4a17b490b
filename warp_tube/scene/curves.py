"""A tube prim's BasisCurves schema values as DCC tools author them: its curve type and wrap, and its
diameters from ``widths`` or ``primvars:widths`` in any of their interpolations."""

from __future__ import annotations

import logging

import numpy as np

from .attributes import samples_differ
from .spec import SceneError

log = logging.getLogger("warp_tube.scene.usd")

__all__ = ["check_curve_type", "check_points_type", "curve_widths"]

#: the array types a tube's points may be authored as
POINT_ARRAYS = ("point3f[]", "point3d[]", "float3[]", "double3[]", "vector3f[]", "vector3d[]", "half3[]", "point3h[]")


def check_curve_type(r, curves) -> None:
    """A SceneError (through the prim reader ``r``) unless the curves are linear and open.

    ``type`` unauthored takes USD's fallback, "cubic"; ``wrap = "periodic"`` closes each curve
    into a loop, which a tube with two ends cannot follow (``"pinned"`` applies to cubic curves
    only, so a linear curve ignores it, as USD does).
    """
    type_attr = curves.GetTypeAttr()
    if not type_attr.HasAuthoredValue():
        raise SceneError(f"{r.where('type')}: not authored (USD's fallback is 'cubic'): expected "
                         "uniform token type = \"linear\" (each point of a curve is a centerline point)")  # fmt: skip
    ctype = type_attr.Get()
    if ctype != "linear":
        r.fail("type", repr(ctype), "'linear' (each point of a curve is a centerline point)")
    wrap = curves.GetWrapAttr().Get()
    if wrap not in ("nonperiodic", "periodic", "pinned"):
        r.fail("wrap", repr(wrap), "'nonperiodic' (or 'pinned', which linear curves ignore)")
    if wrap == "periodic":
        r.fail("wrap", "'periodic' (closed curves)", "'nonperiodic': each curve is a tube with two ends; a closed "
               "loop is not supported (an open curve whose last point repeats the first gives a ring with a seam)")  # fmt: skip


def curve_widths(r, curves, counts: np.ndarray, time) -> np.ndarray:
    """Diameters, one per point (stage units), at ``time``.

    ``primvars:widths`` wins over ``widths`` where both are authored (USD's rule; its indices are
    applied). Either may hold one value (constant), one per curve (``uniform``) or one per point
    (``vertex``, or ``varying``, which for linear curves is the same).
    """
    from pxr import UsdGeom

    n_points = int(counts.sum())
    primvar = UsdGeom.PrimvarsAPI(curves.GetPrim()).GetPrimvar("widths")
    if primvar and primvar.HasAuthoredValue():
        name, interpolation = "primvars:widths", primvar.GetInterpolation()
        _check_array_type(r, name, primvar.GetAttr())
        values = primvar.Get(time)
        indices = primvar.GetIndices(time) if primvar.IsIndexed() else None
        if indices is not None and values is not None:
            indices = np.asarray(indices, dtype=np.int64)
            bad = (indices < 0) | (indices >= len(values))
            if bad.any():
                i = int(np.argmax(bad))
                r.fail("primvars:widths:indices", f"{indices[i]} at position {i}", f"indices 0..{len(values) - 1} into primvars:widths")
            values = np.asarray(values, dtype=np.float64)[indices]
    elif curves.GetWidthsAttr().HasAuthoredValue():
        name, interpolation = "widths", curves.GetWidthsInterpolation()
        _check_array_type(r, name, curves.GetWidthsAttr())
        values = curves.GetWidthsAttr().Get(time)
    else:
        raise SceneError(f"{r.where('widths')}: missing: expected float[] diameters (one, one per curve with "
                         "interpolation \"uniform\", or one per point), as widths or primvars:widths")  # fmt: skip
    attr = primvar.GetAttr() if name == "primvars:widths" else curves.GetWidthsAttr()
    if samples_differ(attr):
        log.warning("%s: time-sampled: the diameters at the first frame are used for the whole run (a tube's "
                    "widths are not animated)", r.where(name))  # fmt: skip
    if values is None or len(values) == 0:
        raise SceneError(f"{r.where(name)}: empty: expected float[] diameters (one, or one per point)")
    widths = np.asarray(values, dtype=np.float64).reshape(-1)
    if len(widths) == 1:
        widths = np.full(n_points, widths[0])
    elif interpolation == "uniform" and len(widths) == len(counts):
        widths = np.repeat(widths, counts)
    elif len(widths) != n_points:
        per_curve = f", {len(counts)} (uniform: one per curve)" if len(counts) > 1 else ""
        r.fail(name, f"{len(widths)} values (interpolation {interpolation!r})", f"1 (constant){per_curve} or {n_points} (one per point)")
    bad = ~(np.isfinite(widths) & (widths > 0))
    if bad.any():
        i = int(np.argmax(bad))
        r.fail(name, f"{widths[i]} at index {i}", "positive finite diameters")
    return widths


def check_points_type(r, attr) -> None:
    """A SceneError unless ``points`` is authored as an array of 3-vectors."""
    _check_array_type(r, "points", attr, POINT_ARRAYS, "point3f[] positions")


def _check_array_type(r, name: str, attr, allowed=("float[]", "double[]", "half[]"), expected="float[] diameters") -> None:
    # the type as authored: for a schema attribute (widths, points) the attribute reports the schema's type
    specs = attr.GetPropertyStack()
    tname = str(specs[0].typeName) if specs else str(attr.GetTypeName())
    if tname not in allowed:
        r.fail(name, f"type {tname}", expected)
