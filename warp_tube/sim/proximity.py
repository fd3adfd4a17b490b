"""Distant parts of tubes that come into contact (contact itself is not modelled): found on the
device each frame (:mod:`warp_tube.kernels.contact`), located on the host when one is found.

Two centerline points are *in contact* when their distance is below the sum of their radii (the
tube surfaces meet) while they are *distant* along the tubes: more than ``pi / 2 x (r_i + r_j)``
apart in rest arclength on the same tube, or on different tubes of the same group unless both lie
that close to a junction of the two (:func:`junctions`: tubes joined at rest, as the branches of an
airway or a vessel tree). (On a straight tube
or a smooth bend, points that close in arclength are never that close in space; a tube folded into
a U of bend radius below its own radius, or looping onto itself, is.) Points already that close at
rest are left out: the scene puts them so (tubes joined at a shared pinned point, the legs of a
hairpin laid side by side). A group is a set of tubes
that share a space: a scene's tubes are one group, a batch's variants one group each.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels.contact import ContactNodes, contact_grid_kernel, contact_pairs_kernel
from .checks import HOST_SLOTS, IMMEDIATE, wait_for_stream

__all__ = ["ContactMonitor", "rest_arclength", "junctions", "grid_dims", "GRID_CELLS_MAX", "JOINED"]

#: groups of up to this many points check all their distant pairs each frame; larger ones query
#: a hash grid
SMALL = 128


def rest_arclength(rest: np.ndarray, tube_node_start: np.ndarray) -> np.ndarray:
    """Arclength of each rest point from its tube's start [m]: ``rest`` (..., node, 3) [m], the
    tubes' first nodes (tube + 1,) int; returns (..., node). Leading axes (a batch's worlds, which
    share the tubes' layout) are independent: each world's row is what its points alone give."""
    start = np.asarray(tube_node_start, dtype=np.int64)
    tube = np.repeat(np.arange(len(start) - 1), np.diff(start))
    seg = np.linalg.norm(np.diff(rest, axis=-2), axis=-1)
    arc = np.concatenate([np.zeros(seg.shape[:-1] + (1,)), np.cumsum(seg, axis=-1)], axis=-1)
    return arc - arc[..., start[:-1]][..., tube]


#: a tube's end within this fraction of its radius of a point of another tube (at rest) joins the two there
JOINED = 1e-3


def junctions(rest: np.ndarray, radius: np.ndarray, tube_node_start: np.ndarray, arc: np.ndarray,
              group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Where tubes are joined at rest: an end of one within :data:`JOINED` of its radius of a point
    of another of its group (a branch's first point on its parent's). Points joined, directly or
    through others, make one junction.

    Args:
        rest: rest positions (node, 3) [m]; radius, arc (rest arclength from the tube's start [m])
            and group: (node,).
        tube_node_start: first node of each tube, (tube + 1,) int.

    Returns:
        Per node: the nearest junction along its tube (an index; -1 where its tube joins no other)
        and the rest arclength to it [m] (infinite where none), shapes (node,).
    """
    n = len(rest)
    start = np.asarray(tube_node_start, dtype=np.int64)
    junction, to_junction = np.full(n, -1, dtype=np.int64), np.full(n, np.inf)
    tube = np.repeat(np.arange(len(start) - 1), np.diff(start))
    first = group[start[:-1]] if n else np.zeros(0, dtype=np.int64)
    if n == 0 or len(np.unique(first)) == len(first):  # no group holds two tubes
        return junction, to_junction
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    # Groups (a batch's worlds, which overlap in space) set apart before the search.
    span = float(np.ptp(rest, axis=0).max()) + 4.0 * float(radius.max()) + 1.0
    apart = rest + (group.astype(np.float64) * 3.0 * span)[:, None] * np.array([1.0, 0.0, 0.0])
    ends = np.unique(np.concatenate([start[:-1], start[1:] - 1]))
    near = cKDTree(apart).query_ball_point(apart[ends], JOINED * radius[ends])
    a = np.repeat(ends, [len(k) for k in near])
    b = np.concatenate([np.asarray(k, dtype=np.int64) for k in near]) if len(a) else np.zeros(0, dtype=np.int64)
    other = tube[a] != tube[b]
    a, b = a[other], b[other]
    if len(a) == 0:
        return junction, to_junction
    _, label = connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)), directed=False)
    joined = np.unique(np.concatenate([a, b]))  # in node order: along each tube by arclength
    k = np.searchsorted(joined, np.arange(n))
    best = np.full(n, np.inf)
    for cand in (joined[np.clip(k - 1, 0, len(joined) - 1)], joined[np.clip(k, 0, len(joined) - 1)]):
        d = np.where(tube[cand] == tube, np.abs(arc - arc[cand]), np.inf)
        closer = d < best
        best[closer] = d[closer]
        junction[closer] = label[cand[closer]]
    to_junction[:] = best
    return junction, to_junction


def _block_size(group: np.ndarray) -> int:
    """The size of the groups where they are equal blocks in a row (a batch's worlds), else 0."""
    sizes = np.bincount(group)
    b = int(sizes[0])
    return b if (sizes == b).all() and np.array_equal(group, np.repeat(np.arange(len(sizes)), b)) else 0


def _tiled(i: np.ndarray, j: np.ndarray, size: int, blocks: int) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``i``, ``j`` of one block of ``size`` points, offset block after block (``blocks``)."""
    offset = (np.arange(blocks) * size)[:, None]
    return (i[None] + offset).reshape(-1), (j[None] + offset).reshape(-1)


def _group_pairs(group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pair ``i < j`` of points of one group, ``group`` (node,) int: built per group (a
    batch's worlds: equal blocks in a row, one block's pairs offset block after block)."""
    n = len(group)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    b = _block_size(group)
    if b:
        return _tiled(*np.triu_indices(b, 1), b, n // b)
    out_i, out_j = [], []
    for g in range(int(group.max()) + 1):
        nodes = np.flatnonzero(group == g)
        i, j = np.triu_indices(len(nodes), 1)
        out_i.append(nodes[i])
        out_j.append(nodes[j])
    return np.concatenate(out_i), np.concatenate(out_j)


#: a hash grid's table holds at most this many cells (two int32 arrays of them)
GRID_CELLS_MAX = 1 << 22


def grid_dims(points: np.ndarray, cell: float, n: int) -> tuple[int, int, int]:
    """A hash grid's table dimensions (x, y, z) for ``points`` (P, 3) [m] in cells of width
    ``cell`` [m], ``n`` points: about two cells of the table per point (at least 4,096, at most
    :data:`GRID_CELLS_MAX`), shared among the axes in proportion to the points' extent along each,
    and never more along an axis than the extent has cells. The table wraps each axis: a table as
    wide along every axis, for the points of a long row of tubes, had the cells along the row share
    a few slots of it, and a query looked through all their points (a frame's check of 5,000 tubes
    in a row took 3.5 times as long as laid out in a square; the same contacts are found either way)."""
    extent = np.ptp(np.asarray(points, dtype=np.float64), axis=0) / max(cell, 1e-30) + 1.0 if len(points) else np.ones(3)
    extent = np.minimum(extent, float(GRID_CELLS_MAX))
    target = float(np.clip(2 * n, 4096, GRID_CELLS_MAX))
    scale = (target / float(np.prod(extent))) ** (1.0 / 3.0)
    dims = np.clip(np.ceil(extent * scale), 1, np.ceil(extent)).astype(np.int64)
    while int(np.prod(dims)) > GRID_CELLS_MAX:  # (rounding up along three axes)
        dims[int(np.argmax(dims))] -= 1
    return int(dims[0]), int(dims[1]), int(dims[2])


class ContactMonitor:
    """Finds contacts between distant parts of a model's tubes, in one world.

    Args:
        rest_q: rest positions [m], shape (node_count, 3).
        radius: tube radius at each node [m], shape (node_count,).
        tube_node_start: first node of each tube, shape (tube_count + 1,) int.
        device: the Warp device of the positions.
        node_group: (node,) int group of each node (default: all one group).
        node_arc: (node,) rest arclength of each node from its tube's start [m] (default:
            :func:`rest_arclength` of ``rest_q``).
        small: groups of at most this many points test all their pairs, larger ones use the
            hash grid (the same contacts either way; many groups of a few dozen points already
            make many pairs).
    """

    def __init__(self, rest_q, radius, tube_node_start, device="cpu", node_group=None, node_arc=None, small: int = SMALL):
        rest = np.asarray(rest_q, dtype=np.float64)
        start = np.asarray(tube_node_start, dtype=np.int64)
        n = len(rest)
        self.radius = np.asarray(radius, dtype=np.float64)
        self.rest = rest
        self.tube = np.repeat(np.arange(len(start) - 1), np.diff(start))
        self.arc = rest_arclength(rest, start) if node_arc is None else np.asarray(node_arc, dtype=np.float64)
        self.group = np.zeros(n, dtype=np.int32) if node_group is None else np.asarray(node_group, dtype=np.int32)
        self.node_count = n
        self.group_count = int(self.group.max()) + 1 if n else 1
        self.max_radius = float(self.radius.max()) if n else 0.0
        self.device = device
        d = device
        self.junction, self.to_junction = junctions(rest, self.radius, start, self.arc, self.group)
        self._nodes = ContactNodes()
        self._nodes.rest_q = wp.array(rest.astype(np.float32).reshape(-1, 3), dtype=wp.vec3, device=d)
        self._nodes.radius = wp.array(self.radius, dtype=float, device=d)
        self._nodes.arc = wp.array(self.arc, dtype=float, device=d)
        self._nodes.tube = wp.array(self.tube, dtype=int, device=d)
        self._nodes.group = self._group = wp.array(self.group, dtype=int, device=d)
        self._nodes.junction = wp.array(self.junction, dtype=int, device=d)
        self._nodes.junction_arc = wp.array(np.minimum(self.to_junction, 1e30), dtype=float, device=d)
        self._gap = wp.zeros(self.group_count, dtype=float, device=d)
        # its host copies, one per slot (checks.HOST_SLOTS: frames in flight, and IMMEDIATE)
        self._gap_host = [wp.zeros(self.group_count, dtype=float, device="cpu", pinned=wp.get_device(d).is_cuda)
                          for _ in range(HOST_SLOTS)]  # fmt: skip
        self._pairs = None
        self._grid = None
        self._launches: dict = {}  # positions' address -> (their monitored points, recorded launch or None)
        largest = int(np.bincount(self.group).max()) if n else 0
        if largest <= small:
            # Every pair of a group that could ever count, fixed once: per frame only distances.
            i, j = self._distant_pairs()
            self._pairs = (wp.array(i, dtype=int, device=d), wp.array(j, dtype=int, device=d))
        else:
            self._grid = wp.HashGrid(*grid_dims(rest, 2.0 * self.max_radius, n), device=d)

    def _distant_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Every pair ``i < j`` of a group whose points are distant along the tubes (see the module
        docstring). Groups that are equal blocks in a row with the same radii, arclengths and
        tubes (a batch's worlds of one geometry) share one block's pairs, offset block after block."""
        n = self.node_count
        b = _block_size(self.group) if n else 0
        if b and n > b:
            radius, arc = self.radius.reshape(-1, b), self.arc.reshape(-1, b)
            tube = self.tube.reshape(-1, b)
            tube = tube - tube[:, :1]  # (each block's own tubes, numbered from its first)
            if (radius == radius[:1]).all() and (arc == arc[:1]).all() and (tube == tube[:1]).all():
                return _tiled(*self._keep(*np.triu_indices(b, 1)), b, n // b)
        return self._keep(*_group_pairs(self.group))

    def _keep(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pairs of ``i``, ``j`` whose points are distant along the tubes (the kernel also
        leaves out those in contact at rest, which differ between a batch's worlds)."""
        keep = self._distant(i, j)
        return i[keep], j[keep]

    def _distant(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Whether the points of pairs ``i``, ``j`` are distant along the tubes, bool."""
        rsum = self.radius[i] + self.radius[j]
        return (self.tube[i] != self.tube[j]) | (np.abs(self.arc[i] - self.arc[j]) > 0.5 * np.pi * rsum)

    def deepest(self, q: wp.array) -> np.ndarray:
        """The deepest overlap of each group, ``distance - (r_i + r_j)`` [m], shape (groups,): 0
        where nothing touches.

        Args:
            q: positions [m], vec3, on the monitor's device, whose first ``node_count`` points
                (in memory order) are the monitor's: one world's (node,), or a state's
                (world, node) of which the monitor watches world 0, or every world of a batch.
        """
        self.launch(q)
        wait_for_stream(self.device)
        return self.measured()

    def measured(self, slot: int = IMMEDIATE) -> np.ndarray:
        """:meth:`deepest` of the positions launched into host slot ``slot`` (:meth:`launch`),
        once the device's stream has reached it (a copy)."""
        return self._gap_host[slot].numpy().copy()

    def launch(self, q: wp.array, slot: int = IMMEDIATE) -> None:
        """Start :meth:`deepest` of ``q``: its kernel and the copy of its result to host slot
        ``slot``, queued on the device's stream (:meth:`measured` reads it)."""
        # One recorded launch per positions array (a run alternates two states), with the view of
        # its monitored points: the launch holds the array, so its address identifies it for as
        # long as the launch is kept.
        held = self._launches.get(q.ptr)
        if held is None:
            flat = q.reshape((q.size,))[: self.node_count] if q.ndim > 1 or q.shape[0] != self.node_count else q
            if self._pairs is not None:
                launch = wp.launch(contact_pairs_kernel, dim=self._pairs[0].shape[0], device=self.device,
                                   inputs=[*self._pairs, flat, self._nodes, self._gap],
                                   record_cmd=True) if self._pairs[0].shape[0] else None  # fmt: skip
            else:
                launch = wp.launch(contact_grid_kernel, dim=self.node_count, device=self.device,
                                   inputs=[self._grid.id, 2.0 * self.max_radius, flat, self._nodes, self._gap],
                                   record_cmd=True)  # fmt: skip
            if len(self._launches) > 8:
                self._launches.clear()
            held = self._launches[q.ptr] = (flat, launch)
        flat, launch = held
        self._gap.zero_()
        if self._pairs is None:
            self._grid.build(flat, 2.0 * self.max_radius, groups=self._group)
        if launch is not None:
            launch.launch()
        wp.copy(self._gap_host[slot], self._gap)

    def closest(self, q: np.ndarray, group: int = 0):
        """The contact with the deepest overlap in ``group``, or None (host side, to name it).

        Args:
            q: positions [m], shape (node_count, 3).

        Returns:
            ``(i, j, gap)``: node indices and ``distance - (r_i + r_j)`` [m] (negative), or None.
        """
        nodes = np.flatnonzero(self.group == group)
        if len(nodes) <= SMALL:
            i, j = np.triu_indices(len(nodes), 1)
        else:
            from scipy.spatial import cKDTree  # (only here: a run that finds no contact does not import SciPy)

            pairs = cKDTree(q[nodes]).query_pairs(2.0 * self.max_radius, output_type="ndarray")
            i, j = pairs[:, 0], pairs[:, 1]
        i, j = nodes[i], nodes[j]
        rsum = self.radius[i] + self.radius[j]
        through = (self.tube[i] != self.tube[j]) & (self.junction[i] >= 0) & (self.junction[i] == self.junction[j]) & (
            self.to_junction[i] + self.to_junction[j] <= 0.5 * np.pi * rsum)
        counted = self._distant(i, j) & ~through & (np.linalg.norm(self.rest[i] - self.rest[j], axis=1) >= rsum)
        gap = np.where(counted, np.linalg.norm(q[i] - q[j], axis=1) - rsum, np.inf)
        k = int(np.argmin(gap)) if len(gap) else -1
        return (int(i[k]), int(j[k]), float(gap[k])) if k >= 0 and gap[k] < 0.0 else None
