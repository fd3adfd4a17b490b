"""Contact between distant parts of tubes, found on the device (contact itself is not modelled).

Two centerline points are *in contact* when their distance is below the sum of their radii while
they are *distant* along the tube: on different tubes, or more than ``pi / 2 x (r_i + r_j)``
apart in rest arclength on the same tube. Points of different groups (variants of a batch) never
touch: the hash grid is built per group.

Shapes: positions (node,) vec3 [m] of one world; ``node_radius``, ``node_arc`` (node,) [m];
``node_tube``, ``node_group`` (node,) int; ``gap_out`` (group,) [m], set to 0 by the host, gets the
deepest overlap ``distance - (r_i + r_j)`` (< 0) of each group.
"""

from __future__ import annotations

import warp as wp

HALF_PI = wp.constant(1.5707963267948966)


@wp.func
def distant_gap(
    i: int, j: int, q: wp.array[wp.vec3], node_radius: wp.array[float], node_arc: wp.array[float],
    node_tube: wp.array[int],
) -> float:  # fmt: skip
    """``|q_i - q_j| - (r_i + r_j)`` [m] of two distant points, 0 for points close along a tube."""
    rsum = node_radius[i] + node_radius[j]
    if node_tube[i] == node_tube[j] and wp.abs(node_arc[i] - node_arc[j]) <= HALF_PI * rsum:
        return 0.0
    return wp.min(wp.length(q[j] - q[i]) - rsum, 0.0)


@wp.kernel(enable_backward=False)
def contact_grid_kernel(
    grid: wp.uint64,
    query_radius: float,
    q: wp.array[wp.vec3],
    node_radius: wp.array[float],
    node_arc: wp.array[float],
    node_tube: wp.array[int],
    node_group: wp.array[int],
    gap_out: wp.array[float],
):
    """A thread per point: its neighbours of the same group within ``query_radius`` [m]."""
    i = wp.tid()
    g = node_group[i]
    query = wp.hash_grid_query(grid, q[i], query_radius, g)
    j = int(0)
    while wp.hash_grid_query_next(query, j):
        if j > i:
            gap = distant_gap(i, j, q, node_radius, node_arc, node_tube)
            if gap < 0.0:
                wp.atomic_min(gap_out, g, gap)


@wp.kernel(enable_backward=False)
def contact_pairs_kernel(
    pair_i: wp.array[int],
    pair_j: wp.array[int],
    q: wp.array[wp.vec3],
    node_radius: wp.array[float],
    node_arc: wp.array[float],
    node_tube: wp.array[int],
    node_group: wp.array[int],
    gap_out: wp.array[float],
):
    """A thread per candidate pair (small models: every distant pair of a group, fixed once)."""
    k = wp.tid()
    i = pair_i[k]
    gap = distant_gap(i, pair_j[k], q, node_radius, node_arc, node_tube)
    if gap < 0.0:
        wp.atomic_min(gap_out, node_group[i], gap)
