"""Export the Surface meshes of an output stage to OBJ or glTF-binary files, one per frame.

Reads a stage written per DESIGN.md's output contract (tube prims holding a ``Surface`` Mesh with
time-sampled ``points``) and writes, through trimesh, one file per frame (or one frame):

- OBJ: one object (``o`` and ``g``, named after its prim path) per Surface mesh, in stage units
  and axes (OBJ has none of its own; a comment at the top of each file names them), with vertex
  normals where the stage has them.
- GLB: one node per Surface mesh (named after its prim path), converted to glTF's metres and
  Y-up (``metersPerUnit`` and ``upAxis`` of the stage), with a plain grey material, double-sided
  for an open Surface (no caps, or ``doubleSided`` in the stage) so viewers draw its inner wall.

Texture coordinates are not exported (the stage's ``st`` are face-varying; both formats would need
the seam vertices split).

Where files go: with ``out`` a folder (or no ``out``), files ``<stage name>.<frame>.<fmt>``; with no
``out`` that folder is ``<stage name>_<fmt>/`` beside the stage (one new folder, never the current
folder), or, for one ``frame``, the file goes beside the stage. No file is replaced unless
``overwrite`` is given (``--force``): the names are checked before anything is written.

All or nothing: every file is written under a hidden temporary name beside its own and the files
are renamed into place only when all of them are complete, so an existing file is only ever
replaced by a complete one. An export that fails (a full disk, a read-only folder, an interrupt)
leaves nothing of itself: its temporary files and a folder it created are removed, and files it had
already put in place are put back as they were.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

from ..scene.spec import SceneError

__all__ = ["export", "open_output_stage", "surface_meshes", "surface_frames", "surface_at", "checked_points"]

FORMATS = ("obj", "glb")


def open_output_stage(usd_path):
    """Open an output stage; :class:`~warp_tube.scene.spec.SceneError` naming the file and what is
    wrong if it cannot (:func:`warp_tube.scene.usd.open_stage`)."""
    from ..scene.usd import open_stage

    return open_stage(str(usd_path))


def surface_meshes(stage, usd_path="") -> list:
    """The ``Surface`` Mesh prims of a stage, in stage order; SceneError if there is none, or if the
    stage's ``metersPerUnit`` is not a finite positive number."""
    from pxr import Usd, UsdGeom

    meshes = [
        UsdGeom.Mesh(p) for p in stage.Traverse(Usd.TraverseInstanceProxies()) if p.GetName() == "Surface" and p.IsA(UsdGeom.Mesh)
    ]
    if not meshes:
        raise SceneError(
            f"{usd_path}: no Surface mesh (expected a Mesh named 'Surface' under each tube prim, as "
            f"`warp-tube run` writes without --no-surface)"
        )
    mpu = UsdGeom.GetStageMetersPerUnit(stage)
    if not (np.isfinite(mpu) and mpu > 0.0):
        raise SceneError(f"{usd_path}: metersPerUnit {mpu:g}: expected a finite number > 0")
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


def _stage_file(prim, usd_path) -> str:
    """The file to name in a message about ``prim``: ``usd_path`` as given, else its stage's root layer."""
    return os.fspath(usd_path) if usd_path else prim.GetStage().GetRootLayer().realPath


def checked_points(points, prim, time, usd_path=None, what="points") -> np.ndarray:
    """``points`` of ``prim`` at ``time`` as float64 (P, 3), refused unless there are some and all
    are finite (SceneError naming the file, the prim and the time)."""
    where = f"{_stage_file(prim, usd_path)}: {prim.GetPath()} at time {_time_text(time)}"
    if points is None or len(points) == 0:
        raise SceneError(f"{where}: no {what}")
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
    if len(bad):
        p = pts[bad[0]]
        raise SceneError(f"{where}: {len(bad):,} of its {len(pts):,} {what} {'is' if len(bad) == 1 else 'are'} not finite "
                         f"(point {bad[0]}: {p[0]:g}, {p[1]:g}, {p[2]:g})")  # fmt: skip
    return pts


def _checked_topology(counts, indices, n_points: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    """faceVertexCounts and faceVertexIndices as int64 arrays, refused unless every face has 3 or more
    corners, the counts sum to the indices, and every index is a point (0 to ``n_points`` - 1)."""
    counts, indices = np.asarray(counts, dtype=np.int64).reshape(-1), np.asarray(indices, dtype=np.int64).reshape(-1)
    if len(counts) == 0:
        raise SceneError(f"{where}: no faces (faceVertexCounts is empty)")
    if counts.min() < 3:
        k = int(np.argmin(counts))
        raise SceneError(f"{where}: faceVertexCounts[{k}] = {counts[k]}: a face needs at least 3 vertices")
    if counts.sum() != len(indices):
        raise SceneError(f"{where}: faceVertexCounts sum to {counts.sum():,}, but faceVertexIndices holds {len(indices):,} indices")
    outside = np.flatnonzero((indices < 0) | (indices >= n_points))
    if len(outside):
        k = outside[0]
        raise SceneError(f"{where}: faceVertexIndices[{k}] = {indices[k]}: expected 0 to {n_points - 1} "
                         f"(the mesh has {n_points:,} points; {len(outside):,} {'index' if len(outside) == 1 else 'indices'} outside)")  # fmt: skip
    return counts, indices


def surface_at(mesh, time, usd_path=None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """World-space vertices (V, 3) [stage units], triangles (F, 3) and vertex normals (V, 3) or None
    of one Surface mesh at a time code. The triangles are wound counter-clockwise seen from their
    front (glTF's and OBJ's rule, USD's ``rightHanded``): reversed where the mesh is ``leftHanded``
    or its transform mirrors (a negative determinant), as a USD renderer turns them.

    Raises:
        SceneError: naming the file (``usd_path``, default the stage's), the prim and the time, where
            the mesh has no points, a point or its transform is not finite, a face has fewer than 3
            corners, faceVertexCounts do not sum to the indices, or an index is not one of the points.
    """
    from pxr import UsdGeom

    prim = mesh.GetPrim()
    where = f"{_stage_file(prim, usd_path)}: {prim.GetPath()} at time {_time_text(time)}"
    points = mesh.GetPointsAttr().Get(time)
    counts = mesh.GetFaceVertexCountsAttr().Get(time)
    indices = mesh.GetFaceVertexIndicesAttr().Get(time)
    if points is None or counts is None or indices is None:
        raise SceneError(f"{where}: Surface mesh without points or topology")
    verts = checked_points(points, prim, time, usd_path)
    counts, indices = _checked_topology(counts, indices, len(verts), where)
    xform = np.asarray(UsdGeom.XformCache(time).GetLocalToWorldTransform(prim), dtype=np.float64)
    verts = verts @ xform[:3, :3] + xform[3, :3]
    if not np.isfinite(verts).all():
        raise SceneError(f"{where}: its transform makes points not finite (a transform of NaN, infinity or overflow)")
    normals = mesh.GetNormalsAttr().Get(time)
    if normals is not None and len(normals) == len(verts) and np.linalg.det(xform[:3, :3]) != 0.0:
        normals = np.asarray(normals, dtype=np.float64) @ np.linalg.inv(xform[:3, :3]).T
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
        if not np.isfinite(normals).all():
            normals = None  # (normals are optional: viewers compute their own)
    else:
        normals = None
    triangles = _triangles(counts, indices)
    left_handed = mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded
    if left_handed != (np.linalg.det(xform[:3, :3]) < 0.0):
        triangles = triangles[:, ::-1]
    return verts, triangles, normals



def _time_text(t: float) -> str:
    """A time code as written in a message: ``3``, ``12.5``, ``1000000`` (no exponent)."""
    return np.format_float_positional(float(t), trim="-")


def _frames_text(times) -> str:
    """The sampled time codes in words: ``frames 100..106 every 2`` (one step throughout), ``frames
    0..9`` (step 1), ``frame 3``, or the list where the steps differ."""
    steps = np.unique(np.round(np.diff(times), 6))
    if len(times) == 1:
        return f"frame {_time_text(times[0])}"
    if len(steps) == 1:
        step = f" every {_time_text(steps[0])}" if steps[0] != 1 else ""
        return f"frames {_time_text(times[0])}..{_time_text(times[-1])}{step}"
    shown = ", ".join(_time_text(t) for t in times[:8])
    return f"frames {shown}" + (f", ... {_time_text(times[-1])}" if len(times) > 8 else "")


def _frame_names(times) -> list[str]:
    """File-name frame numbers of a sequence: integer time codes zero-padded to one width (at least
    4, more where a frame needs it: 9999 and 10000 give ``09999`` and ``10000``), so the names sort
    in frame order; others as ``00012_500``. Negative time codes keep their sign (``-0003``): they
    sort before frame 0, but among themselves in reverse (``-0001`` before ``-0003``)."""
    ints = [int(round(t)) for t in times if float(t).is_integer()]
    width = max([4] + [len(str(abs(i))) for i in ints])
    return [
        (f"-{-int(round(t)):0{width}d}" if t < 0 else f"{int(round(t)):0{width}d}")
        if float(t).is_integer() else f"{t:09.3f}".replace(".", "_")
        for t in times
    ]


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
        SceneError: missing or unreadable file, no Surface mesh, a Surface mesh that is not sound at
            a frame (see :func:`surface_at`), an unusable ``metersPerUnit``, an empty ``out``, an unknown format, a frame the
            stage has no sample for, an ``out`` naming one file for several frames, files that
            exist (without ``overwrite``), or a folder that cannot be created or a file that cannot
            be written (then nothing of the export is left, see the module's docstring).
    """
    from pxr import UsdGeom

    from ..scene.files import refuse_existing, same_file

    if fmt not in FORMATS:
        raise SceneError(f"unknown export format {fmt!r}; expected one of {FORMATS}")
    if out is not None and not os.fspath(out):
        raise SceneError(f"an empty output name: expected a folder, or one {' or '.join(f'.{f}' for f in FORMATS)} file with --frame")
    usd_path = Path(usd_path)
    stage = open_output_stage(usd_path)
    meshes = surface_meshes(stage, usd_path)
    times = surface_frames(meshes)
    if frame is not None:
        if times and not any(abs(t - frame) < 1e-6 for t in times):
            raise SceneError(f"{usd_path}: no Surface sample at frame {_time_text(frame)} ({_frames_text(times)})")
        times = [float(frame)]
    elif not times:
        times = [stage.GetStartTimeCode()]

    names_file = out is not None and Path(out).suffix.lower() in tuple(f".{f}" for f in FORMATS)
    if frame is not None and out is not None and Path(out).suffix and not names_file and not Path(out).is_dir():
        # (one frame to a name with another extension, .gltf say: meant as a file, not a folder)
        raise SceneError(f"{out}: extension {Path(out).suffix}: export writes {' or '.join(f'.{f}' for f in FORMATS)} "
                         "(.glb: glTF binary); name the file so, or give a folder")  # fmt: skip
    if names_file and Path(out).suffix.lower() != f".{fmt}":
        raise SceneError(f"{out}: extension {Path(out).suffix}: expected .{fmt} for --format {fmt}")
    if names_file and len(times) > 1:
        raise SceneError(
            f"{out}: names one file, but {usd_path} has {len(times)} frames: pass --frame T, or give a folder"
        )
    if names_file:
        paths = [Path(out)]
        if not paths[0].resolve().parent.is_dir():  # (a file named in a folder that is not there: as run refuses it)
            raise SceneError(f"{out}: cannot write the file: folder {paths[0].resolve().parent} does not exist")
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
        paths = [folder / f"{usd_path.stem}.{name}.{fmt}" for name in _frame_names(times)]
    for p in paths:
        if same_file(p, usd_path):
            raise SceneError(f"{p}: is the input stage: refusing to write over it")
    if not names_file and frame is None:
        _warn_of_other_frames(paths, usd_path.stem, fmt)
    if not overwrite:
        refuse_existing(paths)
    for p in paths:
        if p.is_dir():
            raise SceneError(f"{p}: is a folder: not replaced by the exported file")
    if not paths[0].parent.is_dir() and not paths[0].parent.parent.is_dir():
        raise SceneError(f"{paths[0].parent}: cannot create the folder: {paths[0].parent.parent} does not exist")

    to_gltf = np.eye(3)
    scale = 1.0
    mpu = UsdGeom.GetStageMetersPerUnit(stage)
    z_up = UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    if fmt == "glb":
        scale = mpu
        if z_up:
            to_gltf = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # rows: x->x, y->-z, z->y
        render = partial(_render_glb, meshes, usd_path, [_open_surface(m, times[0]) for m in meshes], scale, to_gltf)
    else:
        name = " ".join(usd_path.name.split())  # one comment line, whatever the file's name holds
        render = partial(_render_obj, meshes, usd_path, name, mpu, "Z" if z_up else "Y")

    # (each frame's meshes are checked as they are read: a frame that is not sound stops the export,
    # and _write_all leaves nothing of it)
    _write_all(paths[0].parent, [(path, partial(render, t)) for t, path in zip(times, paths)])
    return paths


def _warn_of_other_frames(paths: list[Path], stem: str, fmt: str) -> None:
    """Warn where the folder holds frames of this name not in this export (an earlier, longer
    export's): a sequence importer would read them with the new ones. They are left as they are."""
    import logging
    import re

    folder = paths[0].parent
    if not folder.is_dir():
        return
    pattern = re.compile(rf"{re.escape(stem)}\.-?\d+(_\d+)?\.{fmt}")
    ours = {p.name for p in paths}
    others = sorted(n for n in os.listdir(folder) if pattern.fullmatch(n) and n not in ours)
    if others:
        logging.getLogger(__name__).warning(
            "%s: holds %d other frame file(s) of this name (%s%s), not from this export: an importer "
            "of the sequence would read them too; they are left as they are",
            folder, len(others), others[0], f" ... {others[-1]}" if len(others) > 1 else "",
        )


def _open_surface(mesh, time) -> bool:
    """Whether a Surface is seen from inside: ``doubleSided`` in the stage, or an edge of its
    triangles (at ``time``) that belongs to one face only (an uncapped tube)."""
    if mesh.GetDoubleSidedAttr().Get():
        return True
    counts, indices = mesh.GetFaceVertexCountsAttr().Get(time), mesh.GetFaceVertexIndicesAttr().Get(time)
    if counts is None or indices is None or not len(indices):
        return False
    tris = _triangles(np.asarray(counts), np.asarray(indices))
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    return bool((np.unique(edges, axis=0, return_counts=True)[1] == 1).any())


def _render_glb(meshes, usd_path, open_surfaces, scale: float, to_gltf: np.ndarray, time) -> bytes:
    """The bytes of one GLB file: every Surface mesh at a time code, one node each."""
    import trimesh
    from trimesh.visual.material import PBRMaterial

    scene = trimesh.Scene()
    for mesh, two_sided in zip(meshes, open_surfaces):
        verts, faces, normals = surface_at(mesh, time, usd_path)
        verts = scale * verts @ to_gltf
        normals = None if normals is None else normals @ to_gltf
        m = trimesh.Trimesh(verts, faces, vertex_normals=normals, process=False)
        # glTF's defaults would make a material fully metallic: a plain grey dielectric instead
        material = PBRMaterial(name="tube", baseColorFactor=[0.8, 0.8, 0.8, 1.0], metallicFactor=0.0,
                               roughnessFactor=0.6, doubleSided=bool(two_sided))  # fmt: skip
        m.visual = trimesh.visual.TextureVisuals(material=material)
        name = str(mesh.GetPath())
        scene.add_geometry(m, node_name=name, geom_name=name)
    return scene.export(file_type="glb", tree_postprocessor=_generator)


def _generator(tree: dict) -> None:
    """Name warp_tube as the glTF file's generator (``asset.generator``)."""
    from ..version import __version__

    tree.setdefault("asset", {})["generator"] = f"warp_tube {__version__}"


def _render_obj(meshes, usd_path, stage_name: str, mpu: float, up: str, time) -> bytes:
    """The bytes of one OBJ file: every Surface mesh at a time code, one object each (``o`` for
    Blender, ``g`` for Houdini and Maya), in stage units and axes, which a comment names."""
    out = [
        f"# {stage_name}, time code {time:g}: Surface meshes written by warp_tube\n"
        f"# units: the stage's, 1 unit = {mpu:g} m (metersPerUnit); up axis: {up} (the stage's)\n"
    ]
    v_base = n_base = 0
    for mesh in meshes:
        verts, faces, normals = surface_at(mesh, time, usd_path)
        name = str(mesh.GetPath())
        out.append(f"o {name}\ng {name}\n")
        out.append(("v %.9g %.9g %.9g\n" * len(verts)) % tuple(verts.ravel().tolist()))
        f = faces.astype(np.int64) + 1 + v_base
        if normals is not None:
            out.append(("vn %.9g %.9g %.9g\n" * len(normals)) % tuple(normals.ravel().tolist()))
            fn = faces.astype(np.int64) + 1 + n_base
            corners = np.stack([f, fn], axis=2).reshape(len(f), 6)
            out.append(("f %d//%d %d//%d %d//%d\n" * len(f)) % tuple(corners.ravel().tolist()))
            n_base += len(normals)
        else:
            out.append(("f %d %d %d\n" * len(f)) % tuple(f.ravel().tolist()))
        v_base += len(verts)
    return "".join(out).encode("utf-8")


def _write_all(folder: Path, files: list[tuple[Path, Callable[[], bytes]]]) -> None:
    """Write files in ``folder`` all or nothing.

    ``folder`` is created if it does not exist (its parent must). Each ``(path, render)`` is written
    under a hidden temporary name beside ``path`` (``render()`` gives its bytes); when all are
    written they are renamed into place. On any exception, interrupts included, nothing of this
    call is left: temporary files are removed, files renamed into place are taken back (an earlier
    file there is put back), and ``folder`` is removed if this call created it.

    Raises:
        SceneError: the folder cannot be created or a file cannot be written (path and OS reason).
    """
    made = _make_folder(folder)
    temps = []
    try:
        for path, render in files:
            temps.append((_write_temporary(path, render()), path))
        _put_in_place(temps)
    except BaseException:
        for tmp, _ in temps:
            _remove(tmp)
        if made:
            _remove_folder(folder)
        raise


def _reason(e: OSError) -> str:
    """The OS's words for an error (``Read-only file system``, ``No space left on device``)."""
    return e.strerror or str(e)


def _make_folder(folder: Path) -> bool:
    """Create ``folder`` unless it is there; whether this call created it."""
    if folder.is_dir():
        return False
    try:
        folder.mkdir()
    except FileExistsError:
        return False
    except OSError as e:
        raise SceneError(f"{folder}: cannot create the folder ({_reason(e)})") from None
    return True


def _write_temporary(path: Path, data: bytes) -> str:
    """Write ``data`` to a new file under :func:`~warp_tube.scene.files.temp_path` of ``path``,
    flushed to the disk; its name. Nothing is left if it fails."""
    from ..scene.files import temp_path

    tmp = temp_path(path)
    created = False
    try:
        with open(tmp, "xb") as f:
            created = True
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except BaseException as e:
        if created:
            _remove(tmp)
        if isinstance(e, OSError):
            raise SceneError(f"{path}: cannot write ({_reason(e)})") from None
        raise
    return tmp


def _backup_path(path: Path) -> str:
    """Hidden name beside ``path`` that keeps an earlier file there while it is replaced."""
    return str(path.with_name(f".{path.stem}.old-{os.getpid()}{path.suffix}"))


def _keep(path: Path) -> str | None:
    """A hard link to the file at ``path`` under :func:`_backup_path`; None where there is no
    file, or no link can be made (the file is then replaced without a way back)."""
    if not os.path.lexists(path):
        return None
    backup = _backup_path(path)
    try:
        os.link(path, backup, follow_symlinks=False)
    except OSError:
        return None
    return backup


def _put_in_place(temps: list[tuple[str, Path]]) -> None:
    """Rename each temporary file to its path; if one fails, those renamed are taken back (an
    earlier file put back where it was kept)."""
    backups, done = {}, []
    try:
        for tmp, path in temps:
            existed = os.path.lexists(path)
            backups[path] = _keep(path)
            done.append((path, existed))
            try:
                os.replace(tmp, path)
            except OSError as e:
                raise SceneError(f"{path}: cannot write ({_reason(e)})") from None
    except BaseException:
        for path, existed in reversed(done):
            _take_back(path, existed, backups[path])
        raise
    finally:
        for backup in backups.values():
            if backup is not None:
                _remove(backup)


def _take_back(path: Path, existed: bool, backup: str | None) -> None:
    """Undo the renaming of a new file to ``path``: the kept earlier file back, or no file."""
    try:
        if backup is not None:
            os.replace(backup, path)
        elif not existed:
            os.remove(path)
    except OSError:
        pass


def _remove(path) -> None:
    """Remove a file if it is there and can be removed."""
    try:
        os.remove(path)
    except OSError:
        pass


def _remove_folder(folder: Path) -> None:
    """Remove a folder if it is empty."""
    try:
        folder.rmdir()
    except OSError:
        pass
