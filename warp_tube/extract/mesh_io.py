"""Tube meshes for centerline extraction: loading, cleaning, boundary loops, capping and the flat
faces that seal cut ends.

Meshes come from STL/PLY/OBJ files (through trimesh) or from the points and faces of a USD
``Mesh`` prim carrying ``warptube:extract = true``. Everything that is wrong with the input becomes
a :class:`~warp_tube.scene.spec.SceneError` naming the source and what was found.
"""

from __future__ import annotations

import io
import logging
import os
import re
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components

from ..scene.files import not_a_file
from ..scene.spec import SceneError
from .components import largest_component, surface_labels, weld
from .hollow import outer_wall
from .loops import BoundaryLoop, boundary_loops, cap_loops
from .wording import counted

__all__ = [
    "load_mesh",
    "mesh_from_arrays",
    "load_usd_mesh",
    "clean_mesh",
    "unit_face_normals",
    "BoundaryLoop",
    "boundary_loops",
    "cap_loops",
    "FlatCut",
    "flat_cuts",
]

log = logging.getLogger(__name__)

MIN_EDGE = 10.0 * trimesh.tol.merge
"""Least median edge length of a mesh after scaling [units of the result]: trimesh merges vertices
closer than ``trimesh.tol.merge`` (1e-8), which collapses the faces of a smaller mesh."""
#: the largest mesh file taken, across after scaling [m]: a larger one has a wrong --scale
MAX_SIZE = 1e4
_SEAL_FACES = 3  # least faces of a seal: a cut across a tube of five sides or more has three at least
_TREADS = 0.25  # a flat patch with parallel faces of this x its area just off its plane is a terrace
_FORMATS = {"stl": "STL", "stl_ascii": "STL", "ply": "PLY", "obj": "OBJ", "off": "OFF", "glb": "glTF", "gltf": "glTF"}


def _scale3(scale) -> np.ndarray:
    s = np.asarray(scale, dtype=np.float64).reshape(-1)
    if s.size == 1:
        s = np.repeat(s, 3)
    if s.size != 3 or not (np.isfinite(s).all() and (s > 0).all()):
        raise SceneError(f"scale {np.asarray(scale).tolist()}: expected one or three positive finite factors")
    return s


def clean_mesh(mesh: trimesh.Trimesh, source: str, scale=(1.0, 1.0, 1.0), max_size: float | None = None) -> trimesh.Trimesh:
    """Checked, scaled, welded copy of ``mesh``, reduced to its largest connected component.

    Args:
        mesh: input triangle mesh [mesh units].
        source: name used in messages (file or prim path).
        scale: factor per axis (or one for all) applied to the vertices, e.g. CT voxel sizes.
        max_size: the largest extent taken after scaling [units of the result], or None.

    Returns:
        A new mesh with merged duplicate vertices and without degenerate or duplicate faces.

    Raises:
        SceneError: not a triangle mesh, empty, vertices without 3 coordinates, NaN or infinite
            coordinates, face indices out of range, or no face with area left.
    """
    s = _scale3(scale)
    if not isinstance(mesh, trimesh.Trimesh):
        raise SceneError(f"{source}: holds a {type(mesh).__name__}, expected a triangle mesh")
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    if len(v) == 0 or len(f) == 0:
        raise SceneError(f"{source}: empty mesh ({counted(len(v), 'vertex')}, {counted(len(f), 'face')}): "
                         "expected a tube surface")
    if v.ndim != 2 or v.shape[1] != 3:
        got = f"{v.shape[1]} coordinates" if v.ndim == 2 else f"vertices of shape {v.shape}"
        raise SceneError(f"{source}: vertices with {got}: vertices must have 3 coordinates (x, y, z)")
    if f.ndim != 2 or f.shape[1] != 3:
        raise SceneError(f"{source}: faces shape {f.shape}: expected triangles (F, 3)")
    if f.min() < 0 or f.max() >= len(v):
        raise SceneError(f"{source}: face indices span {f.min()}..{f.max()}: expected 0..{len(v) - 1}")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise SceneError(
            f"{source}: {counted(int(bad.sum()), 'vertex')} with NaN or infinite coordinates "
            f"(first: vertex {int(np.argmax(bad))}): expected finite coordinates"
        )
    with np.errstate(over="ignore", invalid="ignore"):  # (an absurd --scale: named below, not a NumPy warning)
        scaled = v * s
    _check_size(scaled, f, s, source, max_size)
    out = trimesh.Trimesh(scaled, f, process=False)
    out.merge_vertices()
    weld(out)
    # Faces whose corners merged into fewer than three vertices go; a sliver of three distinct
    # collinear corners (marching cubes leaves many) stays: removing it would open a crack where
    # its edges join its neighbours', and a closed mesh would be closed no more.
    g = out.faces
    out.update_faces((g[:, 0] != g[:, 1]) & (g[:, 1] != g[:, 2]) & (g[:, 0] != g[:, 2]))
    out.update_faces(out.unique_faces())
    out.remove_unreferenced_vertices()
    if len(out.faces) == 0:
        raise SceneError(f"{source}: every face has zero area: expected a tube surface")
    labels = surface_labels(out)
    wall, _ = outer_wall(out, source, labels)
    if wall is not out:  # (a hollow tube's outer wall: its own pieces)
        out = wall
        labels = surface_labels(out)
    if labels.max() > 0:
        keep = largest_component(out, labels, source)
        out.update_faces(labels == keep)
        out.remove_unreferenced_vertices()
    if len(out.faces) < 8:
        raise SceneError(f"{source}: only {counted(len(out.faces), 'face')}: expected a tube surface")
    return out


def unit_face_normals(mesh: trimesh.Trimesh) -> np.ndarray:
    """Each face's unit normal (the winding's), (F, 3); 0 for a face of no area. Whatever the
    mesh's size: trimesh's ``face_normals`` gives 0 for faces whose cross product is below its
    absolute tolerance (1e-12: every face of a tube a few micrometres across, in metres)."""
    tri = np.asarray(mesh.triangles, dtype=np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1)
    return np.divide(n, length[:, None], out=np.zeros_like(n), where=length[:, None] > 0.0)


def _check_size(v: np.ndarray, f: np.ndarray, s: np.ndarray, source: str, max_size: float | None = None) -> None:
    """Refuse a mesh whose median edge, after scaling, is below :data:`MIN_EDGE` (its vertices
    would merge and its faces collapse), or that is more than ``max_size`` across (or None).

    Args:
        v: scaled vertices [units of the result], shape (V, 3); f: faces, int (F, 3), indices checked.
        s: the scale factors per axis; source: name used in messages.
    """
    factors = s[:1] if (s == s[0]).all() else s
    scaled = "" if (s == 1.0).all() else f" after scaling by {' x '.join(f'{x:g}' for x in factors)}"
    with np.errstate(over="ignore", invalid="ignore"):
        size = float(np.ptp(v, axis=0).max())
        edges = np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=-1).reshape(-1)
    if max_size is not None and not size <= max_size:  # (inf and NaN included)
        raise SceneError(f"{source}: the mesh is {size:.3g} m across{scaled}: more than {max_size:g} m, no tube; check "
                         "--scale (metres per mesh unit)")  # fmt: skip
    edges = edges[edges > 0]
    if len(edges) == 0 or np.median(edges) >= MIN_EDGE:
        return  # no edge with length: "every face has zero area" below
    raise SceneError(f"{source}: the mesh is {size:.3g} across{scaled} (median edge {np.median(edges):.3g}): too "
                     f"small, vertices closer than {trimesh.tol.merge:g} merge; check --scale (metres per mesh unit)")


def _file_type(path: str) -> str:
    """The mesh format trimesh reads ``path`` as, from its name ("stl", "ply", ...).

    Raises:
        SceneError: a name that is not one of a mesh format trimesh reads.
    """
    name = os.path.basename(path).lower()
    types = sorted(trimesh.available_formats(), key=len, reverse=True)
    found = next((t for t in types if name.endswith("." + t)), None)
    if found is None:
        ext = os.path.splitext(name)[1]
        raise SceneError(f"{path}: {f'a {ext} file' if ext else 'no extension'}: expected a mesh file (.stl, .ply, "
                         ".obj, .off or .glb)")  # fmt: skip
    return found


def _sniff(path: str) -> tuple[str, str] | None:
    """What the start of a mesh file says it is, as ``(description, extension)``, or None: binary
    STL (its triangle count matches its size), ASCII STL, PLY, OFF, glTF binary, OBJ."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
        size = os.path.getsize(path)
    except OSError:
        return None
    if len(head) >= 84 and 84 + 50 * int.from_bytes(head[80:84], "little") == size:
        return "a binary STL", "stl"
    for magic, found in ((b"ply", ("a PLY", "ply")), (b"glTF", ("a glTF binary", "glb"))):
        if head.startswith(magic):
            return found
    if any(b < 9 for b in head):
        return None  # binary, and none of the binary formats above
    text = head.lstrip().lower()
    for magic, found in ((b"solid", ("an ASCII STL", "stl")), (b"off", ("an OFF", "off"))):
        if text.startswith(magic):
            return found
    words = [ln.split(None, 1)[0] for ln in text.splitlines()[:-1] if ln.strip() and not ln.startswith(b"#")]
    if b"v" in words and all(w in (b"v", b"vn", b"vt", b"f", b"o", b"g", b"s", b"mtllib", b"usemtl") for w in words):
        return "an OBJ", "obj"
    return None


def _obj_made_absolute(path: str) -> bytes | None:
    """An OBJ file's text with its relative (negative) indices made absolute, or None where it has
    none. A negative index counts back from the vertices (texture coordinates, normals) read so
    far, which an OBJ may interleave with its faces (``v v v f -3 -2 -1`` over and over); trimesh
    counts it back from the file's last vertex instead."""
    with open(path, "rb") as f:
        data = f.read()
    if not re.search(rb"(?m)^[ \t]*[fl][ \t].*?[ \t/]-\d", data):
        return None
    seen = {b"v": 0, b"vt": 0, b"vn": 0}
    kinds = (b"v", b"vt", b"vn")
    out = []
    for line in data.splitlines():
        words = line.split()
        if words and words[0] in seen:
            seen[words[0]] += 1
        elif words and words[0] in (b"f", b"l"):
            refs = []
            for ref in words[1:]:
                parts = ref.split(b"/")
                for k, part in enumerate(parts[:3]):
                    if part.startswith(b"-") and part[1:].isdigit():
                        parts[k] = str(seen[kinds[k]] + int(part) + 1).encode()
                refs.append(b"/".join(parts))
            line = b" ".join([words[0], *refs])
        out.append(line)
    return b"\n".join(out) + b"\n"


def _obj_index_problem(source) -> str | None:
    """What is wrong with an OBJ's face indices (``source``: its path, or its text with relative
    indices made absolute), or None where they are within its vertices (1-based)."""
    if isinstance(source, bytes):
        data = source
    else:
        with open(source, "rb") as f:
            data = f.read()
    vertices, low, high = 0, None, None
    for line in data.splitlines():
        words = line.split()
        if not words:
            continue
        if words[0] == b"v":
            vertices += 1
        elif words[0] == b"f":
            for ref in words[1:]:
                head = ref.split(b"/", 1)[0]
                if head.lstrip(b"-").isdigit():
                    k = int(head)
                    low, high = (k, k) if low is None else (min(low, k), max(high, k))
    if low is None or (1 <= low and high <= vertices):
        return None
    return f"face indices span {low}..{high}: expected 1..{vertices} (the file's vertices)"


def load_mesh(path, scale=(1.0, 1.0, 1.0)) -> trimesh.Trimesh:
    """Read a triangle mesh file (STL, PLY, OBJ, ... as trimesh reads them) and clean it.

    Args:
        path: mesh file.
        scale: one factor or (fx, fy, fz) applied to the vertices [units of the result per file unit];
            e.g. CT voxel sizes in mm.

    Returns:
        A cleaned mesh (see :func:`clean_mesh`).

    Raises:
        SceneError: no such file (or a symbolic link loop, a link to nothing, not a regular file),
            unreadable, not a mesh, empty, NaN coordinates, ...
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        raise SceneError(f"{path}: is a folder: expected a mesh file")
    if not os.path.isfile(path):
        raise SceneError(f"{path}: {not_a_file(path, 'a mesh file')}")
    ext = os.path.splitext(path)[1].lower()
    if ext in (".usd", ".usda", ".usdc", ".usdz"):
        raise SceneError(f"{path}: a USD stage, not a mesh file: extract reads STL, PLY, OBJ, OFF or glTF binary; a USD Mesh prim is "
                         "extracted when its scene loads, with warptube:extract = true (see the README)")  # fmt: skip
    file_type = _file_type(path)
    if os.path.getsize(path) == 0:  # (the same words for every format: some readers fail on it, some read nothing)
        raise SceneError(f"{path}: an empty file: expected a surface mesh")
    try:
        with warnings.catch_warnings():  # (values beyond float32 become inf: named below, not as NumPy's warning)
            warnings.simplefilter("ignore", RuntimeWarning)
            relative = _obj_made_absolute(path) if file_type == "obj" else None
            if relative is None:
                mesh = trimesh.load(path, force="mesh", process=False)
            else:
                mesh = trimesh.load(io.BytesIO(relative), file_type="obj", force="mesh", process=False)
    except Exception as e:  # trimesh raises many kinds (ValueError, KeyError, IndexError, UnicodeDecodeError, ...)
        log.debug("%s: trimesh: %s: %s", path, type(e).__name__, e)
        kind = _FORMATS.get(file_type, file_type.upper())
        real = _sniff(path)
        hint = f": its content is {real[0]}: rename it to .{real[1]}" if real and real[1] != file_type else ""
        bad = _obj_index_problem(relative if relative is not None else path) if file_type == "obj" and not hint else None
        if bad:
            raise SceneError(f"{path}: {bad}") from None
        raise SceneError(f"{path}: not a readable {kind} mesh: the file is damaged, truncated or not {kind}{hint}") from None
    if isinstance(mesh, trimesh.Scene) or not hasattr(mesh, "faces"):
        raise SceneError(f"{path}: holds no triangle faces: expected a surface mesh")
    if len(mesh.faces) == 0:
        real = _sniff(path)
        if real and real[1] != file_type:  # e.g. an OFF file named .obj reads as an OBJ with nothing in it
            raise SceneError(f"{path}: no mesh read as {_FORMATS.get(file_type, file_type.upper())}: its content is "
                             f"{real[0]}: rename it to .{real[1]}")  # fmt: skip
        try:  # as the file has them (a point cloud; a glTF's: a scene of them)
            loaded = trimesh.load(path, process=False)
            parts = loaded.geometry.values() if isinstance(loaded, trimesh.Scene) else [loaded]
            points = sum(len(getattr(g, "vertices", ())) for g in parts)
        except Exception:
            points = 0
        if points:
            raise SceneError(f"{path}: {counted(points, 'point')} and no faces (a point cloud): expected a surface "
                             "mesh")
        kind = _FORMATS.get(file_type, file_type.upper())
        raise SceneError(f"{path}: no mesh read as {kind}: the file is damaged or not {kind}")
    return clean_mesh(mesh, path, scale, max_size=MAX_SIZE)


def mesh_from_arrays(points, face_vertex_counts, face_vertex_indices, *, source="<mesh>", scale=(1.0, 1.0, 1.0)):
    """Triangle mesh from polygon arrays as USD stores them (fan-triangulating each polygon).

    Args:
        points: vertex positions, shape (V, 3).
        face_vertex_counts: vertices per polygon, shape (F,), each >= 3.
        face_vertex_indices: polygon vertex indices, concatenated, shape (sum(counts),).
        source: name used in messages (e.g. "scene.usda: /World/Colon").
        scale: as in :func:`clean_mesh`.

    Raises:
        SceneError: mismatched counts and indices, polygons of fewer than 3 vertices, plus all of
            :func:`clean_mesh`.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3) if len(points) else np.zeros((0, 3))
    counts = np.asarray(face_vertex_counts, dtype=np.int64).reshape(-1)
    idx = np.asarray(face_vertex_indices, dtype=np.int64).reshape(-1)
    if len(counts) == 0 or len(p) == 0:
        raise SceneError(f"{source}: empty mesh ({counted(len(p), 'point')}, {counted(len(counts), 'face')}): "
                         "expected a tube surface")
    if (counts < 3).any():
        i = int(np.argmax(counts < 3))
        raise SceneError(f"{source}: faceVertexCounts[{i}] = {counts[i]}: expected polygons of 3 or more vertices")
    if counts.sum() != len(idx):
        raise SceneError(
            f"{source}: faceVertexCounts sum to {counts.sum()} but faceVertexIndices has "
            f"{counted(len(idx), 'entry', 'entries')}"
        )
    if idx.min() < 0 or idx.max() >= len(p):
        raise SceneError(f"{source}: faceVertexIndices span {idx.min()}..{idx.max()}: expected 0..{len(p) - 1}")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    # Fan triangulation: polygon k gives triangles (v0, v_j, v_{j+1}) for j = 1 .. n_k - 2.
    tri_per = counts - 2
    owner = np.repeat(np.arange(len(counts)), tri_per)
    j = np.arange(tri_per.sum()) - np.repeat(np.cumsum(tri_per) - tri_per, tri_per) + 1
    s0 = starts[owner]
    faces = np.stack([idx[s0], idx[s0 + j], idx[s0 + j + 1]], axis=1)
    return clean_mesh(trimesh.Trimesh(p, faces, process=False), source, scale)


def load_usd_mesh(prim, *, source=None, scale=(1.0, 1.0, 1.0), time=None) -> trimesh.Trimesh:
    """Triangle mesh of a ``UsdGeom.Mesh`` prim in world space (parent transforms applied).

    Args:
        prim: a ``Usd.Prim`` of type Mesh.
        source: name used in messages (default: the prim path).
        scale: as in :func:`clean_mesh`, applied after the world transform.
        time: ``Usd.TimeCode`` to read (default: the earliest, i.e. the rest pose).
    """
    from pxr import Usd, UsdGeom

    where = source or str(prim.GetPath())
    if not prim.IsA(UsdGeom.Mesh):
        raise SceneError(f"{where}: is a {prim.GetTypeName() or 'typeless prim'}, expected a Mesh")
    tc = Usd.TimeCode.EarliestTime() if time is None else time
    m = UsdGeom.Mesh(prim)
    pts = m.GetPointsAttr().Get(tc)
    counts = m.GetFaceVertexCountsAttr().Get(tc)
    idx = m.GetFaceVertexIndicesAttr().Get(tc)
    if pts is None or counts is None or idx is None:
        raise SceneError(f"{where}: points, faceVertexCounts or faceVertexIndices not authored")
    p = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(tc), dtype=np.float64)
    if len(p):
        p = p @ xf[:3, :3] + xf[3, :3]  # USD matrices act on row vectors
    return mesh_from_arrays(p, np.asarray(counts), np.asarray(idx), source=where, scale=scale)


@dataclass(frozen=True)
class FlatCut:
    """A flat face closing a tube where it was cut and sealed (a planar patch of the surface).

    Attributes:
        centroid: area-weighted centre of the patch [mesh units], shape (3,).
        normal: unit normal of its plane, shape (3,) (sign arbitrary).
        area: its area [mesh units^2].
        radius: radius of a disc of that area [mesh units].
    """

    centroid: np.ndarray
    normal: np.ndarray
    area: float
    radius: float


def _is_terrace(patch: dict, n: np.ndarray, area: np.ndarray, c: np.ndarray, cos: float) -> bool:
    """Whether ``patch`` is the flat top of a staircase: faces (normals ``n``, areas, centres ``c``)
    facing as it does (normals within ``cos`` of its own), behind it by 1 % to 100 % of its disc's
    radius and within two radii of its centre, of :data:`_TREADS` times its area or more, all round
    it (in each of eight sectors about its normal). Behind a seal across a tube of voxels that
    leans to it, such faces of the wall lie on one side only."""
    rc = float(np.sqrt(patch["area"] / np.pi))
    rel = c - patch["centre"]
    depth = rel @ patch["normal"]
    flat = rel - depth[:, None] * patch["normal"]
    behind = (depth < -0.01 * rc) & (depth >= -rc) & (np.linalg.norm(rel, axis=1) <= 2.0 * rc)
    tread = behind & (n @ patch["normal"] > cos)
    if area[tread].sum() < _TREADS * patch["area"]:
        return False
    u = np.cross(patch["normal"], [1.0, 0.0, 0.0] if abs(patch["normal"][0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(patch["normal"], u)
    sector = (np.floor((np.arctan2(flat[tread] @ w, flat[tread] @ u) + np.pi) / (0.25 * np.pi)).astype(int)) % 8
    per = np.bincount(sector, weights=area[tread], minlength=8)
    return bool((per >= 0.01 * patch["area"]).all())


def _unfolded(mesh: trimesh.Trimesh) -> np.ndarray:
    """Per pair of adjacent faces (``mesh.face_adjacency``): whether they lie on either side of their
    shared edge. Two faces folded onto each other (a crumple of a rough wall) lie in one plane with
    opposite normals, on one side of it."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    edge = np.asarray(mesh.face_adjacency_edges)
    apex = np.asarray(mesh.face_adjacency_unshared)
    a = v[edge[:, 0]]
    e = v[edge[:, 1]] - a
    e /= np.maximum(np.linalg.norm(e, axis=1), 1e-300)[:, None]
    side = [v[apex[:, k]] - a for k in (0, 1)]
    side = [x - np.einsum("ij,ij->i", x, e)[:, None] * e for x in side]
    return np.einsum("ij,ij->i", side[0], side[1]) < 0.0


def flat_cuts(mesh: trimesh.Trimesh, min_area: float, angle_deg: float = 1.0, depth=None) -> list[FlatCut]:
    """Planar patches of ``mesh`` of at least ``min_area``, largest first.

    Faces are grouped with their neighbours when their normals differ by less than ``angle_deg``
    and they lie in one plane on either side of their shared edge (not folded onto each other);
    groups in one plane (normals within ``angle_deg``, offsets within 1 % of the radius of
    ``min_area``'s disc) whose centres lie within four such radii are merged (a sealed cut is often
    split by a row of bent triangles). Left out: single faces whose neighbours all leave their
    plane and patches of fewer than three faces (facets of a rough wall, where every face is one: a
    cut across a tube of five sides or more has three faces at least), groups whose bordering faces
    turn less than about 53 degrees away from them on average (a facet of a faceted wall, not a seal
    meeting the wall at a crease), patches much longer than wide (area below 0.3 pi times the
    square of their largest distance from the centre, the ``reach``: flat strips of a straight
    wall; but where ``depth`` is given, one of area down to 0.1 pi reach^2 that the mesh lies
    behind for two reaches or more along its normal is kept: the seal of a flattened tube, up to
    about 10:1, against a strip of a prism's wall, whose tube is narrower than the strip is long), and the
    terraces of a staircase (a surface made of voxel faces, whose rounded tip has a flat top):
    patches with faces parallel to them all round, just out of their plane
    (:func:`_is_terrace`; a seal meets the tube's wall there, across it).
    """
    n = unit_face_normals(mesh)
    area = np.asarray(mesh.area_faces)
    c = np.asarray(mesh.triangles_center)
    adj = np.asarray(mesh.face_adjacency)
    if len(adj) == 0:
        return []
    cos = np.cos(np.radians(angle_deg))
    r0 = float(np.sqrt(min_area / np.pi))
    same = (np.abs(np.einsum("ij,ij->i", n[adj[:, 0]], n[adj[:, 1]])) > cos) & (
        np.abs(np.einsum("ij,ij->i", n[adj[:, 0]], c[adj[:, 1]] - c[adj[:, 0]])) < 0.01 * r0
    ) & _unfolded(mesh)
    g = sp.coo_matrix((np.ones(int(same.sum())), (adj[same, 0], adj[same, 1])), shape=(len(n), len(n)))
    count, label = connected_components(g, directed=False)
    total = np.bincount(label, weights=area, minlength=count)
    centre_of = np.stack([np.bincount(label, weights=area * c[:, k], minlength=count) for k in range(3)], axis=1)
    centre_of /= np.maximum(total, 1e-300)[:, None]
    order = np.lexsort((area, label))  # per group, its largest face last
    largest = np.zeros(count, dtype=np.int64)
    largest[label[order]] = order
    normal_of = n[largest]
    # A seal meets the tube's wall at a crease all round: the faces bordering it turn away (a flat
    # facet of a faceted wall has neighbours almost in its plane).
    la, lb = label[adj[:, 0]], label[adj[:, 1]]
    rim = la != lb
    turn = np.zeros(count)
    seen = np.zeros(count)
    for mine, other in ((adj[rim, 0], adj[rim, 1]), (adj[rim, 1], adj[rim, 0])):
        grp = label[mine]
        np.add.at(turn, grp, np.abs(np.einsum("ij,ij->i", n[other], normal_of[grp])))
        np.add.at(seen, grp, 1.0)
    creased = (seen > 0) & (turn <= 0.6 * np.maximum(seen, 1.0))
    # A face whose neighbours all leave its plane is a facet of the wall, not a piece of a seal: on a
    # rough wall (scanned, segmented) every face is such a group of one (and merging them is quadratic).
    faces = np.bincount(label, minlength=count)
    groups = [k for k in np.argsort(-total) if total[k] >= 0.1 * min_area and creased[k] and faces[k] > 1]
    v = np.asarray(mesh.vertices)
    f_all = np.asarray(mesh.faces)
    patches = []
    for k in groups:
        centre, normal, w_sum = centre_of[k], normal_of[k], float(total[k])
        corners = v[f_all[label == k].reshape(-1)]
        for p in patches:
            if (abs(float(np.dot(p["normal"], normal))) > cos and abs(float(np.dot(p["normal"], centre - p["centre"])))
                    < 0.01 * r0 and np.linalg.norm(centre - p["centre"]) < 4.0 * r0):  # fmt: skip
                p["centre"] = (p["centre"] * p["area"] + centre * w_sum) / (p["area"] + w_sum)
                p["area"] += w_sum
                p["corners"] = np.concatenate([p["corners"], corners])
                p["faces"] += int(faces[k])
                break
        else:
            patches.append({"centre": centre, "normal": normal, "area": w_sum, "corners": corners,
                            "faces": int(faces[k])})
    out = []
    for p in patches:
        reach = float(np.linalg.norm(p["corners"] - p["centre"], axis=1).max())
        # A cut across a tube is about as wide as it is long (a disc or an ellipse); a flat strip
        # of a faceted wall is long and thin, and so is the seal of a flattened tube: the mesh
        # behind the seal runs along the tube, behind the strip only across it.
        if p["faces"] < _SEAL_FACES or p["area"] < min_area or p["area"] < 0.1 * np.pi * reach**2 or \
                _is_terrace(p, n, area, c, cos):  # fmt: skip
            continue
        if p["area"] < 0.3 * np.pi * reach**2 and (depth is None or _depth_behind(p, reach, depth) < 2.0 * reach):
            continue
        out.append(FlatCut(p["centre"], p["normal"], p["area"], float(np.sqrt(p["area"] / np.pi))))
    return sorted(out, key=lambda x: -x.area)


def _depth_behind(patch: dict, reach: float, depth) -> float:
    """How far the mesh lies behind flat ``patch`` along its normal: the longer of the rays from
    just off its centre along the normal either way (``depth(origins, dirs)``: hit distances, -1 on
    a miss)."""
    c, nrm = patch["centre"], patch["normal"]
    eps = 1e-3 * reach
    hits = np.asarray(depth(np.stack([c + eps * nrm, c - eps * nrm]), np.stack([nrm, -nrm])), dtype=np.float64)
    return float(hits.max())
