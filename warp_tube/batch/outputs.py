"""Writing a batch's results: variant files, a grid stage or NumPy arrays, and the summary.

Layouts (``DIR`` is the batch's output folder):

- ``files``: ``DIR/variant_00000.usdc`` ... in batch order, each written by the same
  :class:`~warp_tube.io.writer.StageWriter` as ``warp-tube run`` (same layout, same samples); a
  variant that failed keeps the frames finished before the failure in
  ``DIR/variant_00007.partial.usdc``.
- ``grid``: ``DIR/grid.usda``, one stage with the variants side by side, ``/Grid/variant_00000``
  (translated on a square grid in the ground plane, its rest shape centred in its cell, the cells
  as wide as the largest rest shape and diameter and twice the largest displacement, so that no
  two variants meet) holding the variant's prims under their own paths; it sublayers
  ``DIR/grid/chunk_00000.usdc`` ..., one layer per chunk (written in parallel). A variant that
  failed keeps the frames finished before the failure in its cell, its prim's customData
  ``warptube:partial`` true, ``warptube:framesWritten`` their number and
  ``warptube:maxDisplacement`` the largest displacement in them [stage units].
- ``arrays``: ``DIR/centerline.npy``, float32, (variants, frames, points, 3) [stage units],
  memory-mappable (``np.load(..., mmap_mode="r")``); with ``--surface-arrays`` also
  ``DIR/surface.npy``, (variants, frames, vertices, 3); a variant with fewer points or vertices
  than the largest is padded with NaN, and frames a failed variant did not reach are NaN.
  ``DIR/arrays.json`` says what the axes are, and gives the stage's units, up axis and rates;
  with the surface, ``DIR/surface_faces.npy`` holds its triangles.

Always ``DIR/summary.csv``: one row per variant (batch order) with its parameters, status,
largest displacement, final tip, energy and output.

Writers run in other processes (a pool), reading a chunk's arrays from memory-mapped files, so
the simulation goes on while USD writes; every file appears under its name only when complete.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import os
from dataclasses import dataclass

import numpy as np

from ..scene.spec import Scene
from .rows import Rows

__all__ = ["OutputSpec", "WriteTask", "write", "check_batch_fits", "surface_topology", "surface_faces", "grid_offset", "grid_offsets", "output_spec", "write_summary", "summary_lines", "SUMMARY_FIELDS",
           "prepare_arrays", "finish_arrays", "write_grid_root", "LAYOUTS"]  # fmt: skip

LAYOUTS = ("files", "grid", "arrays")
#: summary.csv columns after the variant's parameters
SUMMARY_FIELDS = ("status", "max_displacement_m", "tip_x", "tip_y", "tip_z", "kinetic_energy_J", "work_J", "frames",
                  "frames_simulated", "integrator", "substeps", "output", "reason", "contact_frame", "max_stretch")  # fmt: skip


@dataclass(frozen=True)
class OutputSpec:
    """Where and how a batch writes.

    Attributes:
        layout: "files", "grid" or "arrays".
        out_dir: the batch folder.
        surface: write the Surface (files, grid) or ``surface.npy`` (arrays).
        time_codes: time code of each written frame.
        variants: number of variants in the batch.
        points: the most centerline points of a variant (arrays: the points axis).
        vertices: the most surface vertices of a variant (arrays: the vertices axis).
        work_dir: the batch's working folder (partial arrays, grid chunk layers).
        grid_cell: the largest rest extent and diameter of a variant [stage units] (the grid's
            cells are this and twice the largest displacement, known when the batch ends).
        grid_columns: variants per grid row.
        up_axis: "Y" or "Z" (the grid lies across it).
    """

    layout: str
    out_dir: str
    surface: bool
    time_codes: tuple
    variants: int
    points: int = 0
    vertices: int = 0
    work_dir: str = ""
    grid_cell: float = 1.0
    grid_columns: int = 1
    up_axis: str = "Y"


def check_batch_fits(spec: OutputSpec, counts: list, chunk: int) -> None:
    """Refuse, before anything is written, a batch whose outputs (and, for USD outputs, the two
    chunks' frame buffers kept in its working folder while they are written) would not fit in
    the free space of its folder.

    Args:
        spec: the batch's outputs.
        counts: per variant its centerline points and surface vertices.
        chunk: variants per chunk.

    Raises:
        SceneError: naming the sizes and the free space.
    """
    from ..runtime import memory
    from ..scene.spec import SceneError

    F = len(spec.time_codes)
    if spec.layout == "arrays":
        per_frame = 12 * (spec.points + (spec.vertices if spec.surface else 0))  # [bytes] a variant-frame, padded
        size = spec.variants * F * per_frame
    else:
        sizes = sorted((12 * (p + 2 * v) for p, v in counts), reverse=True)  # centerline, surface points and normals
        size = F * sum(sizes)
        size += 2 * F * sum(sizes[:chunk])  # (the largest chunk's buffers, twice)
        per_frame = sizes[0]
    folder = os.path.abspath(spec.out_dir)
    while not os.path.isdir(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)
    disk = memory.available_disk(folder)
    if disk is not None and size > disk:
        raise SceneError(
            f"{spec.out_dir}: the batch would write about {size / 1e9:.3g} GB ({spec.variants:,} variant(s) x {F:,} frames x up "
            f"to {per_frame:,} bytes{'' if spec.layout == 'arrays' else ', and the chunks being written'}), more than the "
            f"{disk / 1e9:.3g} GB free in {folder}; free some space, or write fewer frames (--every K, --frames N)"
        )  # fmt: skip


@dataclass(frozen=True)
class WriteTask:
    """Write some variants of one chunk.

    Attributes:
        spec: the batch's output spec.
        chunk: the chunk's id.
        variants: the variants (batch index, name, scene), in chunk order.
        positions: each variant's place in the chunk's arrays (the world).
        rows: each variant's summary fields from the simulation (status, frames written...),
            :class:`~warp_tube.batch.rows.Rows`.
        arrays: the chunk's arrays by name, or the paths of ``.npy`` files holding them.
    """

    spec: OutputSpec
    chunk: int
    variants: tuple
    positions: tuple
    rows: Rows
    arrays: dict


def _open(arrays: dict) -> dict:
    return {k: (np.load(v, mmap_mode="r") if isinstance(v, str) else v) for k, v in arrays.items()}


def write(task: WriteTask) -> list[str]:
    """Run a write task; returns each variant's output (relative to the batch folder, '' if none)."""
    arrays = _open(task.arrays)
    layout = task.spec.layout
    if layout == "files":
        return _write_files(task, arrays)
    if layout == "arrays":
        return _write_arrays(task, arrays)
    return _write_grid(task, arrays)


_topologies: dict = {}
#: the last tube prims asked for, by the identity of their arrays (a batch's variants share them):
#: key -> (the arrays, kept so that their ids stay theirs, and the topology)
_by_identity: dict = {}


def surface_topology(t):
    """The surface topology of tube prim ``t`` (a TubeSpec), as ``SurfaceBuilder`` builds it for a
    run (rest points for ``st``, cap radii from the mean spoke length at the end hubs)."""
    arrays = (t.points, t.radius, t.spoke_lengths, t.curve_counts)
    key = (*map(id, arrays), t.params.spokes, t.params.caps)
    hit = _by_identity.get(key)
    if hit is not None and all(a is b for a, b in zip(hit[0], arrays)):
        return hit[1]
    topology = _surface_topology(t)
    if len(_by_identity) > 256:
        _by_identity.clear()
    _by_identity[key] = (arrays, topology)
    return topology


def _surface_topology(t):
    from ..surface.topology import tube_topology

    S = t.params.spokes
    lengths = t.spoke_lengths if t.spoke_lengths is not None else np.repeat(t.radius[:, None], S, axis=1)
    key = (t.points.tobytes(), lengths.tobytes(), S, t.params.caps, t.curve_counts.tobytes())
    if key not in _topologies:
        if len(_topologies) > 4096:
            _topologies.clear()
        starts = np.concatenate([[0], np.cumsum(t.curve_counts)])
        _topologies[key] = tube_topology(starts, S, lengths, t.params.caps, t.points)
    return _topologies[key]


def _ranges(scene: Scene, surface: bool):
    """Per tube prim, its slice of a variant's centerline points and (surface) of its vertices."""
    out, s, v = [], 0, 0
    for t in scene.tubes:
        n = len(t.points)
        nv = surface_topology(t).vertex_count if surface else 0
        out.append((slice(s, s + n), slice(v, v + nv)))
        s, v = s + n, v + nv
    return out


def _frame_parts(ranges, arrays: dict, f: int, p: int, surface: bool):
    """One frame of one variant as StageWriter.write_frame takes it: per prim centerline points,
    and per prim (points, normals, extent) or None; ``ranges`` from :func:`_ranges`."""
    cl = [arrays["centerline"][f, p, c] for c, _ in ranges]
    if not surface:
        return cl, None
    return cl, [(arrays["points"][f, p, v], arrays["normals"][f, p, v], arrays["extent"][f, p, k]) for k, (_, v) in enumerate(ranges)]


def _centerline_extents(ranges, arrays: dict, frames: int, p: int, halves) -> np.ndarray:
    """The Centerline extents of one variant's prims in its first ``frames`` frames, each prim's
    over all of them at once: (frames, prims, 2, 3); ``halves``: the prims' half widths."""
    from ..scene.curves import curves_extent

    out = np.empty((frames, len(ranges), 2, 3), dtype=np.float32)
    for k, (c, _) in enumerate(ranges):
        out[:, k] = curves_extent(arrays["centerline"][:frames, p, c], halves[k])
    return out


def _write_files(task: WriteTask, arrays: dict) -> list[str]:
    from ..io.writer import StageWriter

    spec, out = task.spec, []
    for (index, name, scene), p, row in zip(task.variants, task.positions, task.rows):
        rel = f"{name}.usdc" if row["status"] == "ok" else f"{name}.partial.usdc"
        topo = [surface_topology(t) for t in scene.tubes] if spec.surface else None
        w = StageWriter(os.path.join(spec.out_dir, rel), scene, topo)
        try:
            ranges = _ranges(scene, spec.surface)
            extents = _centerline_extents(ranges, arrays, row["frames"], p, w.half_widths)
            for f in range(row["frames"]):
                cl, parts = _frame_parts(ranges, arrays, f, p, spec.surface)
                w.write_frame(spec.time_codes[f], cl, parts, centerline_extents=extents[f])
            w.close()
        except BaseException:
            w.abort()
            raise
        out.append(rel)
    return out


def prepare_arrays(spec: OutputSpec, resume: bool) -> None:
    """Create (or, resuming, keep) the partial arrays in the working folder, full size."""
    from numpy.lib.format import open_memmap

    F = len(spec.time_codes)
    for name, n, on in (("centerline", spec.points, True), ("surface", spec.vertices, spec.surface)):
        path = os.path.join(spec.work_dir, f"{name}.npy")
        if on and not (resume and os.path.exists(path)):
            open_memmap(path, mode="w+", dtype=np.float32, shape=(spec.variants, F, n, 3)).flush()  # sparse until written


#: bytes of one block written to an arrays layout's file at once (variants in a row)
ARRAY_BLOCK_BYTES = 64 << 20


def _runs(indices: list, positions: list, limit: int) -> list[tuple[int, int, int]]:
    """``(first batch index, first position, count)`` of each run of variants that follow one
    another both in the batch and in the chunk, at most ``limit`` long."""
    out = []
    for i, p in zip(indices, positions):
        if out and out[-1][2] < limit and i == out[-1][0] + out[-1][2] and p == out[-1][1] + out[-1][2]:
            out[-1] = (out[-1][0], out[-1][1], out[-1][2] + 1)
        else:
            out.append((i, p, 1))
    return out


def _write_arrays(task: WriteTask, arrays: dict) -> list[str]:
    """Each variant's frames into the batch's ``.npy`` files at its row, variants that follow one
    another in a block of their own (one copy out of the frame-major chunk arrays and one
    ``os.pwrite``, both without the GIL: few Python steps per block, so that the writer threads
    do not queue for the GIL behind the simulating thread)."""
    spec, F = task.spec, len(task.spec.time_codes)
    targets = [("centerline", "centerline", spec.points)]
    if spec.surface:
        targets.append(("surface", "points", spec.vertices))
    indices = [index for index, _, _ in task.variants]
    for name, source, n in targets:
        path = os.path.join(spec.work_dir, f"{name}.npy")
        offset = np.load(path, mmap_mode="r").offset
        row_bytes = F * n * 3 * 4
        fd = os.open(path, os.O_WRONLY)
        try:
            runs = _runs(indices, list(task.positions), max(1, ARRAY_BLOCK_BYTES // row_bytes))
            block = np.empty((max(k for _, _, k in runs), F, n, 3), dtype=np.float32)
            for index, p, k in runs:
                data = arrays[source][:, p : p + k]  # (F, k, points, 3)
                out = block[:k]
                out[:, :, : data.shape[2]] = data.transpose(1, 0, 2, 3)
                out[:, :, data.shape[2] :] = np.nan
                written = os.pwrite(fd, out, offset + index * row_bytes)  # the buffer itself: no copy under the GIL
                if written != out.nbytes:
                    raise OSError(f"{path}: short write ({written} of {out.nbytes} bytes)")
        finally:
            os.close(fd)
    return ["centerline.npy" + (" surface.npy" if spec.surface else "")] * len(task.variants)


def finish_arrays(spec: OutputSpec, order: list[int], names: list[str], point_counts: list[int],
                  vertex_counts: list[int], stage_info=None, scenes=None) -> None:  # fmt: skip
    """Move the complete arrays into the batch folder and describe them in ``arrays.json`` (with
    the stage's units, up axis and rates from ``stage_info``, a
    :class:`~warp_tube.scene.spec.StageInfo`); with the surface, write the triangles of the
    variants' surfaces (``scenes``, batch order) in ``surface_faces.npy`` (:func:`surface_faces`)."""
    meta = {
        "centerline.npy": "float32 (variants, frames, points, 3): centerline points [stage units], prims and curves "
                          "in scene order; NaN past a variant's points and in frames a failed variant did not reach",
        "variants": names, "points": point_counts, "time_codes": list(spec.time_codes),
    }  # fmt: skip
    if stage_info is not None:  # what the arrays' numbers mean: stage units in metres, the up axis, time codes in seconds
        meta.update(metersPerUnit=stage_info.meters_per_unit, upAxis=stage_info.up_axis.upper(),
                    timeCodesPerSecond=stage_info.time_codes_per_second, framesPerSecond=stage_info.frames_per_second)  # fmt: skip
    faces = None
    if spec.surface:
        meta["surface.npy"] = ("float32 (variants, frames, vertices, 3): surface vertices [stage units], hub-major as in "
                               "the USD Surface; NaN past a variant's vertices")  # fmt: skip
        meta["vertices"] = vertex_counts
        if scenes is not None:
            faces, topology, counts = surface_faces(scenes)
            meta["surface_faces.npy"] = ("int32 (topologies, faces, 3): the surface's triangles, as indices into a variant's "
                                         "vertices in surface.npy; variant k's are surface_faces[topology[k], :faces[topology[k]]] "
                                         "(-1 past them)")  # fmt: skip
            meta["faces"], meta["topology"] = counts, topology
    # one key a line, each value from the C encoder (indent= encodes in Python: slow for long lists)
    text = "{\n" + ",\n".join(f" {json.dumps(k)}: {json.dumps(v)}" for k, v in meta.items()) + "\n}\n"
    if faces is not None:
        tmp = os.path.join(spec.work_dir, "surface_faces.npy")
        np.save(tmp, faces)
        os.replace(tmp, os.path.join(spec.out_dir, "surface_faces.npy"))
    _atomic_text(os.path.join(spec.out_dir, "arrays.json"), text)
    for name, on in (("centerline", True), ("surface", spec.surface)):
        if on:
            os.replace(os.path.join(spec.work_dir, f"{name}.npy"), os.path.join(spec.out_dir, f"{name}.npy"))


def surface_faces(scenes) -> tuple[np.ndarray, list[int], list[int]]:
    """The triangles of the variants' surfaces, as ``surface.npy`` holds their vertices (every tube
    prim's, in scene order): ``(faces, topology, counts)``, ``faces`` int32 (topologies, most
    faces, 3) with one row per distinct triangulation (variants of other point counts, spokes or
    caps have their own), padded with -1; ``topology`` each variant's row; ``counts`` each row's
    triangles."""
    memo: dict = {}  # the prims' topologies by identity (a batch's variants share them) -> row
    rows: dict = {}  # a triangulation's bytes -> row
    tables, topology = [], []
    last = None  # (the scene before and its row: a batch of plain variants repeats one scene)
    for scene in scenes:
        if last is not None and scene is last[0]:
            topology.append(last[1])
            continue
        topos = tuple(surface_topology(t) for t in scene.tubes)
        key = tuple(map(id, topos))
        hit = memo.get(key)
        if hit is None:
            offsets = np.concatenate([[0], np.cumsum([t.vertex_count for t in topos])])
            tri = np.concatenate([t.faces + int(o) for t, o in zip(topos, offsets)]).astype(np.int32)
            row = rows.setdefault(tri.tobytes(), len(tables))
            if row == len(tables):
                tables.append(tri)
            hit = memo[key] = (topos, row)  # (the topologies kept: their ids stay theirs)
        topology.append(hit[1])
        last = (scene, hit[1])
    counts = [len(t) for t in tables]
    faces = np.full((len(tables), max(counts, default=0), 3), -1, dtype=np.int32)
    for k, t in enumerate(tables):
        faces[k, : len(t)] = t
    return faces, topology, counts


def grid_offset(spec: OutputSpec, index: int, cell: float, centre=(0.0, 0.0, 0.0)) -> tuple[float, float, float]:
    """The translation of variant ``index`` in the grid [stage units]: rows and columns ``cell``
    apart across the up axis, the variant's rest centre ``centre`` moved to its cell's centre in
    that plane (its height kept)."""
    row, col = divmod(index, spec.grid_columns)
    a, b = col * cell, row * cell
    x, y, z = (float(c) for c in centre)
    return (a - x, 0.0, b - z) if spec.up_axis.upper() == "Y" else (a - x, b - y, 0.0)


def _write_grid(task: WriteTask, arrays: dict) -> list[str]:
    from ..io.writer import StageWriter

    spec = task.spec
    # a failed variant's finished frames are kept, as the files layout keeps them in a partial file
    keep = [(v, p, r) for v, p, r in zip(task.variants, task.positions, task.rows) if r["status"] == "ok" or r["frames"] > 0]
    rel = f"grid/chunk_{task.chunk:05d}.usdc"
    if not keep:
        return [""] * len(task.variants)
    tubes, topo = [], []
    for (index, name, scene), _, _ in keep:
        for t in scene.tubes:
            tubes.append(dataclasses.replace(t, path=f"/Grid/{name}{t.path}", pin_track=None))
            topo.append(surface_topology(t))
    first = keep[0][0][2]
    grid_scene = Scene(tubes=tuple(tubes), stage=first.stage, source=first.source)
    w = StageWriter(os.path.join(spec.out_dir, rel), grid_scene, topo if spec.surface else None)
    try:
        first_prim, prims = 0, []  # per variant the indices of its tube prims in the writer
        for (index, name, scene), p, row in keep:
            prims.append(list(range(first_prim, first_prim + len(scene.tubes))))
            first_prim += len(scene.tubes)
            if row["status"] != "ok":
                # its summary's max_displacement_m counts the frame that failed: the grid's
                # spacing takes the frames kept (nested: usd-core reads "warptube:partial" as a key path)
                n = sum(t.points.shape[0] for t in scene.tubes)
                cl = np.asarray(arrays["centerline"][: row["frames"], p, :n], dtype=np.float64)
                moved = float(np.nanmax(np.linalg.norm(cl - cl[:1], axis=-1))) if cl.size else 0.0
                info = {"partial": True, "framesWritten": int(row["frames"]), "maxDisplacement": moved}
                w.layer.GetPrimAtPath(f"/Grid/{name}").SetInfo("customData", {"warptube": info})
        ranges = [_ranges(scene, spec.surface) for (_, _, scene), _, _ in keep]
        extents = [_centerline_extents(r, arrays, row["frames"], p, w.half_widths[own])
                   for (_, p, row), r, own in zip(keep, ranges, prims)]  # fmt: skip
        for f in range(len(spec.time_codes)):
            cls, parts, held, ext = [], [] if spec.surface else None, [], []
            for ((index, name, scene), p, row), r, own, e in zip(keep, ranges, prims, extents):
                if f >= row["frames"]:
                    continue  # past a failed variant's last finished frame
                c, s = _frame_parts(r, arrays, f, p, spec.surface)
                cls += c
                held += own
                ext.append(e[f])
                if spec.surface:
                    parts += s
            if held:
                w.write_frame(spec.time_codes[f], cls, parts, prims=held, centerline_extents=np.concatenate(ext))
        w.close()
    except BaseException:
        w.abort()
        raise
    kept = {v[0] for v, _, _ in keep}
    return [("grid.usda" if v[0] in kept else "") for v in task.variants]


def write_grid_root(spec: OutputSpec, stage_info, chunk_layers: list[str], names: list[str], offsets: list) -> None:
    """``DIR/grid.usda``: the stage's metadata, the chunks' layers as sublayers, the variants'
    order under ``/Grid`` (``names``, batch order) and their translations (``offsets``, per name;
    here, since the spacing that keeps them apart is known only once every variant has moved)."""
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    from ..io.writer import save_error

    path = os.path.join(spec.out_dir, "grid.usda")
    tmp = os.path.join(spec.out_dir, f".grid.partial-{os.getpid()}.usda")
    layer = Sdf.Layer.CreateNew(tmp)
    st = Usd.Stage.Open(layer)
    UsdGeom.SetStageMetersPerUnit(st, stage_info.meters_per_unit)
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.z if stage_info.up_axis.upper() == "Z" else UsdGeom.Tokens.y)
    st.SetTimeCodesPerSecond(stage_info.time_codes_per_second)
    st.SetFramesPerSecond(stage_info.frames_per_second)
    st.SetStartTimeCode(stage_info.start_time_code)
    st.SetEndTimeCode(spec.time_codes[-1])
    grid = UsdGeom.Xform.Define(st, "/Grid").GetPrim()
    st.SetDefaultPrim(grid)
    del st
    grid_spec = layer.GetPrimAtPath("/Grid")
    with Sdf.ChangeBlock():
        for name, offset in zip(names, offsets):
            prim = Sdf.PrimSpec(grid_spec, name, Sdf.SpecifierOver)
            op = Sdf.AttributeSpec(prim, "xformOp:translate", Sdf.ValueTypeNames.Double3)
            op.default = Gf.Vec3d(*offset)
            order = Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform)
            order.default = Vt.TokenArray(["xformOp:translate"])
    grid_spec.nameChildrenOrder = list(names)
    layer.subLayerPaths = list(chunk_layers)
    try:
        layer.Save()
    except Exception as e:  # (usd-core's exception names no errno, and does not pickle)
        del layer
        if os.path.exists(tmp):
            os.remove(tmp)
        raise save_error(path, e) from None
    del layer
    os.replace(tmp, path)


def _atomic_text(path: str, text: str) -> None:
    tmp = os.path.join(os.path.dirname(path), f".{os.path.basename(path)}.partial-{os.getpid()}")
    with open(tmp, "w", encoding="utf-8", newline="") as f:
        f.write(text)
    os.replace(tmp, path)


_AS_STR = {float, int, str, bool}


def _fmt(v) -> str:
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    return str(v)


def write_summary(path: str, parameter_columns: list[str], lines: str) -> None:
    """``summary.csv``: its header, then ``lines`` (:func:`summary_lines` of every variant in
    batch order)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(["variant", "name", *parameter_columns, *SUMMARY_FIELDS])
    buf.write(lines)
    _atomic_text(path, buf.getvalue())


def summary_lines(variants, columns: dict) -> str:
    """The summary's lines of ``variants`` (``columns``: each field's values in their order)."""
    buf = io.StringIO()
    out = csv.writer(buf, lineterminator="\n")
    n = len(variants)
    nan3 = [math.nan] * 3
    tip_axis = {"tip_x": 0, "tip_y": 1, "tip_z": 2}
    tips = [t or nan3 for t in columns.get("tip", [None] * n)]
    fields = [[t[tip_axis[k]] for t in tips] if k in tip_axis else columns.get(k) or [""] * n for k in SUMMARY_FIELDS]
    # csv writes str(value): for floats repr (NaN as "nan"), ints, strings and bools as _fmt does;
    # only a column holding something else (None) goes through _fmt
    fields = [c if set(map(type, c)) <= _AS_STR else [_fmt(x) for x in c] for c in fields]
    cells = list(zip(*(v.cells for v in variants))) if variants and variants[0].cells else []
    chosen = list(zip(*(v.selection for v in variants))) if variants and variants[0].selection else []
    out.writerows(zip([v.index for v in variants], [v.name for v in variants], *cells, *chosen, *fields))  # (a column at a time)
    return buf.getvalue()


def output_spec(variants, counts: list, layout, out_dir, work_dir, surface, time_codes) -> OutputSpec:
    """The batch's outputs (``counts``: per variant its centerline points and surface vertices)."""
    vs = variants.variants
    points = max(p for p, _ in counts)
    vertices = max(n for _, n in counts) if surface else 0
    first = vs[0].scene.stage
    cell, columns = 1.0, 1
    if layout == "grid":
        mpu = first.meters_per_unit
        size = max(float(np.ptp(np.concatenate([t.points for t in v.scene.tubes]), axis=0).max())
                   + 2.0 * max(float(t.radius.max()) for t in v.scene.tubes) for v in vs)  # fmt: skip
        cell = size / mpu
        columns = math.ceil(math.sqrt(len(vs)))
    return OutputSpec(layout=layout, out_dir=out_dir, surface=surface, time_codes=time_codes, variants=len(vs),
                      points=points, vertices=vertices, work_dir=work_dir, grid_cell=cell, grid_columns=columns,
                      up_axis=first.up_axis)  # fmt: skip


def grid_offsets(spec: OutputSpec, vs, shown: list, cols: dict, records: dict, mpu: float) -> list:
    """The grid's translation of each variant of ``shown`` (batch indices) [stage units]: its rest
    shape centred in a cell of the largest rest extent and diameter, a quarter of that for a gap,
    and twice the largest displacement of any variant shown, so that neighbours cannot meet
    however they moved."""
    # (a chunk recorded by an earlier version keeps no displacements: a tube's full reach, its
    # length either side, stands for them)
    ok = [cols["max_displacement_m"][i] for i in shown if cols["status"][i] == "ok"]
    moved = [float(d) if d != "" else spec.grid_cell * mpu for d in ok]
    for rec in records.values():  # failed variants: the largest displacement in their frames kept
        rows = rec["rows"]
        failed = [vs[i].name for i, s, o in zip(rows["index"], rows["status"], rows["output"]) if s != "ok" and o]
        if failed and rec["layer"]:
            from pxr import Sdf

            layer = Sdf.Layer.FindOrOpen(os.path.join(spec.out_dir, rec["layer"]))
            moved += [float(layer.GetPrimAtPath(f"/Grid/{n}").customData["warptube"]["maxDisplacement"]) * mpu for n in failed]
    reach = max([m for m in moved if math.isfinite(m)], default=0.0) / mpu
    cell = 1.25 * spec.grid_cell + 2.0 * reach
    from .plan import by_identity

    memo: dict = {}  # rest centres by the identity of the tubes' points (a batch's variants share them)
    out = []
    for i in shown:
        tubes = vs[i].scene.tubes
        centre = by_identity(memo, tuple(t.points for t in tubes), (), _rest_centre, tubes) / mpu
        out.append(grid_offset(spec, i, cell, centre))
    return out


def _rest_centre(tubes):
    """The centre of the tubes' rest points' bounding box [m]."""
    pts = np.concatenate([t.points for t in tubes])
    return (pts.min(axis=0) + pts.max(axis=0)) / 2.0
