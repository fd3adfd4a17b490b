"""A hollow tube (a hose, a pipe: a wall of some thickness around a bore) reduced to its outer wall.

The extraction finds the axis of the solid a surface encloses. A hose modelled with its wall
(an outer and an inner cylinder, joined by flat rings at the ends, as CAD tools export a pipe)
encloses only the wall: its axis would be a thread inside the wall, running round the bore. A
hollow tube is found as two walls, one inside the other:

- given as separate pieces (an outer and an inner surface, open at the ends), or
- joined by flat rims: planar patches of a closed surface with a hole through it (``V - E + F <=
  0``) bounded by two loops or more (a ring, not a disc), whose removal splits the surface into an
  outer and an inner wall.

The inner wall counts when it lies inside the outer one (its faces' centres inside the outer wall
with its open ends capped, by ray parity) and its area is at least :data:`BORE_AREA` of the outer's (a
bore along the tube, not a speck inside it). The outer wall alone is then the tube: a solid tube of
the outer radius, open where the rims were. The bore's radius relative to the outer one is about
the ratio of the two walls' areas (equal lengths), which the warning gives with the factors that
turn a solid tube's stiffness and mass into the hollow one's. A bore closed at one end (a test
tube) or rims that are not flat (a rounded lip, a scan) are not recognised.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import trimesh
import warp as wp
from scipy.sparse.csgraph import connected_components

from .loops import boundary_loops, cap_loops

__all__ = ["Bore", "outer_wall", "BORE_AREA"]

log = logging.getLogger(__name__)

#: an inner wall counts as a bore when its area is at least this fraction of the outer wall's
#: (a bore of 0.3 the outer radius along the whole tube has 0.3 of its area)
BORE_AREA = 0.25
_INSIDE = 0.9  # fraction of the inner wall's sampled vertices that must lie inside the outer wall
_SAMPLES = 256  # face centres of the inner wall tested (its vertices may lie on the outer's end planes)
_FLAT_COS = np.cos(np.radians(1.0))  # faces of one rim: normals within 1 degree, in one plane


@dataclass(frozen=True)
class Bore:
    """The bore left out of a hollow tube.

    Attributes:
        ratio: the inner wall's area over the outer wall's: about the bore's radius over the
            tube's outer radius.
        rims: faces of the flat rims removed (0 where the walls were separate pieces).
    """

    ratio: float
    rims: int


def _components(mesh: trimesh.Trimesh, keep: np.ndarray) -> np.ndarray:
    """Connected-component label per face of ``mesh`` among the faces ``keep`` (bool (F,)), -1 elsewhere."""
    adj = np.asarray(mesh.face_adjacency)
    adj = adj[keep[adj[:, 0]] & keep[adj[:, 1]]] if len(adj) else adj.reshape(0, 2)
    n = len(mesh.faces)
    g = sp.coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    label = np.where(keep, label, -1)
    _, label[keep] = np.unique(label[keep], return_inverse=True)
    return label


def _rims(mesh: trimesh.Trimesh) -> np.ndarray:
    """Faces of the planar patches bounded by two loops or more (flat rings) of a closed ``mesh``
    (every edge between two faces), bool (F,)."""
    n = np.asarray(mesh.face_normals, dtype=np.float64)
    c = np.asarray(mesh.triangles_center, dtype=np.float64)
    adj = np.asarray(mesh.face_adjacency)
    nf, nv = len(mesh.faces), len(mesh.vertices)
    if len(adj) == 0:
        return np.zeros(nf, dtype=bool)
    scale = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    flat = (np.einsum("ij,ij->i", n[adj[:, 0]], n[adj[:, 1]]) > _FLAT_COS) & (
        np.abs(np.einsum("ij,ij->i", n[adj[:, 0]], c[adj[:, 1]] - c[adj[:, 0]])) < 1e-6 * scale
    )
    g = sp.coo_matrix((np.ones(int(flat.sum())), (adj[flat, 0], adj[flat, 1])), shape=(nf, nf))
    _, patch = connected_components(g, directed=False)
    # An edge between two patches borders both: its ends are nodes (patch, vertex) of each.
    cut = patch[adj[:, 0]] != patch[adj[:, 1]]
    ends = np.asarray(mesh.face_adjacency_edges)[cut].astype(np.int64)
    if len(ends) == 0:
        return np.zeros(nf, dtype=bool)
    side = np.concatenate([patch[adj[cut, 0]], patch[adj[cut, 1]]]).astype(np.int64)
    ends = np.concatenate([ends, ends])
    nodes, inv = np.unique(np.concatenate([side * nv + ends[:, 0], side * nv + ends[:, 1]]), return_inverse=True)
    m = len(side)
    g = sp.coo_matrix((np.ones(m), (inv[:m], inv[m:])), shape=(len(nodes), len(nodes)))
    _, piece = connected_components(g, directed=False)
    first = np.unique(piece, return_index=True)[1]
    loops = np.bincount(nodes[first] // nv, minlength=patch.max() + 1)  # boundary loops per patch
    # A rim is flat as a whole, not only face to face: a band of a finely meshed torus, its
    # neighbouring faces within 1 degree and their planes apart by less than the tolerance, turns
    # round the ring (every normal within 1 degree of the patch's mean, every centre in its plane).
    ring = loops[patch] >= 2
    if not ring.any():
        return ring
    k = patch[ring]
    w = np.asarray(mesh.area_faces, dtype=np.float64)[ring]
    mean = np.stack([np.bincount(k, weights=w * n[ring, j], minlength=len(loops)) for j in range(3)], axis=1)
    mean /= np.maximum(np.linalg.norm(mean, axis=1, keepdims=True), 1e-300)
    level = np.einsum("ij,ij->i", mean[k], c[ring])
    lo = np.full(len(loops), np.inf)
    hi = np.full(len(loops), -np.inf)
    np.minimum.at(lo, k, level)
    np.maximum.at(hi, k, level)
    turn = np.ones(len(loops))
    np.minimum.at(turn, k, np.einsum("ij,ij->i", mean[k], n[ring]))
    flat = (turn > _FLAT_COS) & (hi - lo < 1e-6 * scale)
    return ring & flat[patch]


def _sampled(points: np.ndarray) -> np.ndarray:
    """At most :data:`_SAMPLES` of ``points``, evenly through the array."""
    return points[:: max(1, len(points) // _SAMPLES)]


def _inside(outer: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Whether each of ``points`` (n, 3) lies inside ``outer`` with its boundary loops capped (ray
    parity), bool (n,)."""
    from ..kernels import raycast

    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    v, f = cap_loops(outer, boundary_loops(outer))
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))  # float32 queries: near the origin
    device = wp.get_device()
    pts = wp.array(np.asarray(v - centre, dtype=np.float32), dtype=wp.vec3, device=device)
    idx = wp.array(np.asarray(f, dtype=np.int32).reshape(-1), dtype=wp.int32, device=device)
    mesh = wp.Mesh(points=pts, indices=idx)
    p = wp.array(np.asarray(points - centre, dtype=np.float32), dtype=wp.vec3, device=device)
    out = wp.zeros(len(points), dtype=wp.int32, device=device)
    reach = 2.0 * float(np.linalg.norm(np.ptp(v, axis=0)))
    wp.launch(raycast.inside_by_parity, dim=len(points), inputs=[mesh.id, p, reach], outputs=[out], device=device)
    return out.numpy() != 0


def outer_wall(mesh: trimesh.Trimesh, source: str, labels: np.ndarray | None = None) -> tuple[trimesh.Trimesh, Bore | None]:
    """``mesh`` (welded, without degenerate faces) as its outer wall where it is a hollow tube;
    ``labels``: its faces' connected pieces where the caller has them (F,) int.

    Returns:
        ``(mesh, None)`` where it is not a hollow tube (the same object); else the outer wall's faces
        as a new mesh, open where the rims were, and the :class:`Bore` left out (also warned of).
    """
    if len(mesh.faces) < 16:
        return mesh, None
    rims = np.zeros(len(mesh.faces), dtype=bool)
    label = _components(mesh, ~rims) if labels is None else np.asarray(labels)
    if label.max() == 0:  # one piece: walls joined by flat rims? (closed, with a hole through it at least)
        if not mesh.is_watertight or mesh.euler_number > 0:
            return mesh, None
        rims = _rims(mesh)
        if not rims.any():
            return mesh, None
        label = _components(mesh, ~rims)
        if label.max() < 1:
            return mesh, None
    area = np.bincount(label[label >= 0], weights=np.asarray(mesh.area_faces)[label >= 0])
    order = np.argsort(-area, kind="stable")
    outer = trimesh.Trimesh(mesh.vertices, mesh.faces[label == order[0]], process=False)
    outer.remove_unreferenced_vertices()
    inner = int(order[1])
    if area[inner] < BORE_AREA * area[order[0]]:
        return mesh, None
    # Each other piece's sampled face centres, tested in one launch: the inner wall must lie inside
    # the outer one; every other piece inside it goes with the bore, pieces outside stay for the caller.
    centres = np.asarray(mesh.triangles_center)
    pieces = [int(k) for k in order[1:]]
    by_piece = np.argsort(label, kind="stable")  # faces grouped by piece (-1, the rims, first)
    bounds = np.searchsorted(label[by_piece], np.arange(label.max() + 2))
    samples = [_sampled(centres[by_piece[bounds[k]:bounds[k + 1]]]) for k in pieces]
    flags = np.split(_inside(outer, np.concatenate(samples)), np.cumsum([len(x) for x in samples])[:-1])
    share = {k: float(fl.mean()) if len(fl) else 0.0 for k, fl in zip(pieces, flags)}
    if share[inner] < _INSIDE:
        return mesh, None
    keep = ~np.isin(label, [k for k in pieces if share[k] >= _INSIDE])
    if rims.any():
        keep &= ~rims
    out = trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False)
    out.remove_unreferenced_vertices()
    ratio = float(area[inner] / area[order[0]])
    bore = Bore(ratio, int(rims.sum()))
    k2, k4 = 1.0 - min(ratio, 1.0) ** 2, 1.0 - min(ratio, 1.0) ** 4
    log.warning(
        "%s: a hollow tube (an inner wall inside the outer one%s; bore about %.2f of the outer radius, from the walls' "
        "areas): extracted as the solid tube of its outer wall, the bore left out. A solid tube is heavier and stiffer: "
        "the hollow one has about %.2f of its mass and stretch stiffness and %.2f of its bending stiffness (scale "
        "warptube:density, or set warptube:stretchStiffness and warptube:bendStiffness)", source,
        ", joined by flat rims" if rims.any() else "", ratio, k2, k4)  # fmt: skip
    return out, bore
