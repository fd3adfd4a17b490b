"""Closed rings: meshes of a tube that closes on itself (a torus), which have no ends.

A mesh is a closed ring when it is watertight (every edge shared by two faces) and its Euler
characteristic ``V - E + F`` is 0 (genus 1: one loop through it). An open-ended tube also has
``V - E + F = 0`` but has boundary edges; a capped tube has 2. The simulator's tubes have two
ends, so extraction cuts a ring open between two ends it picks, and the tube leaves the rest of
the ring out. The ring is confirmed on the result: the mesh's faces away from the tube's rest
surface form one piece joining its two ends (a tiny handle in a straight tube's wall leaves the
ends apart).

Lengths are in the mesh's units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .fidelity import mesh_distances, plain_surface

__all__ = ["RingCut", "euler_characteristic", "is_closed_ring", "ring_cut", "LEFT_OUT_DISTANCE"]

LEFT_OUT_DISTANCE = 0.5
"""A face is left out of the tube when its centre lies farther than this x the mean radius from the
tube's rest rings (joined by strips, no caps)."""
_TIP_REACH = 2.0  # faces within this x the end radius of a tip belong to that end


@dataclass(frozen=True)
class RingCut:
    """How a closed ring was cut open into the extracted tube.

    Attributes:
        cuts: where the tube ends, its two tips [mesh units], shape (2, 3).
        left_out: fraction of the ring's surface area the tube leaves out (0 to 1).
        rest: indices, among the side branches found, of those that are the rest of the ring.
    """

    cuts: np.ndarray
    left_out: float
    rest: tuple[int, ...] = ()


def euler_characteristic(mesh: trimesh.Trimesh) -> int:
    """``V - E + F`` of a triangle mesh, each edge counted once (trimesh's ``euler_number``)."""
    return int(mesh.euler_number)


def is_closed_ring(mesh: trimesh.Trimesh) -> bool:
    """Whether ``mesh`` (welded, one connected piece) is watertight (every edge shared by two
    faces) with ``V - E + F == 0``."""
    return bool(mesh.is_watertight) and euler_characteristic(mesh) == 0


def _left_out_faces(mesh: trimesh.Trimesh, points, spoke_lengths, reference_normal, device) -> np.ndarray:
    """Faces whose centre lies farther than :data:`LEFT_OUT_DISTANCE` mean radii from the tube's
    rings, bool (F,). ``points``: hubs (N, 3) and ``spoke_lengths`` (N, S) [mesh units]."""
    radius = float(np.mean(spoke_lengths))
    d = mesh_distances(mesh.triangles_center, *plain_surface(points, spoke_lengths, reference_normal), device)
    return d > LEFT_OUT_DISTANCE * radius


def _joining_piece(mesh: trimesh.Trimesh, far: np.ndarray, tips: np.ndarray, reach: np.ndarray) -> np.ndarray | None:
    """The connected piece of the ``far`` faces that comes within ``reach`` (2,) of both ``tips``
    (2, 3) [mesh units], bool (F,); None when no piece joins the two ends."""
    adj = np.asarray(mesh.face_adjacency)
    both = adj[far[adj[:, 0]] & far[adj[:, 1]]]
    n = len(far)
    graph = sp.coo_matrix((np.ones(len(both)), (both[:, 0], both[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    centres = np.asarray(mesh.triangles_center)
    near = [far & (np.linalg.norm(centres - tips[k], axis=1) <= reach[k]) for k in (0, 1)]
    common = np.intersect1d(label[near[0]], label[near[1]])
    if len(common) == 0:
        return None
    sizes = [np.asarray(mesh.area_faces)[label == c].sum() for c in common]
    return label == common[int(np.argmax(sizes))]


def _rest_branches(mesh: trimesh.Trimesh, piece: np.ndarray, branch_paths) -> tuple[int, ...]:
    """Indices of the branch paths that run mostly inside ``piece``: their points' nearest faces
    are faces of it."""
    tree = cKDTree(np.asarray(mesh.triangles_center))
    rest = []
    for i, path in enumerate(branch_paths):
        path = np.asarray(path, dtype=np.float64).reshape(-1, 3)
        if len(path) and piece[tree.query(path)[1]].mean() > 0.5:
            rest.append(i)
    return tuple(rest)


def ring_cut(mesh: trimesh.Trimesh, points, spoke_lengths, reference_normal, tips, branch_paths=(), device=None
             ) -> RingCut | None:  # fmt: skip
    """How the extracted tube cut ``mesh`` open, or None when it is not a closed ring.

    Args:
        mesh: the cleaned mesh the tube was extracted from [mesh units].
        points: the tube's hubs, shape (N, 3); spoke_lengths: shape (N, S); reference_normal: (3,).
        tips: where the tube ends, shape (2, 3).
        branch_paths: the side branches' paths found, each (k, 3).
        device: Warp device for the distance queries.
    """
    if not is_closed_ring(mesh):
        return None
    lengths = np.asarray(spoke_lengths, dtype=np.float64)
    tips = np.asarray(tips, dtype=np.float64)
    far = _left_out_faces(mesh, points, lengths, reference_normal, device)
    reach = _TIP_REACH * lengths.mean(axis=1)[[0, -1]]
    piece = _joining_piece(mesh, far, tips, reach)
    if piece is None:
        return None
    area = np.asarray(mesh.area_faces)
    return RingCut(tips.copy(), float(area[piece].sum() / area.sum()), _rest_branches(mesh, piece, branch_paths))
