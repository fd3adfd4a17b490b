"""A tube prim's BasisCurves schema values as DCC tools author them: its curve type and wrap, its
curves' point counts, its diameters from ``widths`` or ``primvars:widths`` in any of their
interpolations, and the later time samples of its ``points`` that moving pins follow."""

from __future__ import annotations

import logging

import numpy as np

from .attributes import missing, samples_differ
from .spec import SceneError
from .transforms import to_world

log = logging.getLogger("warp_tube.scene.usd")

__all__ = ["check_curve_type", "check_points_type", "curve_counts", "curve_widths", "moving_pin_track", "MAX_WORLD_M",
           "BEYOND_WORLD", "curves_extent", "half_width"]  # fmt: skip

#: the array types a tube's points may be authored as
POINT_ARRAYS = ("point3f[]", "point3d[]", "float3[]", "double3[]", "vector3f[]", "vector3d[]", "half3[]", "point3h[]")
#: the largest coordinate or radius a tube may have in world space [m]
MAX_WORLD_M = 1e6
#: what is expected of a coordinate or radius beyond :data:`MAX_WORLD_M`
BEYOND_WORLD = f"at most {MAX_WORLD_M:g} m (past any tube: a transform or metersPerUnit is likely wrong)"


def half_width(widths) -> np.float32:
    """Half the largest of a curves prim's ``widths`` as usd-core pads its points with them (0 for
    none), in float32."""
    widths = np.asarray(widths, dtype=np.float32)
    return np.float32(widths.max() if widths.size else 0.0) * np.float32(0.5)


def curves_extent(points, half: np.float32) -> np.ndarray:
    """A curves prim's ``extent`` by usd-core's rule (``UsdGeomCurves::ComputeExtent``, which
    ``UsdGeom.Boundable.ComputeExtentFromPlugins`` applies): the float32 bounds of its points, each
    side padded by half the largest width (``half``, :func:`half_width`) in float32 arithmetic.

    Args:
        points: shape (..., n, 3), n >= 1 (e.g. (frames, n, 3) for every frame at once).
        half: half the largest width.

    Returns:
        float32, shape (..., 2, 3): ``[min - half, max + half]``.
    """
    points = np.asarray(points, dtype=np.float32)
    out = np.empty((*points.shape[:-2], 2, 3), dtype=np.float32)
    np.subtract(points.min(axis=-2), half, out=out[..., 0, :])
    np.add(points.max(axis=-2), half, out=out[..., 1, :])
    return out


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
        name, interpolation, authored = "primvars:widths", primvar.GetInterpolation(), primvar.HasAuthoredInterpolation()
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
        plain = curves.GetWidthsAttr().Get(time) if curves.GetWidthsAttr().HasAuthoredValue() else None
        if plain is not None and values is not None and not np.array_equal(np.asarray(plain, dtype=np.float64),
                                                                           np.asarray(values, dtype=np.float64)):  # fmt: skip
            log.warning("%s: both authored, with other values than widths: primvars:widths is used (USD's rule), widths "
                        "ignored", r.where("primvars:widths"))  # fmt: skip
    elif curves.GetWidthsAttr().HasAuthoredValue():
        name, interpolation = "widths", curves.GetWidthsInterpolation()
        authored = curves.GetWidthsAttr().HasAuthoredMetadata("interpolation")
        _check_array_type(r, name, curves.GetWidthsAttr())
        values = curves.GetWidthsAttr().Get(time)
    else:
        raise SceneError(f"{r.where('widths')}: {missing(r.prim, ('widths', 'primvars:widths'))}: expected float[] diameters "
                         "(one, one per curve with interpolation \"uniform\", or one per point), as widths or primvars:widths")  # fmt: skip
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
    elif len(widths) == len(counts) and len(widths) != n_points:  # (one per curve, but not said to be)
        takes = f"{interpolation!r}: " + ("one value" if interpolation == "constant" else "one per point")
        how = f" (interpolation {takes})" if authored else f" with no interpolation authored (USD's fallback {takes})"
        r.fail(name, f"{len(widths)} values{how}", f'{n_points} (one per point), or author interpolation = "uniform" on '
               f"{name} for {len(widths)}, one per curve")  # fmt: skip
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


def curve_counts(r, curves, n_points: int, time) -> np.ndarray:
    """The points of each curve, at ``time``: ``curveVertexCounts`` checked against the
    ``n_points`` points; one curve of them all where it is not authored (with a warning)."""
    attr = curves.GetCurveVertexCountsAttr()
    counts = None
    if attr.HasAuthoredValue():
        _check_array_type(r, "curveVertexCounts", attr, ("int[]",), "int[] points per curve")
        counts = attr.Get(time)
    if counts is None:
        log.warning("%s: %s: no curveVertexCounts: taken as one curve of %d points; author curveVertexCounts = [%d]",
                    r.file, r.prim.GetPath(), n_points, n_points)  # fmt: skip
        return np.array([n_points], dtype=np.int64)
    if samples_differ(attr):
        log.warning("%s: time-sampled: the curves at the first frame (%s) are used for the whole run (a tube's "
                    "topology is not animated)", r.where("curveVertexCounts"), list(counts))  # fmt: skip
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    if counts.sum() != n_points or (counts < 2).any():
        r.fail("curveVertexCounts", counts.tolist(), f"counts >= 2 summing to the {n_points} points")
    return counts


def moving_pin_track(r, prim, attr, times, first: np.ndarray, pinned: np.ndarray, mpu: float, file: str) -> np.ndarray:
    """The pinned points' world positions [m] at each of ``times``, from the time-sampled ``points``
    ``attr`` (``first``: the first frame's, for its shape). Every value read is checked as the first
    frame's is (shape, finite, within :data:`MAX_WORLD_M`); a bad value between two samples is
    named by the authored sample that makes it so."""
    track = []
    for tc in times:
        world, problem = _points_at(prim, attr, tc, first.shape, mpu, file)
        if problem is not None:
            for sample in dict.fromkeys(attr.GetBracketingTimeSamples(tc)):
                bad = _points_at(prim, attr, sample, first.shape, mpu, file)[1]
                if bad is not None:
                    r.fail("points", f"{bad[0]} in the sample at time {sample:g}", bad[1])
            r.fail("points", f"{problem[0]} at time {tc:g}", problem[1])
        track.append(world[pinned])
    return np.asarray(track) * mpu


def _points_at(prim, attr, time, shape, mpu, file):
    """(world points in stage units, None) of ``attr`` at ``time``, or (None, (found, expected))
    where they cannot be followed."""
    from pxr import Usd

    value = attr.Get(Usd.TimeCode(time))
    if value is None:
        return None, ("no value (a blocked sample)", f"points of the first frame's shape {shape}")
    p = np.asarray(value, dtype=np.float64)
    if p.shape != shape:
        return None, (f"shape {p.shape}", f"points of the first frame's shape {shape}")
    if not np.isfinite(p).all():
        i = int(np.argmax(~np.isfinite(p).all(axis=1)))
        return None, (f"{p[i].tolist()} at index {i}", "finite values")
    world = to_world(prim, p, Usd.TimeCode(time), file)[0]
    coordinate = float(np.abs(world).max()) * mpu
    if not coordinate <= MAX_WORLD_M:  # (also where the transform overflowed)
        return None, (f"a coordinate of {coordinate:.3g} m (after the transforms and metersPerUnit)", BEYOND_WORLD)
    return world, None
