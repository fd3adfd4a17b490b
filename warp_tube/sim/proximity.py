"""Distant parts of tubes that come into contact (contact itself is not modelled).

Two centerline points are *in contact* when their distance is below the sum of their radii (the
tube surfaces meet) while they are *distant* along the tube: on different tubes, or more than
``pi / 2 x (r_i + r_j)`` apart in rest arclength on the same tube. (On a straight tube or a smooth
bend, points that close in arclength are never that close in space; a tube folded into a U of bend
radius below its own radius, or looping onto itself, is.)
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["ContactMonitor"]

#: models up to this many points check all their distant pairs directly each frame
SMALL = 128


class ContactMonitor:
    """Finds contacts between distant parts of a model's tubes, for one world's positions.

    Args:
        host: the TubeModel's host dict (rest positions, radii, tube starts) [m].
    """

    def __init__(self, host: dict):
        rest = host["node_rest_q"]
        start = host["tube_node_start"]
        self.radius = host["node_radius"]
        self.tube = np.repeat(np.arange(len(start) - 1), np.diff(start))
        seg = np.linalg.norm(np.diff(rest, axis=0), axis=1)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        self.arc = arc - arc[start[:-1]][self.tube]  # arclength from each tube's start
        self.max_radius = float(self.radius.max())
        n = len(rest)
        # Small models: every pair that could ever count, fixed once (distant along the tube);
        # per frame only their distances. Large ones: a k-d tree per frame.
        self.pairs = None
        if n <= SMALL:
            i, j = np.triu_indices(n, 1)
            rsum = self.radius[i] + self.radius[j]
            keep = (self.tube[i] != self.tube[j]) | (np.abs(self.arc[i] - self.arc[j]) > 0.5 * np.pi * rsum)
            self.pairs = (i[keep], j[keep], rsum[keep])

    def closest(self, q: np.ndarray):
        """The contact with the deepest overlap, or None.

        Args:
            q: positions [m], shape (node_count, 3).

        Returns:
            ``(i, j, gap)``: node indices and ``distance - (r_i + r_j)`` [m] (negative), or None.
        """
        if self.pairs is not None:
            i, j, rsum = self.pairs
            gap = np.linalg.norm(q[i] - q[j], axis=1) - rsum
            k = int(np.argmin(gap)) if len(gap) else -1
            return (int(i[k]), int(j[k]), float(gap[k])) if k >= 0 and gap[k] < 0.0 else None
        pairs = cKDTree(q).query_pairs(2.0 * self.max_radius, output_type="ndarray")
        if len(pairs) == 0:
            return None
        i, j = pairs[:, 0], pairs[:, 1]
        rsum = self.radius[i] + self.radius[j]
        dist = np.linalg.norm(q[i] - q[j], axis=1)
        distant = (self.tube[i] != self.tube[j]) | (np.abs(self.arc[i] - self.arc[j]) > 0.5 * np.pi * rsum)
        hit = distant & (dist < rsum)
        if not hit.any():
            return None
        k = int(np.argmin(np.where(hit, dist - rsum, np.inf)))
        return int(i[k]), int(j[k]), float(dist[k] - rsum[k])
