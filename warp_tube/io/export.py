"""Export the Surface meshes of an output stage to OBJ or glTF-binary files, one per frame.

Reads a stage written per DESIGN.md's output contract (tube prims holding a ``Surface`` Mesh with
time-sampled ``points``) and writes, through trimesh, one file per frame (or one frame):

- OBJ: all Surface meshes of the stage merged into one mesh, in stage units and axes (OBJ has
  none of its own), with vertex normals where the stage has them.
- GLB: one node per Surface mesh (named after its prim path), converted to glTF's metres and
  Y-up (``metersPerUnit`` and ``upAxis`` of the stage).

Texture coordinates are not exported (the stage's ``st`` are face-varying; both formats would need
the seam vertices split).

Where files go: with ``out`` a folder (or no ``out``), files ``<stage name>.<frame>.<fmt>``; with no
``out`` that folder is ``<stage name>_<fmt>/`` beside the stage (one new folder, never the current
folder), or, for one ``frame``, the file goes beside the stage. No file is replaced unless
``overwrite`` is given (``--force``): the names are checked before anything is written, and each
file is written under a temporary name and renamed when complete.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..scene.spec import SceneError

__all__ = ["export", "open_output_stage", "surface_meshes", "surface_frames", "surface_at"]

FORMATS = ("obj", "glb")


def open_output_stage(usd_path):
    """Open an output stage; :class:`~warp_tube.scene.spec.SceneError` naming the file and what is
    wrong if it cannot (:func:`warp_tube.scene.usd.open_stage`)."""
    from ..scene.usd import open_stage

    return open_stage(str(usd_path))


def surface_meshes(stage, usd_path="") -> list:
    """The ``Surface`` Mesh prims of a stage, in stage order; SceneError if there is none."""
    from pxr import Usd, UsdGeom

    meshes = [
        UsdGeom.Mesh(p) for p in stage.Traverse(Usd.TraverseInstanceProxies()) if p.GetName() == "Surface" and p.IsA(UsdGeom.Mesh)
    ]
    if not meshes:
        raise SceneError(
            f"{usd_path}: no Surface mesh (expected a Mesh named 'Surface' under each tube prim, as "
            f"`warp-tube run` writes without --no-surface)"
        )
    return meshes


def surface_frames(meshes) -> list[float]:
    """Sorted time codes at which any Surface's ``points`` is sampled (empty: static only)."""
    times = set()
    for mesh in meshes:
        times.update(mesh.GetPointsAttr().GetTimeSamples())
    return sorted(times)


def _triangles(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Fan-triangulate polygons given by faceVertexCounts / faceVertexIndices, int (F, 3)."""
    if np.all(counts == 3):
        return indices.reshape(-1, 3)
    tris = []
    start = 0
    for c in counts:
        for k in range(1, c - 1):
            tris.append((indices[start], indices[start + k], indices[start + k + 1]))
        start += c
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3)


def surface_at(mesh, time) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """World-space vertices (V, 3) [stage units], triangles (F, 3) and vertex normals (V, 3) or None
    of one Surface mesh at a time code."""
    from pxr import UsdGeom

    path = mesh.GetPath()
    points = mesh.GetPointsAttr().Get(time)
    counts = mesh.GetFaceVertexCountsAttr().Get()
    indices = mesh.GetFaceVertexIndicesAttr().Get()
    if points is None or counts is None or indices is None:
        raise SceneError(f"{path}: Surface mesh without points or topology at time {time}")
    verts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    xform = np.asarray(UsdGeom.XformCache(time).GetLocalToWorldTransform(mesh.GetPrim()), dtype=np.float64)
    verts = verts @ xform[:3, :3] + xform[3, :3]
    normals = mesh.GetNormalsAttr().Get(time)
    if normals is not None and len(normals) == len(verts):
        normals = np.asarray(normals, dtype=np.float64) @ np.linalg.inv(xform[:3, :3]).T
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    else:
        normals = None
    return verts, _triangles(np.asarray(counts), np.asarray(indices)), normals


def _frame_name(time: float) -> str:
    return f"{int(round(time)):04d}" if float(time).is_integer() else f"{time:09.3f}".replace(".", "_")


def export(usd_path, fmt: str = "obj", out=None, frame=None, overwrite: bool = False) -> list[Path]:
    """Write the Surface meshes of an output stage, one file per frame.

    Args:
        usd_path: output stage (``.usdc``/``.usda``) written by ``warp-tube run``.
        fmt: "obj" or "glb".
        out: folder for the files (created if needed), named ``<stage stem>.<frame>.<fmt>`` (frame
            as a 4-digit time code); default ``<stage stem>_<fmt>/`` beside the stage. With ``frame``
            given (or a stage of one frame), ``out`` may also be the file name itself (ending in
            ``.obj``/``.glb``); with ``frame`` and no ``out`` the file goes beside the stage.
        frame: the time code to export; default: every time sample.
        overwrite: replace existing files (otherwise an existing file is an error, before any
            file is written).

    Returns:
        The paths written, in frame order.

    Raises:
        SceneError: missing or unreadable file, no Surface mesh, an unknown format, a frame the
            stage has no sample for, an ``out`` naming one file for several frames, or files that
            exist (without ``overwrite``).
    """
    import trimesh
    from pxr import UsdGeom

    from ..scene.files import refuse_existing, same_file, write_atomically

    if fmt not in FORMATS:
        raise SceneError(f"unknown export format {fmt!r}; expected one of {FORMATS}")
    usd_path = Path(usd_path)
    stage = open_output_stage(usd_path)
    meshes = surface_meshes(stage, usd_path)
    times = surface_frames(meshes)
    if frame is not None:
        if times and not any(abs(t - frame) < 1e-6 for t in times):
            raise SceneError(f"{usd_path}: no Surface sample at frame {frame} (frames {times[0]:g}..{times[-1]:g})")
        times = [float(frame)]
    elif not times:
        times = [stage.GetStartTimeCode()]

    names_file = out is not None and Path(out).suffix.lower() in tuple(f".{f}" for f in FORMATS)
    if names_file and Path(out).suffix.lower() != f".{fmt}":
        raise SceneError(f"{out}: extension {Path(out).suffix}: expected .{fmt} for --format {fmt}")
    if names_file and len(times) > 1:
        raise SceneError(
            f"{out}: names one file, but {usd_path} has {len(times)} frames: pass --frame T, or give a folder"
        )
    if names_file:
        paths = [Path(out)]
    else:
        if out is not None:
            folder = Path(out)
        elif frame is not None:
            folder = usd_path.parent
        else:
            folder = usd_path.parent / f"{usd_path.stem}_{fmt}"
        if folder.exists() and not folder.is_dir():
            if same_file(folder, usd_path):
                raise SceneError(f"{folder}: is the input stage: -o takes a folder, or one .{fmt} file with --frame")
            raise SceneError(f"{folder}: exists and is not a folder: -o takes a folder, or one .{fmt} file with --frame")
        paths = [folder / f"{usd_path.stem}.{_frame_name(t)}.{fmt}" for t in times]
    for p in paths:
        if same_file(p, usd_path):
            raise SceneError(f"{p}: is the input stage: refusing to write over it")
    if not overwrite:
        refuse_existing(paths)
    if not paths[0].parent.is_dir():
        if not paths[0].parent.parent.is_dir():
            raise SceneError(f"{paths[0].parent}: cannot create the folder: {paths[0].parent.parent} does not exist")
        paths[0].parent.mkdir(exist_ok=True)

    to_gltf = np.eye(3)
    scale = 1.0
    if fmt == "glb":
        scale = UsdGeom.GetStageMetersPerUnit(stage)
        if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z:
            to_gltf = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # rows: x->x, y->-z, z->y

    written = []
    for time, path in zip(times, paths):
        parts = []
        for mesh in meshes:
            verts, faces, normals = surface_at(mesh, time)
            verts = scale * verts @ to_gltf
            normals = None if normals is None else normals @ to_gltf
            parts.append((str(mesh.GetPath()), trimesh.Trimesh(verts, faces, vertex_normals=normals, process=False)))
        if fmt == "obj":
            merged = trimesh.util.concatenate([m for _, m in parts]) if len(parts) > 1 else parts[0][1]
            write_atomically(path, lambda tmp: merged.export(tmp, file_type="obj", include_normals=True))
        else:
            scene = trimesh.Scene()
            for name, m in parts:
                scene.add_geometry(m, node_name=name, geom_name=name)
            write_atomically(path, lambda tmp: scene.export(tmp, file_type="glb"))
        written.append(path)
    return written
