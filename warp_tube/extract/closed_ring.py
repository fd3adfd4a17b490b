"""Closed rings: meshes of a tube that closes on itself (a torus), which have no ends.

A mesh is a closed ring when it is watertight (every edge shared by two faces) and its Euler
characteristic ``V - E + F`` is 0 (genus 1: one loop through it). An open-ended tube also has
``V - E + F = 0`` but has boundary edges; a capped tube has 2. The simulator's tubes have two
ends, so extraction cuts a ring open (:func:`open_ring`): at the widest point of its inside, the
inside voxels across the tube within :data:`CUT_GAP` / 2 of the tube's radius there on either side
of the plane normal to the tube are taken out, and the tube runs the other way round the ring, from
one side of that gap to the other. Its two ends are cut ends (:mod:`warp_tube.extract.ends`) sealed
by the gap's two planes: their end rings are complete sections of the ring's wall normal to the axis,
their hubs on it, and the tube leaves out only the surface between its two end rings (about
:data:`CUT_GAP` radii of the ring's length, :func:`ring_cut`). The ring is confirmed on the inside:
without the gap its two sides are still joined, by a path that stays of the tube's width (a tiny
handle in a straight tube's wall is no ring: the gap parts the tube, or the path runs through the
thin handle).

Lengths are in the mesh's units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from . import distance_map as dmap
from .ends import EndChoice
from .mesh_io import FlatCut

__all__ = ["RingCut", "RingOpening", "euler_characteristic", "is_closed_ring", "open_ring", "ring_cut", "CUT_GAP"]

CUT_GAP = 1.0
"""A closed ring is cut open across a gap of this x the tube's radius at the cut, along its axis
(between the planes that seal its two ends)."""
_NEAR = 3.0  # the cut takes out inside voxels within this x the radius (along the inside) of its centre
_TANGENT_REACH = 2.5  # the axis's direction at the cut: principal axis of the inside within this x the radius
_THIN = 0.3  # a ring's path round from one side of the gap to the other is this x the radius at the cut
_THIN_SHARE = 0.1  # ... wide or wider, but for at most this share of its length
_WIDTH = 1.5  # ... and reaches this x the radius from the cut at least (a ring's loop spans its diameter)


@dataclass(frozen=True)
class RingCut:
    """How a closed ring was cut open into the extracted tube.

    Attributes:
        cuts: where the tube ends, its two tips [mesh units], shape (2, 3).
        left_out: fraction of the ring's surface area the tube leaves out (0 to 1): the faces
            between its two end rings.
        rest: indices, among the side branches found, of those in the surface left out.
    """

    cuts: np.ndarray
    left_out: float
    rest: tuple[int, ...] = ()


@dataclass(frozen=True)
class RingOpening:
    """Where a closed ring is cut open: the ends as :func:`~warp_tube.extract.ends.choose_ends`
    gives them (the gap's two planes as the cuts that seal them) and the centred voxel graph without
    the gap, along which the tube runs round the ring."""

    choice: EndChoice
    graph: sp.csr_matrix


def euler_characteristic(mesh: trimesh.Trimesh) -> int:
    """``V - E + F`` of a triangle mesh, each edge counted once (trimesh's ``euler_number``)."""
    return int(mesh.euler_number)


def is_closed_ring(mesh: trimesh.Trimesh) -> bool:
    """Whether ``mesh`` (welded, one connected piece) is watertight (every edge shared by two
    faces) with ``V - E + F == 0``."""
    return bool(mesh.is_watertight) and euler_characteristic(mesh) == 0


def _side_voxel(dm: dmap.DistanceMap, near: np.ndarray, along: np.ndarray, lo: float) -> int | None:
    """The most centred voxel of ``near`` whose position ``along`` the axis lies in the slice of
    two voxels beyond ``lo`` [mesh units]; None when there is none."""
    cand = near[(along[near] > lo) & (along[near] <= lo + 2.0 * dm.voxel_size)]
    return None if len(cand) == 0 else int(cand[np.argmax(dm.dfb[cand])])


def open_ring(dm: dmap.DistanceMap) -> RingOpening | None:
    """Cut the inside of a closed ring open (see the module), or None where it is not a ring: the
    gap parts the inside, or the path round the ring is thin (:data:`_THIN`) for more than
    :data:`_THIN_SHARE` of its length or stays within :data:`_WIDTH` radii of the cut.

    The cut's centre is the inside voxel farthest from the wall, at radius ``r``; the axis there
    is the principal axis of the inside voxels within :data:`_TANGENT_REACH` ``r`` of it (along the
    inside), and the voxels within :data:`_NEAR` ``r`` of it whose position along the axis lies within
    ``CUT_GAP r / 2`` of it are the gap. Each end starts at the most centred voxel just beyond the gap.
    """
    centre = int(np.argmax(dm.dfb))
    r = float(dm.dfb[centre])
    reach = dijkstra(dm.length_graph, directed=False, indices=centre, limit=(_NEAR + CUT_GAP) * r)
    local = dm.points[reach <= _TANGENT_REACH * r]
    if len(local) < 4:
        return None
    tangent = np.linalg.svd(local - local.mean(axis=0), full_matrices=False)[2][0]
    along = (dm.points - dm.points[centre]) @ tangent
    near = np.flatnonzero(np.isfinite(reach))
    half = 0.5 * CUT_GAP * r
    gap = near[np.abs(along[near]) <= half]
    a, b = _side_voxel(dm, near, along, half), _side_voxel(dm, near, -along, half)
    if a is None or b is None:
        return None
    keep = np.ones(dm.count)
    keep[gap] = 0.0
    graph = (sp.diags(keep) @ dm.centred_graph @ sp.diags(keep)).tocsr()
    graph.eliminate_zeros()
    dist, pred, _ = dmap.shortest_tree(graph, a)
    if not np.isfinite(dist[b]):
        return None  # the gap parts the inside: a tube, not a ring
    path = dmap.trace_path(pred, b)
    steps = np.r_[np.linalg.norm(np.diff(dm.points[path], axis=0), axis=1), 0.0]
    thin = steps[dm.dfb[path] < _THIN * r].sum() / max(steps.sum(), 1e-300)
    width = float(np.linalg.norm(dm.points[path] - dm.points[centre], axis=1).max())
    if thin > _THIN_SHARE or width < _WIDTH * r:
        return None  # a small handle, not the loop of a ring
    point = dm.points[centre]
    cuts = [FlatCut(point + sign * half * tangent, sign * tangent, np.pi * r**2, r) for sign in (1.0, -1.0)]
    return RingOpening(EndChoice(a, b, cuts[0], cuts[1], [], []), graph)


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


def ring_cut(mesh: trimesh.Trimesh, points, spoke_lengths, tips, branch_paths=()) -> RingCut:
    """How the extracted tube cut the closed ring ``mesh`` open.

    The surface left out is that of the faces between the tube's two end rings: beyond the planes of
    both (each normal to its end hub's edge, as the simulator builds it) and within two end radii of
    the gap (more: half the tips' distance apart).

    Args:
        mesh: the cleaned mesh the tube was extracted from [mesh units].
        points: the tube's hubs, shape (N, 3); spoke_lengths: shape (N, S).
        tips: where the tube ends, shape (2, 3).
        branch_paths: the side branches' paths found, each (k, 3).
    """
    pts = np.asarray(points, dtype=np.float64)
    tips = np.asarray(tips, dtype=np.float64)
    radius = np.asarray(spoke_lengths, dtype=np.float64).mean(axis=1)[[0, -1]]
    centres = np.asarray(mesh.triangles_center)
    beyond = np.ones(len(centres), dtype=bool)
    for hub, nxt in ((pts[0], pts[1]), (pts[-1], pts[-2])):
        out = (hub - nxt) / max(float(np.linalg.norm(hub - nxt)), 1e-300)
        beyond &= (centres - hub) @ out > 0.0
    mid = 0.5 * (tips[0] + tips[1])
    reach = 2.0 * radius.max() + 0.5 * float(np.linalg.norm(tips[0] - tips[1]))
    piece = beyond & (np.linalg.norm(centres - mid, axis=1) <= reach)
    area = np.asarray(mesh.area_faces)
    return RingCut(tips.copy(), float(area[piece].sum() / area.sum()), _rest_branches(mesh, piece, branch_paths))
