"""The pieces of a mesh: corners welded within a tolerance relative to the mesh's size, and the
component kept where it falls into several."""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components

from .wording import counted

__all__ = ["weld", "largest_component", "WELD"]

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
    if len(area) > 100 and area[keep] < 0.5 * total:  # the soup of an STL whose corners do not meet, as a rule
        pieces = ("; the mesh falls into many small pieces: are its triangles' shared corners apart (each triangle "
                  "its own corners, not welded)?")  # fmt: skip
    log.warning("%s: %s; kept the largest by surface area (%s, %.3g%% of the area); left out: %s%s", source,
                counted(1 + len(dropped), "connected component", fmt=","), described(keep), 100.0 * area[keep] / total,
                left, pieces)  # fmt: skip
    return keep
