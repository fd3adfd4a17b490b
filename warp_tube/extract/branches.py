"""Side branches of an extracted tube: parts of the inside that the main centerline leaves out.

Two kinds are found, both relative to the main tube's surface (the main centerline with a cover
radius of 1.25 x its largest spoke per point for voxels, 1 x for loop centroids):

- branches inside the mesh: voxels of the distance map whose geodesic distance from the main
  centerline exceeds the cover by more than the branch's own diameter (so a bulge or a haustral
  fold is not a branch). The branch's centre path is the most-centred path from its farthest voxel
  back to the main centerline. One connected region of such voxels is one side branch, with any
  branches of its own; a region whose tip lies within the tube's radius of a larger one's is the
  same branch (a short stub's two flanks leave the cover before its middle does).
- cut branches: open boundary loops (of end size) that are not the tube's ends and whose centroid
  lies farther from the centerline than the wall (median spoke length): a branch stub cut off the
  mesh. A loop nearer than that is an opening in the wall where a branch was cut flush; it is
  logged, not reported.

Lengths are in the mesh's units.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from . import distance_map as dmap
from .mesh_io import BoundaryLoop
from .polyline import arclength, resample, smooth

__all__ = ["FoundBranch", "find_branches"]

log = logging.getLogger(__name__)

_TOUCH = 1.75  # voxel sizes: neighbouring voxels, corners too (sqrt(3)), are this close


@dataclass(frozen=True)
class FoundBranch:
    """A side branch before hubs are chosen.

    Attributes:
        junction: index of the main line point where the branch's centre path meets it.
        length: centre-path length from the junction to the tip [mesh units].
        path: points of the branch beyond the main tube's cover [mesh units], shape (k, 3): its
            inside voxels, or for a cut branch points from the cover to the loop centroid.
        kind: "inside" (the mesh holds the branch) or "cut" (an open loop next to the tube).
    """

    junction: int
    length: float
    path: np.ndarray
    kind: str


def find_branches(
    dm: dmap.DistanceMap,
    voxel_path: np.ndarray,
    line: np.ndarray,
    cover: np.ndarray,
    wall: np.ndarray,
    loops: list[BoundaryLoop],
    max_branches: int = 8,
) -> list[FoundBranch]:
    """Side branches of the tube whose centre line is ``line``.

    Args:
        dm: the distance map the main path was found in.
        voxel_path: voxel indices of the main path, shape (k,).
        line: main centerline points [mesh units], shape (n, 3).
        cover: largest radius of the main tube at each line point [mesh units], shape (n,); voxels
            count as the main tube's within 1.25 times it.
        wall: median radius of the main tube at each line point [mesh units], shape (n,).
        loops: open loops that are not the tube's ends (candidates for cut branches).
        max_branches: stop after this many.
    """
    h = dm.voxel_size
    line_tree = cKDTree(line)
    _, near = line_tree.query(dm.points[voxel_path])
    node_cover = np.zeros(dm.count)
    node_cover[voxel_path] = 1.25 * cover[near]
    junction_of = dict(zip(voxel_path.tolist(), near.tolist()))
    dist, _, src = dmap.shortest_tree(dm.length_graph, voxel_path)
    fin = np.isfinite(dist)
    excess = np.full(dm.count, -np.inf)
    excess[fin] = dist[fin] - node_cover[src[fin]]
    out_nodes = np.flatnonzero(excess > 0.0)
    found: list[FoundBranch] = []
    if len(out_nodes):
        # Each connected region outside the cover is one candidate: a branch (with any branches of
        # its own) or a bulge.
        sub = dm.length_graph[out_nodes][:, out_nodes]
        count, label = connected_components(sub, directed=False)
        tips = np.full(count, -1)
        best = np.full(count, -np.inf)
        np.maximum.at(best, label, excess[out_nodes])
        is_best = excess[out_nodes] >= best[label]
        tips[label[is_best]] = out_nodes[is_best]
        cpred = None
        tips_found = []  # the tip of each branch found inside
        for k in np.argsort(-best):
            if len(found) >= max_branches or best[k] <= 3.0 * h:
                break
            region = out_nodes[label == k]
            r_b = float(np.median(dm.dfb[region]))
            if best[k] <= 2.0 * r_b + h:
                continue  # a bulge: it does not reach a diameter beyond the tube's surface
            tip = dm.points[int(tips[k])]
            near = float(wall[line_tree.query(tip)[1]]) + _TOUCH * h  # the tube's radius there
            if any(np.linalg.norm(tip - p) <= near for p in tips_found):
                continue  # its tip beside a larger region's: two flanks of one stub, which leave the cover before its middle
            tips_found.append(tip)
            if cpred is None:
                _, cpred, _ = dmap.shortest_tree(dm.centred_graph, voxel_path)
            bpath = dmap.trace_path(cpred, int(tips[k]))
            pts = dm.points[bpath]
            length = float(arclength(smooth(resample(pts, max(3, len(pts))), 1.0))[-1])
            junction = junction_of.get(int(bpath[0]), int(line_tree.query(pts[0])[1]))
            found.append(FoundBranch(int(junction), length, dm.points[region], "inside"))
    for lp in loops:
        if len(found) >= max_branches:
            break
        if any(len(b.path) and np.min(np.linalg.norm(b.path - lp.centroid, axis=1)) <= lp.radius + 2.0 * h
               for b in found):
            continue
        d, j = line_tree.query(lp.centroid)
        if d <= wall[j]:
            log.info("opening in the wall (radius %.4g) at %.4g from the centerline: a branch cut flush", lp.radius, d)
            continue
        u = (lp.centroid - line[j]) / d
        seg = line[j] + u * np.linspace(wall[j], d, 4)[:, None]
        found.append(FoundBranch(int(j), float(d), seg, "cut"))
    return found
