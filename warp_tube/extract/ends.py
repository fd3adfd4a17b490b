"""Where an extracted tube ends: the choice of its two ends, and its end rings.

Choice (in the voxel graph of :mod:`warp_tube.extract.distance_map`):

- An open boundary loop is *terminal* when the tube does not go on past it (:func:`is_terminal`):
  the inside voxels at a geodesic distance of 3 to 4 local radii from the loop form one connected
  piece (the tube leaving the loop in one direction). A loop in the side of a tube that goes on both
  ways (an opening where a branch was cut flush, a short branch stub, a hole) leaves two or more
  pieces there.
- A flat face that seals the tube where it was cut out of a longer one
  (:func:`warp_tube.extract.mesh_io.flat_cuts`) is an end of the mesh like a terminal open loop when
  it passes the same test and has the inside on one side only (a flat fold of a rough wall has it
  on both).
- Two or more terminal open loops: the tube's ends are the two of them farthest apart along the
  inside. One: it is one end, the other is the sealed cut farthest from it, or without one the
  inside point farthest from it. None, but sealed cuts: the same among the cuts (where the two
  farthest apart are nearer each other than half the inside's length, they close one end, e.g. two
  flat facets of one tip, and the other end is the inside point farthest from them). None of either (a
  closed mesh with rounded tips, or one with openings in its side only): the two ends of the
  longest geodesic, found by a double sweep from the widest point (the farthest-apart rule). The
  loops that are not ends are reported with their size.

End rings (on the centred line, :mod:`warp_tube.extract.sections`):

- at an open end the line runs to the loop's centre (the tube's *tip*) and is trimmed back to the
  first point whose cross-section is complete (every ray meets the wall), so that the end ring lies
  on the wall and not across the open end (an oblique cut leaves a short stretch open);
- at a closed end the line is continued straight along its tangent to the closed surface (the
  tip). A rounded tip is capped: the end hub is put where the simulator's cap, a dome of the end
  ring's spoke lengths (rings at polar angles ``(pi / 2)(1 - k / K)``,
  :func:`warp_tube.surface.topology.cap_ring_count`), lies closest to the mesh (about one radius in
  on a hemisphere). A flat cut (a segment cut out of a longer tube and sealed) is trimmed: a dome
  cannot follow it (the best misses a flat disc by 0.11 radii, an oblique one by more), so the end
  hub goes just inside the cut and the scene leaves that end open. On a rough wall (a scan's noise)
  the radius and the direction of the end are measured past the noise, and a flat cut is where the
  tube keeps its width up to the surface ahead (:func:`fit_closed_end`).

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
from .mesh_io import BoundaryLoop, FlatCut
from .polyline import arclength, point_at, resample_spline
from .queries import MeshQueries
from ..model.frames import spoke_directions
from .rough_wall import ROUGH, rough_cut_plane, straight_start, wall_noise
from .sections import RAYS, plane_basis, ring_hits

__all__ = [
    "EndChoice", "is_terminal", "choose_ends", "cut_closed_tail", "trim_open_end", "fit_closed_end", "settle_end",
]

log = logging.getLogger(__name__)

_SHELL = (3.0, 4.0)  # geodesic shell around a loop, in local radii, for the terminal test
_CAP_FIT = np.linspace(0.3, 1.5, 49)  # candidate distances of a closed end's hub from the tip, in end radii
_POLE_WEIGHT = 0.6  # the pole is one vertex, the cap rings S each: its distance counts this much
_CAP_TOLERANCE = 0.2  # a closed tip is capped where the best cap lies within this x end radius of it
_FLAT = 0.03  # a closed end is a flat cut where the surface ahead lies within this x end radius of a plane
_FLAT_REACH = 0.6  # ... over a disc of at least this x the tube's radius, where a cone of rays
_FLAT_CONE = 45.0  # ... up to this half-angle [degrees] (35 at least) reaches it
_CUT_MARGIN = 0.02  # a trimmed end ring stays this x end radius before the cut's plane
_RING_RATIO = 3.0  # an end ring's longest spoke is at most this x its shortest (no degenerate end ring)
_SAME_END = 0.5  # two sealed cuts closer than this x the inside's reach from one close one end


@dataclass(frozen=True)
class EndChoice:
    """The two end voxels of the tube, what closes them and the loops left over.

    Attributes:
        a, b: voxel indices of the ends in the distance map.
        end_a, end_b: the open loop or sealed flat cut at each end, or None for a closed tip.
        terminal: the terminal loops (open ends of the mesh).
        others: the loops that are not ends (openings in the wall, cut side branches, spare ends).
    """

    a: int
    b: int
    end_a: BoundaryLoop | FlatCut | None
    end_b: BoundaryLoop | FlatCut | None
    terminal: list[BoundaryLoop]
    others: list[BoundaryLoop]


def _nearest_voxel(dm: dmap.DistanceMap, tree: cKDTree, reach: np.ndarray, point: np.ndarray) -> int:
    return int(reach[tree.query(point)[1]])


def is_terminal(dm: dmap.DistanceMap, voxel: int, loop: BoundaryLoop | FlatCut) -> bool:
    """Whether the tube ends at ``loop``: the inside voxels at a geodesic distance of 3 to 4 local
    radii from the loop's voxel form at most one connected piece (two or more: the tube goes on
    both ways past the loop). The local radius is the larger of the loop's radius and the widest
    distance from the wall within two loop radii of the voxel. An opening in the wall less than
    three local radii from a closed tip leaves one piece too, and counts as an end.

    A flat cut is an end only where it closes the tube: no inside voxel within two of its radii
    (along the inside) of its voxel lies more than a voxel beyond its plane. A seal has the inside
    on one side only; a flat patch of the wall has it on both, e.g. a fold of a rough wall that
    lies in one plane (noise along normals that share a plane keeps a fold's vertices in it).
    """
    h = dm.voxel_size
    near = dijkstra(dm.length_graph, directed=False, indices=voxel, limit=2.0 * loop.radius + 2.0 * h)
    if isinstance(loop, FlatCut):
        side = (dm.points[np.isfinite(near)] - loop.centroid) @ loop.normal
        if (side > h).any() and (side < -h).any():
            return False  # the inside on both sides: a flat patch of the wall, not a seal
    r_loc = max(loop.radius, float(dm.dfb[np.isfinite(near)].max()))
    dist = dijkstra(dm.length_graph, directed=False, indices=voxel, limit=_SHELL[1] * r_loc + h)
    shell = np.flatnonzero((dist >= _SHELL[0] * r_loc) & (dist <= _SHELL[1] * r_loc))
    if len(shell) == 0:
        return True  # nothing that far: a short piece behind the loop
    _, label = connected_components(dm.length_graph[shell][:, shell], directed=False)
    return int((np.bincount(label) >= max(3, 0.05 * len(shell))).sum()) <= 1


def _reversed(p_a: np.ndarray, p_b: np.ndarray) -> bool:
    """Whether the tube from ``p_a`` to ``p_b`` (its two ends) runs backwards: its ends are taken in
    the order of their coordinates along the axis they lie farthest apart on. Which end a search
    reached first hangs on round-off (the two ways between them are equally long): taken as it
    came, a mesh and the same mesh saved again in another format, or with its vertices moved by a
    nanometre, gave a tube run the other way, its spokes and push turned with it."""
    d = np.asarray(p_b, dtype=np.float64) - np.asarray(p_a, dtype=np.float64)
    k = int(np.argmax(np.abs(d)))
    return bool(d[k] < 0.0)


def choose_ends(dm: dmap.DistanceMap, loops: list[BoundaryLoop], cuts: list[FlatCut] = ()) -> EndChoice:
    """The tube's two ends (see the module).

    Args:
        dm: the distance map of the inside.
        loops: the open loops large enough to be ends (open ends, openings, cut branches).
        cuts: flat faces that may seal a cut end (:func:`warp_tube.extract.mesh_io.flat_cuts`);
            a terminal one is a mesh end like a terminal open loop.
    """
    root = int(np.argmax(dm.dfb))
    d_root = dmap.shortest_tree(dm.length_graph, root)[0]
    reach = np.flatnonzero(np.isfinite(d_root))
    tree = cKDTree(dm.points[reach])
    cand = list(loops) + list(cuts)
    voxels = [_nearest_voxel(dm, tree, reach, lp.centroid) for lp in cand]
    terminal = [i for i, v in enumerate(voxels) if is_terminal(dm, v, cand[i])]
    open_ends = [i for i in terminal if isinstance(cand[i], BoundaryLoop)]
    sealed = [i for i in terminal if not isinstance(cand[i], BoundaryLoop)]

    def farthest_pair(idx):
        vox = [voxels[i] for i in idx]
        dist = np.stack([dmap.shortest_tree(dm.length_graph, c)[0][vox] for c in vox])
        i, j = np.unravel_index(int(np.argmax(np.where(np.isfinite(dist), dist, -1.0))), dist.shape)
        return idx[i], idx[j]

    def farthest_from(i, idx):
        """The candidate of ``idx`` farthest from candidate ``i``, or the farthest inside voxel."""
        d_i = dmap.shortest_tree(dm.length_graph, voxels[i])[0]
        d_i = np.where(np.isfinite(d_i), d_i, -1.0)
        if idx:
            k = max(idx, key=lambda k: d_i[voxels[k]])
            return voxels[k], cand[k]
        return int(np.argmax(d_i)), None

    # Open loops first (the issue of an end put in a blind bulge), then sealed cuts, then the
    # farthest-apart rule.
    pool = open_ends if len(open_ends) >= 2 else (sealed if not open_ends and len(sealed) >= 2 else None)
    if pool is not None:
        ia, ib = farthest_pair(pool)
        a, b, end_a, end_b = voxels[ia], voxels[ib], cand[ia], cand[ib]
        if pool is sealed:
            d_a = dmap.shortest_tree(dm.length_graph, a)[0]
            d_a = np.where(np.isfinite(d_a), d_a, -1.0)
            if d_a[b] < _SAME_END * d_a.max():  # two flat faces of one end (facets of one tip): the
                b, end_b = int(np.argmax(d_a)), None  # other end is the inside point farthest away
    elif open_ends or sealed:
        ia = (open_ends or sealed)[0]
        a, end_a = voxels[ia], cand[ia]
        b, end_b = farthest_from(ia, sealed if open_ends else [])
    else:
        a = int(reach[np.argmax(d_root[reach])])
        d_a = dmap.shortest_tree(dm.length_graph, a)[0]
        b = int(np.argmax(np.where(np.isfinite(d_a), d_a, -1.0)))
        end_a = end_b = None
    if _reversed(dm.points[a], dm.points[b]):
        a, b, end_a, end_b = b, a, end_b, end_a
    used = [e for e in (end_a, end_b) if e is not None]
    return EndChoice(
        a, b, end_a, end_b, [cand[i] for i in terminal if isinstance(cand[i], BoundaryLoop)],
        [lp for lp in loops if not any(lp is u for u in used)],
    )


def cut_closed_tail(path: np.ndarray, d: np.ndarray, h: float, rough: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Cut the start of a voxel path that ends at a closed tip while it runs off-centre.

    A most-centred path to the farthest voxel of a closed end leaves the axis near the end to reach
    the wall; its points before the distance from the wall first reaches 80 % of the largest
    within three such distances further on are cut (at most a third of the path).

    On a rough wall (``rough``) the distance from the wall is that of the deepest inward spike near
    the point, which near the wall says nothing of the tube's width, and the farthest voxel of a
    tip lies at the end of a fold of it: a channel about as wide as the noise and many times
    longer, which the test at its own width takes for a thin tube. There the points look at least
    three times the path's median distance from the wall further on (the width its axis keeps).

    Args:
        path: voxel centres, shape (k, 3); d: their distances from the wall, shape (k,); h: voxel edge.
        rough: whether the tube's wall is rough (:class:`warp_tube.extract.scale.TubeScale`).

    Returns:
        ``(path, d)`` without the cut points.
    """
    s = arclength(path)
    floor = float(np.median(d)) if rough else 0.0
    i = 0
    for i in range(len(path) // 3):
        win = (s >= s[i]) & (s <= s[i] + 3.0 * max(d[i], floor) + 2.0 * h)
        if d[i] >= 0.8 * d[win].max():
            break
    return path[i:], d[i:]


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
    ok = [_complete(q, *point_at(line, s, x), diag) for x in probe]
    if ok[0] or not any(ok):
        return line, 0.0
    k = int(np.argmax(ok))
    lo, hi = probe[k - 1], probe[k]
    while hi - lo > 0.01 * reach:
        mid = 0.5 * (lo + hi)
        if _complete(q, *point_at(line, s, mid), diag):
            hi = mid
        else:
            lo = mid
    start, _ = point_at(line, s, hi)
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


def _best_cap(q: MeshQueries, ext: np.ndarray, r_end: float, diag: float, spokes: int):
    """Arclength from ``ext[0]`` (the tip) along ``ext`` of the end hub whose cap fits best (None: no
    position has a complete ring) and the cap's score there [mesh units].

    The cap's axis is the line's outward tangent there. The score of a position is the larger of
    the largest distance of a cap-ring point from the mesh and :data:`_POLE_WEIGHT` times the pole's.
    """
    s = arclength(ext)
    best, best_score = None, np.inf
    for c in _CAP_FIT * max(r_end, 1e-12):
        hub, tan = point_at(ext, s, c)
        r, s_ = plane_basis((-tan)[None])
        hits, valid, _ = ring_hits(q, hub[None], spoke_directions(r, s_, spokes), diag)
        if not valid.all():
            continue
        dist = q.distance(_cap_points(hub, -tan, hits[0], spokes), diag)
        score = max(float(dist[1:].max()), _POLE_WEIGHT * float(dist[0]))
        if score < best_score:
            best, best_score = c, score
    return best, best_score


def _cut_plane(q: MeshQueries, hub: np.ndarray, out: np.ndarray, r_end: float, diag: float, r_tube: float | None = None):
    """The plane of a flat cut closing the tube ahead of ``hub`` (looking along unit ``out``), as
    ``(point, unit normal)``, or None when the closed surface there is not flat: the hits of rays
    in a cone around ``out`` lie within 3 % of the end radius of their best plane. The cone is 35
    degrees wide, or wider (up to :data:`_FLAT_CONE`) until it meets the surface ahead at :data:`_FLAT_REACH` times
    ``r_tube`` (the tube's radius behind the end) from its axis: a hub near a rounded tip sees only
    its top, which is flat where the tip is a staircase of voxels."""
    ahead = float(q.rays(q.closed, hub[None], out[None], diag)[0])
    if ahead <= 0.0:
        return None
    wide = np.arctan2(_FLAT_REACH * max(r_tube or 0.0, r_end), ahead)
    wide = float(np.clip(wide, np.radians(35.0), np.radians(_FLAT_CONE)))
    r, s = plane_basis(out[None])
    dirs = [out]
    for angle in (wide * 20.0 / 35.0, wide):
        ring = spoke_directions(r, s, 8)[0]
        dirs += list(np.cos(angle) * out + np.sin(angle) * ring)
    dirs = np.asarray(dirs)
    t = q.rays(q.closed, np.repeat(hub[None], len(dirs), axis=0), dirs, diag)
    if (t <= 0.0).any():
        return None
    pts = hub + t[:, None] * dirs
    centre = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - centre)
    normal = vt[2] if np.dot(vt[2], out) > 0.0 else -vt[2]
    if np.abs((pts - centre) @ normal).max() > _FLAT * r_end:
        return None
    return centre, normal


def _tube_radius(q: MeshQueries, line: np.ndarray, r_end: float, diag: float) -> float:
    """The tube's radius behind the closed end where ``line`` starts: the largest distance from the
    closed surface of the line's points within three ``r_end`` of its start (at least ``r_end``)."""
    near = line[arclength(line) <= 3.0 * r_end]
    return max(r_end, float(q.distance(near, diag).max())) if len(near) else r_end


def _extend(q: MeshQueries, line: np.ndarray, r_end: float, diag: float, cut: FlatCut | None):
    """The line continued beyond its start along the quadratic through its first four points (so a
    bend goes on bending) until it meets the closed surface, or the plane of ``cut``; where that
    meets nothing within three end radii, straight along the tangent at the start.

    Returns:
        ``(extended line from the tip inwards (k, 3), tip (3,))``, or ``(line, None)`` when nothing
        is met.
    """
    if len(line) >= 4:
        s4 = arclength(line[:4])
        coef = np.polyfit(s4, line[:4], 2)  # rows: s^2, s, 1
    else:  # a straight continuation: p(sigma) = line[0] - sigma * out for sigma < 0
        out = (line[0] - line[1]) / max(np.linalg.norm(line[0] - line[1]), 1e-300)
        coef = np.stack([np.zeros(3), -out, line[0]])
    step = 0.05 * max(r_end, 1e-12)
    prev = line[0]
    beyond = []
    for k in range(1, 61):
        sigma = -k * step
        p = coef[0] * sigma**2 + coef[1] * sigma + coef[2]
        seg = p - prev
        length = float(np.linalg.norm(seg))
        if cut is not None:
            a, b = float(np.dot(prev - cut.centroid, cut.normal)), float(np.dot(p - cut.centroid, cut.normal))
            if a * b <= 0.0 and a != b:
                tip = prev + (a / (a - b)) * seg
                return np.concatenate([tip[None], np.asarray(beyond[::-1]).reshape(-1, 3), line]), tip
        elif length > 0.0:
            t = q.rays(q.closed, prev[None], (seg / length)[None], length)[0]
            if t > 0.0:
                tip = prev + t * seg / length
                return np.concatenate([tip[None], np.asarray(beyond[::-1]).reshape(-1, 3), line]), tip
        beyond.append(p)
        prev = p
    # The quadratic turned away without meeting the surface: go straight along the end's tangent.
    out = -coef[1] / max(np.linalg.norm(coef[1]), 1e-300)
    t = q.rays(q.closed, line[0][None], out[None], diag)[0]
    if t <= 0.0:
        return line, None
    tip = line[0] + t * out
    return np.concatenate([tip[None], line]), tip


def fit_closed_end(q: MeshQueries, line: np.ndarray, diag: float, spokes: int, cut: FlatCut | None = None,
                   own: bool = False):
    """End the tube at the closed end of ``line`` (its start): capped at a round tip, trimmed at a cut.

    The line is continued beyond its start along the quadratic through its first four points to the
    closed surface (or ``cut``'s plane): that is the tube's tip. Where the surface ahead is a flat cut
    (``cut``, or found by :func:`_cut_plane`), the end hub goes where the ring normal to the line first lies wholly
    inside the cut (every spoke end at least 2 % of the end radius before its plane): the scene
    leaves that end open (``"cut"``). Elsewhere (a rounded tip) it goes where the simulator's cap
    fits: for hubs at :data:`_CAP_FIT` end radii from the tip along the continued line, the cap is
    built on the hub's ring (``spokes`` rays in the plane normal to the line) and the hub whose
    ring is complete with the best cap (:func:`_best_cap`; a hemisphere puts it one radius in) is
    taken (``"closed"``); where even that cap misses the tip by more than :data:`_CAP_TOLERANCE`
    end radii, the end stays there but is left open (``"cut"``).

    On a rough wall (noise round the line over :data:`~warp_tube.extract.rough_wall.ROUGH` of its
    radius, :func:`~warp_tube.extract.rough_wall.wall_noise`; a clean mesh's is 0.006 or less, and is
    left as above) the wall's nearest point is its deepest inward spike (0.6 radii from the axis at
    noise of 0.1 radii) and the centred line's first points wander by the noise: the end radius is
    the median ray of rings round the line's first radii instead, the line's first 1.5 such radii
    are straightened (:func:`~warp_tube.extract.rough_wall.straight_start`), and a flat cut is told
    from a rounded tip by the tube's width before it
    (:func:`~warp_tube.extract.rough_wall.rough_cut_plane`). Else such a tip's cap
    positions stopped short of a hemisphere's centre and its tolerance shrank by as much: it was
    left open (5 of 8 ends at noise of 0.1 radii, most at 0.2).

    ``own``: ``cut`` is known to close this end (a closed ring's gap, whose line runs round to the
    plane's far side): it is kept wherever the line ends.

    Returns:
        ``(line (k, 3) starting at the end hub, tip (3,), kind, seal)``: ``kind`` "closed" or "cut",
        ``seal`` the cut's ``(point, outward unit normal, radius)`` or None; the line unchanged when no
        ray reaches the closed surface or no position has a complete ring.
    """
    r_end = float(q.distance(line[:1], diag)[0])
    noise, r_wall = wall_noise(q, line, diag)
    rough = noise > ROUGH * r_wall
    if rough:  # the nearest point of a rough wall is the tip of its deepest inward spike
        r_end = max(r_end, r_wall)
        line = straight_start(line, 1.5 * r_wall)
    if cut is not None and not own and \
            np.dot(line[0] - cut.centroid, cut.normal) * np.dot(line[-1] - cut.centroid, cut.normal) <= 0:
        cut = None  # the line starts on the far side of the cut's plane: it does not close this end
    ext, tip = _extend(q, line, r_end, diag, cut)
    if tip is None:
        return line, line[0].copy(), "closed", None
    s = arclength(ext)
    out = (ext[0] - ext[1]) / max(np.linalg.norm(ext[0] - ext[1]), 1e-300)
    if cut is not None:
        normal = cut.normal if np.dot(cut.normal, out) > 0.0 else -cut.normal
        seal = (cut.centroid, normal, max(cut.radius, r_end))
    else:
        plane = _cut_plane(q, line[0], out, r_end, diag, _tube_radius(q, line, r_end, diag))
        seal = None if plane is None else (*plane, 1.5 * r_end)
    if seal is None and rough:
        plane = rough_cut_plane(q, line[0], out, r_wall, diag)
        seal = None if plane is None else (*plane, 1.5 * r_end)
    if seal is not None:
        best = _inside_cut(q, ext, s, seal[:2], r_end, diag, spokes)
        kind = "cut"
    else:
        best, score = _best_cap(q, ext, r_end, diag, spokes)
        # A tip the cap cannot follow (flattened, oblique, lopsided) is trimmed like a cut instead.
        kind = "closed" if score <= _CAP_TOLERANCE * r_end else "cut"
    if best is None:
        return line, tip, kind, seal
    hub, _ = point_at(ext, s, best)
    return np.concatenate([hub[None], ext[s > best]]), tip, kind, seal


def _inside_cut(q: MeshQueries, ext, s, cut, r_end: float, diag: float, spokes: int):
    """Least arclength from the tip along ``ext`` at which the hub's ring (normal to the line) is
    complete, not degenerate (longest ray at most :data:`_RING_RATIO` times the shortest) and lies
    wholly before the cut plane, refined by bisection to 1 % of ``r_end``; None if none within two
    end radii."""
    point, normal = cut

    def inside(x: float) -> bool:
        hub, tan = point_at(ext, s, x)
        r, s_ = plane_basis(tan[None])
        dirs = spoke_directions(r, s_, max(spokes, RAYS))[0]
        origins = np.repeat(hub[None], len(dirs), axis=0)
        hits = q.rays(q.wall, origins, dirs, diag)  # next to the cut the distance from the wall
        if (hits <= 0.0).any() or (q.rays(q.closed, origins, dirs, diag) < hits - 1e-5 * diag).any():
            return False  # is small, so ring_hits' bound by it does not apply: any wall hit counts
        if hits.max() > _RING_RATIO * hits.min():
            return False  # a degenerate ring: along the cut, or into a corner
        ends = hub + hits[:, None] * dirs
        return bool(((ends - point) @ normal).max() <= -_CUT_MARGIN * r_end)

    probe = np.linspace(_CUT_MARGIN * r_end, min(2.0 * r_end, s[-1]), 21)
    ok = [inside(x) for x in probe]
    if not any(ok):
        return None
    k = int(np.argmax(ok))
    if k == 0:
        return probe[0]
    lo, hi = probe[k - 1], probe[k]
    while hi - lo > 0.01 * r_end:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if inside(mid) else (mid, hi)
    return hi


def _cut_line(line: np.ndarray, s: np.ndarray, x: float) -> np.ndarray:
    """``line`` without its first ``x`` of arclength (``s``: its arclengths)."""
    start, _ = point_at(line, s, x)
    return np.concatenate([start[None], line[s > x]])


def settle_end(q: MeshQueries, line: np.ndarray, hubs: int, diag: float, spokes: int, seal=None) -> np.ndarray:
    """Trim the start of the axis ``line`` (an open or cut end) until the end ring of ``hubs`` hubs fits.

    The simulator's end ring is normal to the end hub's edge, not to the axis, so on a bent end it
    can lean out of an open end or through a cut. The line is trimmed, by up to one and a half hub
    spacings, until the first of ``hubs`` hubs spread along it (:func:`~warp_tube.extract.polyline.resample_spline`)
    has a ring, normal to its edge, whose every ray meets the tube's wall as a section of it
    (:func:`~warp_tube.extract.sections.ring_hits`; and, with a ``seal``
    ``(point, outward normal, radius)``, whose every spoke end stays 2 % of the end radius before its
    plane); bisection to 1 % of the spacing. Unchanged when it fits already or nothing does.

    Returns:
        The line, shape (k, 3).
    """
    s = arclength(line)
    reach = 1.5 * s[-1] / max(hubs - 1, 1)
    r_end = float(q.distance(line[:1], diag)[0])

    def fits(x: float) -> bool:
        pts = resample_spline(_cut_line(line, s, x), hubs)
        axis = pts[0] - pts[1]
        axis = axis / max(np.linalg.norm(axis), 1e-300)
        r, s_ = plane_basis(axis[None])
        dirs = spoke_directions(r, s_, max(spokes, RAYS))
        hits, valid, _ = ring_hits(q, pts[:1], dirs, diag)
        if not valid.all():
            return False
        if seal is not None:
            ends = pts[0] + hits[0][:, None] * dirs[0]
            return bool(((ends - seal[0]) @ seal[1]).max() <= -_CUT_MARGIN * r_end)
        return True

    if hubs < 3 or fits(0.0):
        return line
    probe = np.linspace(0.0, reach, 11)[1:]
    ok = [fits(x) for x in probe]
    if not any(ok):
        return line
    k = int(np.argmax(ok))
    lo, hi = (probe[k - 1] if k else 0.0), probe[k]  # lo does not fit, hi does
    while hi - lo > 0.01 * reach:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    return _cut_line(line, s, hi)
