"""Contact between distant parts of tubes, found on the device (contact itself is not modelled).

Two centerline points are *in contact* when their distance is below the sum of their radii while
they are *distant* along the tubes: more than ``pi / 2 x (r_i + r_j)`` apart in rest arclength on
the same tube, or on different tubes unless both lie that close to a junction the two tubes share
(``junction``: points of tubes joined at rest, an airway's or a vessel tree's branching); and were
not in contact at rest (``rest_q``: the legs of a hairpin laid side by side). Points of different
groups (variants of a batch) never touch: the hash grid is built per group.

Shapes: positions (node,) vec3 [m] of one world; the :class:`ContactNodes` arrays (node,) [m];
``gap_out`` (group,) [m], set to 0 by the host, gets the deepest overlap ``distance - (r_i + r_j)``
(< 0) of each group.
"""

from __future__ import annotations

import warp as wp

HALF_PI = wp.constant(1.5707963267948966)


@wp.struct
class ContactNodes:
    """Per centerline point, fixed for a run: ``rest_q`` rest position [m], ``radius`` [m], ``arc``
    rest arclength from its tube's start [m], ``tube`` and ``group`` indices, ``junction`` the
    junction nearest along its tube (-1: its tube joins no other) and ``junction_arc`` the rest
    arclength to it [m]."""

    rest_q: wp.array[wp.vec3]
    radius: wp.array[float]
    arc: wp.array[float]
    tube: wp.array[int]
    group: wp.array[int]
    junction: wp.array[int]
    junction_arc: wp.array[float]


@wp.func
def distant_gap(i: int, j: int, q: wp.array[wp.vec3], nodes: ContactNodes) -> float:
    """``|q_i - q_j| - (r_i + r_j)`` [m] of two distant points; 0 for points close along a tube or
    through a shared junction, or in contact at rest."""
    rsum = nodes.radius[i] + nodes.radius[j]
    reach = HALF_PI * rsum
    if nodes.tube[i] == nodes.tube[j]:
        if wp.abs(nodes.arc[i] - nodes.arc[j]) <= reach:
            return 0.0
    elif nodes.junction[i] >= 0 and nodes.junction[i] == nodes.junction[j]:
        if nodes.junction_arc[i] + nodes.junction_arc[j] <= reach:
            return 0.0
    if wp.length(nodes.rest_q[j] - nodes.rest_q[i]) < rsum:
        return 0.0
    return wp.min(wp.length(q[j] - q[i]) - rsum, 0.0)


@wp.kernel(enable_backward=False)
def contact_grid_kernel(
    grid: wp.uint64,
    query_radius: float,
    q: wp.array[wp.vec3],
    nodes: ContactNodes,
    gap_out: wp.array[float],
):
    """A thread per point: its neighbours of the same group within ``query_radius`` [m]."""
    i = wp.tid()
    g = nodes.group[i]
    query = wp.hash_grid_query(grid, q[i], query_radius, g)
    j = int(0)
    while wp.hash_grid_query_next(query, j):
        if j > i:
            gap = distant_gap(i, j, q, nodes)
            if gap < 0.0:
                wp.atomic_min(gap_out, g, gap)


@wp.kernel(enable_backward=False)
def contact_pairs_kernel(
    pair_i: wp.array[int],
    pair_j: wp.array[int],
    q: wp.array[wp.vec3],
    nodes: ContactNodes,
    gap_out: wp.array[float],
):
    """A thread per candidate pair (small models: every distant pair of a group, fixed once)."""
    k = wp.tid()
    i = pair_i[k]
    gap = distant_gap(i, pair_j[k], q, nodes)
    if gap < 0.0:
        wp.atomic_min(gap_out, nodes.group[i], gap)
