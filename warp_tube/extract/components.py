"""The pieces of a mesh: corners welded within a tolerance relative to the mesh's size, and the
component kept where it falls into several."""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components

from .wording import counted

__all__ = ["weld", "largest_component", "surface_labels", "WELD"]

log = logging.getLogger(__name__)

WELD = 1e-6
"""Vertices closer than this x the bounding box's diagonal are one: float32 carries 7 digits, so
corners of one point computed separately differ by about 1e-7 of the coordinates, and a mesh with
an edge this short along its diagonal would have about 1e12 faces."""
_FLOAT32_STEPS = 8  # the least weld, in float32 steps of the largest coordinate


def weld(mesh: trimesh.Trimesh) -> None:
    """Merge the vertices of ``mesh`` closer than :data:`WELD` of its bounding box's diagonal, in place.

    Corners of one triangle soup computed separately (an STL written triangle by triangle) differ
    in their last bits, and trimesh's merge (exact to 1e-8 in absolute units) leaves them apart:
    the mesh then falls into thousands of components. The tolerance is relative, so the weld is the
    same at every size (a capillary in metres as the same mesh in mm), and it is at least a few
    float32 steps of the coordinates (a mesh far from its origin has coarser steps than its size
    says); a tenth of the median edge bounds it, so no real edge of the mesh is collapsed.
    """
    from scipy.spatial import cKDTree

    v = np.asarray(mesh.vertices, dtype=np.float64)
    if len(v) < 2:
        return
    edges = mesh.edges_unique_length
    edges = edges[edges > 0]
    if len(edges) == 0:
        return
    diagonal = float(np.linalg.norm(np.ptp(v, axis=0)))
    ulps = _FLOAT32_STEPS * float(np.spacing(np.float32(np.abs(v).max())))
    tol = min(max(WELD * diagonal, ulps), 0.1 * float(np.median(edges)))
    pairs = cKDTree(v).query_pairs(tol, output_type="ndarray")
    if len(pairs) == 0:
        return
    g = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(v), len(v)))
    _, label = connected_components(g, directed=False)
    first = np.full(label.max() + 1, len(v))
    np.minimum.at(first, label, np.arange(len(v)))  # each group kept at its first vertex
    mesh.faces = first[label][mesh.faces]
    mesh.remove_unreferenced_vertices()


def surface_labels(mesh: trimesh.Trimesh) -> np.ndarray:
    """Each face's piece of ``mesh`` (faces that share an edge, on and on), (F,) int from 0.

    Where two faces share an edge they are one surface. Where three or more do (a wall across the
    tube joined to it along its whole rim; two closed segments of one organ exported end to end,
    their touching caps one wall once welded), the faces there pair up by how straight the surface
    goes on through the edge: the pair whose normals agree best (and point within 90 degrees of
    each other), then the next of the others. The tube's two sides are then one piece and the wall
    one of its own (trimesh's ``face_adjacency`` takes edges of two faces only: the tube fell
    apart at the wall, and one half was kept)."""
    F = len(mesh.faces)
    edges = np.sort(np.asarray(mesh.faces, dtype=np.int64)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    face_of = np.repeat(np.arange(F, dtype=np.int64), 3)
    key = edges[:, 0] * (int(edges.max()) + 1 if len(edges) else 1) + edges[:, 1]
    order = np.argsort(key, kind="stable")
    k = key[order]
    starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]]) if len(k) else np.zeros(0, dtype=np.int64)
    counts = np.diff(np.r_[starts, len(k)])
    two = starts[counts == 2]
    a, b = [face_of[order[two]]], [face_of[order[two + 1]]]
    many = np.flatnonzero(counts >= 3)
    if len(many):
        tri = np.asarray(mesh.triangles, dtype=np.float64)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)  # (a face of no area: 0, paired with none)
        extra_a, extra_b = [], []
        for s0, c in zip(starts[many].tolist(), counts[many].tolist()):
            fs = np.unique(face_of[order[s0 : s0 + c]])
            d = n[fs] @ n[fs].T
            np.fill_diagonal(d, -np.inf)
            while True:
                i, j = np.unravel_index(int(np.argmax(d)), d.shape)
                if not d[i, j] > 0.0:
                    break
                extra_a.append(fs[i])
                extra_b.append(fs[j])
                d[[i, j], :] = -np.inf
                d[:, [i, j]] = -np.inf
        a.append(np.asarray(extra_a, dtype=np.int64))
        b.append(np.asarray(extra_b, dtype=np.int64))
    a, b = np.concatenate(a), np.concatenate(b)
    g = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(F, F))
    return connected_components(g, directed=False)[1]


def largest_component(mesh: trimesh.Trimesh, labels: np.ndarray, source: str) -> int:
    """The component of ``mesh`` (face ``labels``) with the largest surface area, the others named
    in a warning. Area, not the count of faces: a finely meshed twig has more faces than a coarsely
    meshed artery ten times its size; and not volume, which an open tube does not enclose."""
    area = np.bincount(labels, weights=mesh.area_faces)
    faces = np.bincount(labels)
    order = np.argsort(-area, kind="stable")
    keep = int(order[0])
    total = float(area.sum()) or 1.0

    def described(c: int) -> str:
        v = mesh.vertices[np.unique(mesh.faces[labels == c])]
        return f"{counted(faces[c], 'face', fmt=',')}, {float(np.linalg.norm(np.ptp(v, axis=0))):.3g} m across"

    # Pieces of no area (degenerate faces along an edge of the mesh, which join it at that edge
    # only, a third face there) are no part of the surface: dropped without a warning.
    flat = area[order[1:]] <= 1e-9 * total
    none = order[1:][flat]
    if len(none):
        log.info("%s: %s of no area left out (degenerate faces joined to the mesh at an edge only)", source,
                 counted(int(faces[none].sum()), "face", fmt=","))  # fmt: skip
    dropped = order[1:][~flat]
    if not len(dropped):
        return keep
    if len(dropped) <= 3:
        left = "; ".join(described(int(c)) for c in dropped)
    else:
        left = (f"{len(dropped):,} others, {100.0 * area[dropped].sum() / total:.3g}% of the area, the largest "
                f"{described(int(dropped[0]))}")  # fmt: skip
    pieces = ""
    kept_vertices = np.unique(mesh.faces[labels == keep])
    walls = [int(c) for c in dropped if np.isin(mesh.faces[labels == c], kept_vertices).any()]
    if walls:  # (joined to the kept piece where three or more faces share an edge)
        pieces = f"; {counted(len(walls), 'piece')} of them touching it (a wall inside the tube, or pieces exported together?)"
    if len(area) > 100 and area[keep] < 0.5 * total:  # the soup of an STL whose corners do not meet, as a rule
        pieces = ("; the mesh falls into many small pieces: are its triangles' shared corners apart (each triangle "
                  "its own corners, not welded)?")  # fmt: skip
    log.warning("%s: %s; kept the largest by surface area (%s, %.3g%% of the area); left out: %s%s", source,
                counted(1 + len(dropped), "connected component", fmt=","), described(keep), 100.0 * area[keep] / total,
                left, pieces)  # fmt: skip
    return keep
