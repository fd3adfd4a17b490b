"""Time-sampled USD output (the output contract in the README).

For each tube prim at path P the stage holds an ``Xform`` at P with ``P/Centerline`` (BasisCurves,
``points`` and ``extent`` time-sampled, the extent by usd-core's rule for curves: the points padded
by half the largest width; ``purpose = "guide"`` where a Surface is written) and, unless disabled,
``P/Surface`` (Mesh: static triangle topology and ``primvars:st``, ``doubleSided`` where the tube
has no caps; ``points``, ``normals`` and ``extent`` time-sampled). Samples are written straight
into the layer, which no stage has open after the prims are defined (``Sdf.Layer.SetTimeSample`` of
``Vt.Vec3fArray`` values: about 1 us less per sample than through an open stage). The layer is
saved under a hidden temporary name beside the target (:func:`warp_tube.scene.files.temp_path`) and
renamed over it only by :meth:`StageWriter.close`, so an existing file is replaced only by a complete
one. A run that stops early calls :meth:`StageWriter.keep_partial` instead: the frames written so far
go to ``OUT.partial.usdc`` beside the target (:func:`warp_tube.scene.files.partial_path`), and the
target is left as it was.
"""

from __future__ import annotations

import ctypes
import os

import numpy as np

from ..scene.curves import curves_extent, half_width
from ..scene.spec import Scene
from ..scene.files import USD_EXTENSIONS, free_partial_path, output_path, partial_path, temp_path

__all__ = ["StageWriter", "check_output_path", "points_extent", "vec3f_array"]

DIRECT_COPY_MIN = 2048
"""Arrays of at least this many vec3 go to USD by one memory copy (:func:`vec3f_array`); smaller
ones through ``Vt.Vec3fArray.FromNumpy``, which costs less per call."""

_direct_copy_ok = None
_from_numpy = None  # Vt.Vec3fArray.FromNumpy, looked up once (pxr is imported on first use)


def _direct_copy(values: np.ndarray):
    """A new ``Vt.Vec3fArray`` holding ``values`` (contiguous float32 (n, 3)), filled by one
    ``memmove`` into its own storage (``FromNumpy`` converts element by element, ~8x slower)."""
    from pxr import Vt

    out = Vt.Vec3fArray(len(values))
    view = np.asarray(out)  # the buffer of the new, unshared array: its storage, not a copy
    ctypes.memmove(view.__array_interface__["data"][0], values.ctypes.data, values.nbytes)
    return out


def vec3f_array(values):
    """``values`` ((n, 3), any float dtype) as a ``Vt.Vec3fArray``.

    Large arrays are copied straight into a freshly allocated (so unshared) array's storage; the
    first call checks that this path reproduces its input exactly and otherwise keeps to
    ``Vt.Vec3fArray.FromNumpy`` for the whole process.
    """
    global _direct_copy_ok, _from_numpy
    if _from_numpy is None:
        from pxr import Vt

        _from_numpy = Vt.Vec3fArray.FromNumpy
    if not (type(values) is np.ndarray and values.dtype == np.float32 and values.flags.c_contiguous):
        values = np.ascontiguousarray(values, dtype=np.float32)
    if len(values) < DIRECT_COPY_MIN or values.ndim != 2 or values.shape[1] != 3:
        return _from_numpy(values)
    if _direct_copy_ok is None:
        probe = np.arange(3 * DIRECT_COPY_MIN, dtype=np.float32).reshape(-1, 3)
        try:
            _direct_copy_ok = bool(np.array_equal(np.asarray(_direct_copy(probe)), probe))
        except Exception:
            _direct_copy_ok = False
    if not _direct_copy_ok:
        return _from_numpy(values)
    return _direct_copy(values)


def points_extent(points: np.ndarray) -> np.ndarray:
    """Exact axis-aligned bounds of ``points`` ((n, 3), n >= 1): ``[[min x, y, z], [max x, y, z]]``.

    Reduces over rows of 64 points at a time, so NumPy's inner loops run 192 elements long
    instead of 3 (``points.min(axis=0)`` on an (n, 3) array is ~20x slower).
    """
    n = len(points)
    if n < 4096:  # few enough that two plain reductions cost less than the blocked ones
        return np.stack([points.min(axis=0), points.max(axis=0)])
    rows = n - n % 64
    lo, hi = [], []
    if rows:
        block = points[:rows].reshape(-1, 192)
        lo.append(block.min(axis=0).reshape(64, 3).min(axis=0))
        hi.append(block.max(axis=0).reshape(64, 3).max(axis=0))
    if rows < n:
        lo.append(points[rows:].min(axis=0))
        hi.append(points[rows:].max(axis=0))
    return np.stack([np.min(lo, axis=0), np.max(hi, axis=0)])


def check_output_path(path, inputs=()) -> str:
    """Validate an output stage path before any simulation (extension .usdc/.usda/.usd, writable
    folder, not one of ``inputs``); returns it absolute. See :func:`warp_tube.scene.files.output_path`."""
    return output_path(path, USD_EXTENSIONS, inputs=inputs)


class StageWriter:
    """Writes one output stage, frame by frame.

    Args:
        path: final output path (.usdc, .usda or .usd).
        scene: the scene (stage metadata, tube prim paths, curve counts).
        surfaces: per tube prim, ``None`` or an object with ``face_vertex_counts``,
            ``face_vertex_indices`` (NumPy int arrays) and ``st`` ((K, 2) float), ``st_interpolation``.
        start_time_code: the stage's startTimeCode (default the scene's; a run continued from a
            later frame starts its stage there).
        inputs: files the output must not be (the scene and its layers).

    Raises:
        SceneError: the path cannot be written or is one of ``inputs``.
    """

    def __init__(self, path: str, scene: Scene, surfaces=None, *, start_time_code=None, inputs=()):
        from pxr import Sdf

        self.path = check_output_path(path, inputs)
        self.tmp = temp_path(self.path)
        self.partial = partial_path(self.path)
        info = scene.stage
        start = info.start_time_code if start_time_code is None else float(start_time_code)
        self.info = info
        self.mpu = info.meters_per_unit
        # The layer is ours and no stage listens to it: prims and time samples go straight into it
        # as specs (through a stage, each prim defined paid for the change processing of all the
        # prims before it: 20,000 tube prims took 28 s), and usd-core skips the notices that
        # cost about 1 us per sample.
        self.closed = False
        self.layer = Sdf.Layer.CreateNew(self.tmp)  # (the temporary file exists from here)
        try:
            self._define(scene, surfaces, start)
        except BaseException:  # (an interrupt included: no temporary file is left behind)
            self.abort()
            raise

    def _define(self, scene: Scene, surfaces, start: float) -> None:
        """The layer's metadata and prims, and the writer's bookkeeping (see the constructor)."""
        from pxr import Sdf, UsdGeom, Vt

        layer, info = self.layer, self.info
        layer.startTimeCode = layer.endTimeCode = start
        layer.timeCodesPerSecond = info.time_codes_per_second
        layer.framesPerSecond = info.frames_per_second
        layer.pseudoRoot.SetInfo(UsdGeom.Tokens.metersPerUnit, info.meters_per_unit)
        layer.pseudoRoot.SetInfo(UsdGeom.Tokens.upAxis, UsdGeom.Tokens.z if info.up_axis.upper() == "Z" else UsdGeom.Tokens.y)
        T = Sdf.ValueTypeNames
        surfaces = surfaces or [None] * len(scene.tubes)
        self.tubes, halves = [], []
        with Sdf.ChangeBlock():
            for spec, surf in zip(scene.tubes, surfaces):
                path_p = Sdf.Path(spec.path)
                for anc in path_p.GetPrefixes():
                    if not layer.GetPrimAtPath(anc):
                        _define(layer, anc, "Xform")
                cl = _define(layer, path_p.AppendChild("Centerline"), "BasisCurves")
                _attr(cl, "type", T.Token, UsdGeom.Tokens.linear, uniform=True)
                _attr(cl, "curveVertexCounts", T.IntArray, Vt.IntArray([int(c) for c in spec.curve_counts]))
                diameters = (2.0 * spec.radius / self.mpu).astype(np.float32)
                widths = _attr(cl, "widths", T.FloatArray, Vt.FloatArray.FromNumpy(diameters))
                widths.SetInfo(UsdGeom.Tokens.interpolation, UsdGeom.Tokens.vertex)
                entry = {"centerline": _attr(cl, "points", T.Point3fArray).path, "extent": _attr(cl, "extent", T.Float3Array).path,
                         "surface": None}  # fmt: skip
                halves.append(half_width(diameters))
                if surf is not None:
                    # beside its Surface the curve is a guide: renderers (Karma, Cycles) would draw
                    # it as a second, round tube of the same diameter through the mesh's flat faces
                    _attr(cl, "purpose", T.Token, UsdGeom.Tokens.guide, uniform=True)
                    mesh = _define(layer, path_p.AppendChild("Surface"), "Mesh")
                    _attr(mesh, "subdivisionScheme", T.Token, UsdGeom.Tokens.none, uniform=True)
                    if not _closed(surf):
                        # an open tube is seen from inside through its ends: without this, usdview
                        # (Storm) culls the inner wall and Blender turns on backface culling
                        _attr(mesh, "doubleSided", T.Bool, True, uniform=True)
                    _attr(mesh, "faceVertexCounts", T.IntArray,
                          Vt.IntArray.FromNumpy(np.ascontiguousarray(surf.face_vertex_counts, dtype=np.int32)))  # fmt: skip
                    _attr(mesh, "faceVertexIndices", T.IntArray,
                          Vt.IntArray.FromNumpy(np.ascontiguousarray(surf.face_vertex_indices, dtype=np.int32)))  # fmt: skip
                    points = _attr(mesh, "points", T.Point3fArray)
                    normals = _attr(mesh, "normals", T.Normal3fArray)
                    normals.SetInfo(UsdGeom.Tokens.interpolation, UsdGeom.Tokens.vertex)
                    extent = _attr(mesh, "extent", T.Float3Array)
                    st = _attr(mesh, "primvars:st", T.TexCoord2fArray, Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(surf.st, dtype=np.float32)))
                    st.SetInfo(UsdGeom.Tokens.interpolation, getattr(surf, "st_interpolation", UsdGeom.Tokens.vertex))
                    if getattr(surf, "st_indices", None) is not None:
                        _attr(mesh, "primvars:st:indices", T.IntArray, Vt.IntArray.FromNumpy(np.ascontiguousarray(surf.st_indices, dtype=np.int32)))
                    entry["surface"] = (points.path, normals.path, extent.path)
                self.tubes.append(entry)
        layer.defaultPrim = Sdf.Path(scene.tubes[0].path).GetPrefixes()[0].name
        self.half_widths = np.array(halves, dtype=np.float32)
        self.frames_written = 0
        self.first_time = None
        self.last_time = start

    def write_frame(self, time_code: float, centerlines, surfaces=None, prims=None, centerline_extents=None):
        """Add one frame.

        Args:
            time_code: the frame's time code.
            centerlines: per tube prim, points in stage units, shape (P, 3).
            surfaces: per tube prim, ``(points, normals)`` or ``(points, normals, extent)`` in stage
                units, shapes (V, 3) and (2, 3) (the points' ``[min, max]`` corners; found here when
                not given), or None.
            prims: the indices of the tube prims this frame holds, ``centerlines`` and ``surfaces``
                given for these only (default: all); a prim left out has no sample at this time
                (a grid's failed variant, whose frames end before the others').
            centerline_extents: per tube prim (of ``prims``), its Centerline's extent (2, 3),
                :func:`~warp_tube.scene.curves.curves_extent` of its points and
                :attr:`half_widths`; found here when not given.
        """
        put = self.layer.SetTimeSample  # no stage listens to the layer: nothing to batch notices for
        t = float(time_code)
        entries = self.tubes if prims is None else [self.tubes[i] for i in prims]
        if centerline_extents is None:
            centerline_extents = self._centerline_extents(centerlines, prims)
        for k, entry in enumerate(entries):
            put(entry["centerline"], t, vec3f_array(centerlines[k]))
            put(entry["extent"], t, vec3f_array(centerline_extents[k]))
            if entry["surface"] is not None and surfaces is not None and surfaces[k] is not None:
                p_path, n_path, e_path = entry["surface"]
                sp, sn, *ext = surfaces[k]
                sp = np.ascontiguousarray(sp, dtype=np.float32)
                ext = points_extent(sp) if not ext else np.asarray(ext[0], dtype=np.float32)
                put(p_path, t, vec3f_array(sp))
                put(n_path, t, vec3f_array(sn))
                put(e_path, t, vec3f_array(ext))
        self.frames_written += 1
        if self.first_time is None:
            self.first_time = time_code
        self.last_time = time_code

    def _centerline_extents(self, centerlines, prims=None) -> np.ndarray:
        """The Centerlines' extents (prims, 2, 3) of one frame, the prims' points reduced together."""
        halves = self.half_widths if prims is None else self.half_widths[list(prims)]
        points = [np.asarray(c, dtype=np.float32) for c in centerlines]
        starts = np.cumsum([0] + [len(c) for c in points[:-1]])
        joined = np.concatenate(points)
        bounds = np.stack([np.minimum.reduceat(joined, starts), np.maximum.reduceat(joined, starts)], axis=1)
        return curves_extent(bounds, halves[:, None])  # (each prim's bounds: the same as its points')

    def close(self) -> str:
        """Finish the stage: endTimeCode = last frame written, save, rename over the target.

        Returns:
            The output path.
        """
        if self.closed:
            return self.path
        self._save_to(self.path)
        return self.path

    def keep_partial(self) -> str | None:
        """Save the frames written so far to :attr:`partial` (``OUT.partial.usdc``), a valid stage
        ending at the last of them, and leave the target alone.

        Returns:
            The partial file's path, or None when no frame was written (nothing is kept then).
        """
        if self.closed:
            return None
        if self.frames_written == 0:
            self.abort()
            return None
        self.partial = free_partial_path(self.path)  # an existing file of that name is left alone
        self._save_to(self.partial)
        return self.partial

    def _save_to(self, final: str):
        try:
            self.layer.endTimeCode = self.last_time
            try:
                self.layer.Save()
            except Exception as e:  # usd-core's errors (pxr.Tf.ErrorException) name no errno
                raise save_error(final, e) from None
            self.closed = True
            del self.layer
            os.replace(self.tmp, final)
        except BaseException:
            self.abort()
            raise

    def abort(self):
        """Drop the stage being written without touching the target."""
        if not self.closed:
            self.closed = True
            if hasattr(self, "layer"):
                del self.layer  # out of usd-core's registry, so a new writer may create the same file
        try:
            os.remove(self.tmp)
        except FileNotFoundError:
            pass


#: operating-system errors usd-core reports in words when a save fails, most specific first
_SAVE_ERRNOS = ("ENOSPC", "EDQUOT", "EROFS", "EACCES", "EFBIG", "EIO")


def save_error(path: str, error: Exception) -> OSError:
    """An ``OSError`` for a failed ``Sdf.Layer.Save`` of ``path``: the operating system's reason
    where usd-core's message names one (no space left, read-only file system, ...), else "usd-core
    could not save the stage". Plain, so it crosses process boundaries (usd-core's own exception
    does not pickle)."""
    import errno

    text = str(error)
    for name in _SAVE_ERRNOS:
        code = getattr(errno, name, None)
        if code is not None and os.strerror(code) in text:
            return OSError(code, os.strerror(code), path)
    return OSError(errno.EIO, "usd-core could not save the stage", path)


def _closed(surf) -> bool:
    """Whether a surface topology is closed (its tubes capped): ``surf.caps`` where it says so,
    else no edge of its triangles belongs to one face only."""
    caps = getattr(surf, "caps", None)
    if caps is not None:
        return bool(caps)
    tris = np.asarray(surf.face_vertex_indices, dtype=np.int64).reshape(-1, 3)
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(len(counts)) and not (counts == 1).any()


def _define(layer, path, type_name: str):
    """A ``def`` prim spec of ``type_name`` at ``path`` in ``layer`` (its parents must exist)."""
    from pxr import Sdf

    return Sdf.PrimSpec(layer.GetPrimAtPath(path.GetParentPath()), path.name, Sdf.SpecifierDef, type_name)  # ("/": the pseudo-root)


def _attr(prim_spec, name: str, type_name, value=None, uniform: bool = False):
    """A schema attribute spec (not custom) on ``prim_spec``, with a default ``value`` unless None."""
    from pxr import Sdf

    spec = Sdf.AttributeSpec(prim_spec, name, type_name, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    if value is not None:
        spec.default = value
    return spec
