"""Where an extracted tube ends: the choice of its two ends, and its end rings.

Choice (in the voxel graph of :mod:`warp_tube.extract.distance_map`):

- An open boundary loop is *terminal* when the tube does not go on past it (:func:`is_terminal`):
  the inside voxels at a geodesic distance of 3 to 4 local radii from the loop form one connected
  piece (the tube leaving the loop in one direction). A loop in the side of a tube that goes on both
  ways (an opening where a branch was cut flush, a short branch stub, a hole) leaves two or more
  pieces there.
- Two or more terminal loops: the ends are the two of them farthest apart along the inside. One:
  it is one end, the other is the inside point farthest from it. None (a closed mesh, or one with
  openings in its side only): the two ends of the longest geodesic, found by a double sweep from the
  widest point (the farthest-apart rule). The loops that are not ends are reported with their size.

End rings (on the centred line, :mod:`warp_tube.extract.sections`):

- at an open end the line runs to the loop's centre (the tube's *tip*) and is trimmed back to the
  first point whose cross-section is complete (every ray meets the wall), so that the end ring lies
  on the wall and not across the open end (an oblique cut leaves a short stretch open);
- at a closed end the line is continued straight along its tangent to the closed surface (the
  tip), and the end hub is put where the simulator's rounded cap, a dome of the end ring's spoke
  lengths (rings at polar angles ``(pi / 2)(1 - k / K)``, :func:`warp_tube.surface.topology.cap_ring_count`),
  lies closest to the mesh (a flat cap puts it about 0.85 radii in, a round tip about one radius).

Lengths are in the mesh's units.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from . import distance_map as dmap
from ..surface.topology import cap_ring_count
from .mesh_io import BoundaryLoop
from .polyline import arclength
from .queries import MeshQueries
from ..model.frames import spoke_directions
from .sections import RAYS, plane_basis, ring_hits

__all__ = ["EndChoice", "is_terminal", "choose_ends", "cut_closed_tail", "trim_open_end", "fit_closed_end"]

log = logging.getLogger(__name__)

_SHELL = (3.0, 4.0)  # geodesic shell around a loop, in local radii, for the terminal test
_CAP_FIT = np.linspace(0.3, 1.5, 49)  # candidate distances of a closed end's hub from the tip, in end radii
_POLE_WEIGHT = 0.6  # the pole is one vertex, the cap rings S each: its distance counts this much


@dataclass(frozen=True)
class EndChoice:
    """The two end voxels of the tube, their loops (None: closed end) and the loops left over.

    Attributes:
        a, b: voxel indices of the ends in the distance map.
        loop_a, loop_b: the open loops at the ends, or None for closed ends.
        terminal: the terminal loops (open ends of the mesh).
        others: the loops that are not ends (openings in the wall, cut side branches, spare ends).
    """

    a: int
    b: int
    loop_a: BoundaryLoop | None
    loop_b: BoundaryLoop | None
    terminal: list[BoundaryLoop]
    others: list[BoundaryLoop]


def _nearest_voxel(dm: dmap.DistanceMap, tree: cKDTree, reach: np.ndarray, point: np.ndarray) -> int:
    return int(reach[tree.query(point)[1]])


def is_terminal(dm: dmap.DistanceMap, voxel: int, loop: BoundaryLoop) -> bool:
    """Whether the tube ends at ``loop``: the inside voxels at a geodesic distance of 3 to 4 local
    radii from the loop's voxel form at most one connected piece (two or more: the tube goes on
    both ways past the loop). The local radius is the larger of the loop's radius and the widest
    distance from the wall within two loop radii of the voxel. An opening in the wall less than
    three local radii from a closed tip leaves one piece too, and counts as an end.
    """
    h = dm.voxel_size
    near = dijkstra(dm.length_graph, directed=False, indices=voxel, limit=2.0 * loop.radius + 2.0 * h)
    r_loc = max(loop.radius, float(dm.dfb[np.isfinite(near)].max()))
    dist = dijkstra(dm.length_graph, directed=False, indices=voxel, limit=_SHELL[1] * r_loc + h)
    shell = np.flatnonzero((dist >= _SHELL[0] * r_loc) & (dist <= _SHELL[1] * r_loc))
    if len(shell) == 0:
        return True  # nothing that far: a short piece behind the loop
    _, label = connected_components(dm.length_graph[shell][:, shell], directed=False)
    return int((np.bincount(label) >= max(3, 0.05 * len(shell))).sum()) <= 1


def choose_ends(dm: dmap.DistanceMap, loops: list[BoundaryLoop]) -> EndChoice:
    """The tube's two ends (see the module).

    Args:
        dm: the distance map of the inside.
        loops: the open loops large enough to be ends (open ends, openings, cut branches).
    """
    root = int(np.argmax(dm.dfb))
    d_root = dmap.shortest_tree(dm.length_graph, root)[0]
    reach = np.flatnonzero(np.isfinite(d_root))
    tree = cKDTree(dm.points[reach])
    voxels = [_nearest_voxel(dm, tree, reach, lp.centroid) for lp in loops]
    terminal = [i for i, v in enumerate(voxels) if is_terminal(dm, v, loops[i])]
    if len(terminal) >= 2:
        cand = [voxels[i] for i in terminal]
        dist = np.stack([dmap.shortest_tree(dm.length_graph, c)[0][cand] for c in cand])
        i, j = np.unravel_index(int(np.argmax(np.where(np.isfinite(dist), dist, -1.0))), dist.shape)
        ia, ib = terminal[i], terminal[j]
        a, b, loop_a, loop_b = voxels[ia], voxels[ib], loops[ia], loops[ib]
    elif len(terminal) == 1:
        ia = terminal[0]
        a, loop_a = voxels[ia], loops[ia]
        d_a = dmap.shortest_tree(dm.length_graph, a)[0]
        b, loop_b = int(np.argmax(np.where(np.isfinite(d_a), d_a, -1.0))), None
    else:
        a = int(reach[np.argmax(d_root[reach])])
        d_a = dmap.shortest_tree(dm.length_graph, a)[0]
        b = int(np.argmax(np.where(np.isfinite(d_a), d_a, -1.0)))
        loop_a = loop_b = None
    used = [lp for lp in (loop_a, loop_b) if lp is not None]
    return EndChoice(
        a, b, loop_a, loop_b, [loops[i] for i in terminal], [lp for lp in loops if not any(lp is u for u in used)]
    )


def cut_closed_tail(path: np.ndarray, d: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Cut the start of a voxel path that ends at a closed tip while it runs off-centre.

    A most-centred path to the farthest voxel of a closed end leaves the axis near the end to reach
    the wall; its points before the distance from the wall first reaches 80 % of the largest
    within three such distances further on are cut (at most a third of the path).

    Args:
        path: voxel centres, shape (k, 3); d: their distances from the wall, shape (k,); h: voxel edge.

    Returns:
        ``(path, d)`` without the cut points.
    """
    s = arclength(path)
    i = 0
    for i in range(len(path) // 3):
        win = (s >= s[i]) & (s <= s[i] + 3.0 * d[i] + 2.0 * h)
        if d[i] >= 0.8 * d[win].max():
            break
    return path[i:], d[i:]


def _point_at(line: np.ndarray, s: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Point and unit tangent of a polyline at arclength ``sigma`` from its start (clamped)."""
    sigma = float(np.clip(sigma, 0.0, s[-1]))
    k = int(np.clip(np.searchsorted(s, sigma, side="right") - 1, 0, len(line) - 2))
    w = (sigma - s[k]) / max(s[k + 1] - s[k], 1e-300)
    t = line[k + 1] - line[k]
    return line[k] + w * t, t / max(np.linalg.norm(t), 1e-300)


def _complete(q: MeshQueries, point: np.ndarray, tangent: np.ndarray, diag: float) -> bool:
    r, s = plane_basis(tangent[None])
    _, valid, _ = ring_hits(q, point[None], spoke_directions(r, s, RAYS), diag)
    return bool(valid.all())


def trim_open_end(q: MeshQueries, line: np.ndarray, diag: float, reach: float) -> tuple[np.ndarray, float]:
    """Cut the start of ``line`` (which begins at an open loop's centre) back to the first point
    whose cross-section normal to the line is complete, searched within ``reach`` of the start and
    refined by bisection to 1 % of ``reach``.

    Returns:
        ``(line (k, 3), trimmed length)``; the line is unchanged when its first point's section is
        complete or no point within ``reach`` has one.
    """
    s = arclength(line)
    probe = np.linspace(0.0, min(reach, s[-1]), 9)
    ok = [_complete(q, *_point_at(line, s, x), diag) for x in probe]
    if ok[0] or not any(ok):
        return line, 0.0
    k = int(np.argmax(ok))
    lo, hi = probe[k - 1], probe[k]
    while hi - lo > 0.01 * reach:
        mid = 0.5 * (lo + hi)
        if _complete(q, *_point_at(line, s, mid), diag):
            hi = mid
        else:
            lo = mid
    start, _ = _point_at(line, s, hi)
    rest = line[s > hi]
    return np.concatenate([start[None], rest]), hi


def _cap_points(hub: np.ndarray, tangent: np.ndarray, lengths: np.ndarray, spokes: int) -> np.ndarray:
    """The simulator's cap on a hub with outward unit ``tangent``: cap rings and pole, shape (k, 3)."""
    r, s = plane_basis(tangent[None])
    u = spoke_directions(r, s, spokes)[0]
    big_k = cap_ring_count(spokes)
    pts = [hub + lengths.mean() * tangent]
    for k in range(1, big_k):
        beta = 0.5 * np.pi * (1.0 - k / big_k)
        pts.append(hub + lengths[:, None] * (np.cos(beta) * tangent + np.sin(beta) * u))
    return np.vstack(pts)


def fit_closed_end(q: MeshQueries, line: np.ndarray, diag: float, spokes: int):
    """Place the closed end of ``line`` (its start) where the simulator's cap fits the mesh.

    The line is continued straight along its first segment's direction (outwards) to the closed
    surface: that hit is the tube's tip. For hubs at :data:`_CAP_FIT` end radii from the tip along
    the continued line, the cap is built on the hub's ring (``spokes`` rays in the plane normal to
    the line) and the hub whose ring is complete and whose cap lies nearest the mesh is taken: the
    least of the largest distance of a cap-ring point and :data:`_POLE_WEIGHT` times the pole's (on a
    flat cap this puts the hub 0.82 radii in, its cap rings within 0.11 radii of the mesh and the
    pole 0.18 radii beyond it).

    Returns:
        ``(line (k, 3) starting at the end hub, tip (3,))``, or the line unchanged and its first
        point when no ray reaches the closed surface.
    """
    if len(line) >= 4:  # the outward tangent at the end, from a quadratic through the first 4 points
        coef = np.polyfit(arclength(line[:4]), line[:4], 2)  # rows: s^2, s, 1
        out = -coef[1]
    else:
        out = line[0] - line[1]
    out = out / max(np.linalg.norm(out), 1e-300)
    t = q.rays(q.closed, line[0][None], out[None], diag)[0]
    if t <= 0.0:
        return line, line[0].copy()
    tip = line[0] + t * out
    ext = np.concatenate([tip[None], line])  # from the tip inwards
    s = arclength(ext)
    r_end = float(q.distance(line[:1], diag)[0])
    best, best_score = None, np.inf
    for c in _CAP_FIT:
        hub, tan = _point_at(ext, s, c * max(r_end, 1e-12) + 0.0)
        r, s_ = plane_basis((-tan)[None])
        hits, valid, _ = ring_hits(q, hub[None], spoke_directions(r, s_, spokes), diag)
        if not valid.all():
            continue
        dist = q.distance(_cap_points(hub, -tan, hits[0], spokes), diag)
        score = max(float(dist[1:].max()), _POLE_WEIGHT * float(dist[0]))
        if score < best_score:
            best, best_score = c * r_end, score
    if best is None:
        return line, tip
    hub, _ = _point_at(ext, s, best)
    return np.concatenate([hub[None], ext[s > best]]), tip
