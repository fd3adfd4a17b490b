"""How the GPU's surface kernel splits a world among warps: spans of whole tubes.

The block kernel (:mod:`warp_tube.kernels.surface_block`) rebuilds a span with one warp. A batch's
worlds fill the device alone (thousands of worlds, each one span); a scene run alone is one world,
whose tubes (16,384 curves of one prim, say) would otherwise all go through one warp. Its tubes
are then grouped, in order, into spans of about ``hubs / spans`` hubs (at least
:data:`MIN_SPAN_HUBS`) until the worlds' spans number about :data:`TARGET_WARPS`. A tube is never
split: the frames are carried along a tube hub after hub.
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels.surface_arrays import RING_BODY

__all__ = ["Spans", "block_spans", "TARGET_WARPS", "MIN_SPAN_HUBS"]

#: warps a rebuild is split into, about (a world's tubes are grouped into spans until it has)
TARGET_WARPS = 8192
#: least hubs of a span (a warp has 32 lanes; a span of fewer leaves lanes idle)
MIN_SPAN_HUBS = 32


class Spans:
    """A world's spans: hubs ``hub_start[s] .. hub_start[s + 1]`` (whole tubes; their body rings
    have the same indices) and cap rings ``cap_ring[s] .. cap_ring[s + 1]``, int32 (count + 1,)
    each; ``hubs_max``, the most hubs of a span."""

    def __init__(self, hub_start: np.ndarray, cap_ring: np.ndarray):
        self.hub_start = np.asarray(hub_start, dtype=np.int32)
        self.cap_ring = np.asarray(cap_ring, dtype=np.int32)
        self.count = len(self.hub_start) - 1
        self.hubs_max = int(np.diff(self.hub_start).max()) if self.count else 0


def block_spans(tube_node_start, ring_hub, ring_kind, world_count: int, target_warps: int | None = None,
                min_hubs: int | None = None) -> Spans:  # fmt: skip
    """The spans of one world of a surface (see the module docstring).

    Args:
        tube_node_start: first hub of each tube, (T + 1,), from 0.
        ring_hub, ring_kind: the ring table's hub and kind of each ring
            (:class:`~warp_tube.surface.topology.SurfaceTopology`): body rings first, ring ``i``
            of hub ``i``, then each tube's cap rings, tube after tube.
        world_count: worlds of the rebuild.
        target_warps, min_hubs: default :data:`TARGET_WARPS`, :data:`MIN_SPAN_HUBS`.
    """
    target_warps = TARGET_WARPS if target_warps is None else target_warps
    min_hubs = MIN_SPAN_HUBS if min_hubs is None else min_hubs
    starts = np.asarray(tube_node_start, dtype=np.int64)
    n_tubes, n_hubs = len(starts) - 1, int(starts[-1])
    ring_hub = np.asarray(ring_hub, dtype=np.int64)
    ring_kind = np.asarray(ring_kind)
    whole = Spans(np.array([0, n_hubs]), np.array([n_hubs, len(ring_hub)]))
    wanted = math.ceil(target_warps / max(int(world_count), 1))
    if wanted <= 1 or n_tubes <= 1:
        return whole
    if not (np.array_equal(ring_hub[:n_hubs], np.arange(n_hubs)) and np.all(ring_kind[:n_hubs] == RING_BODY)):
        return whole  # (not the ring table's layout: one span, as the kernel always could)
    size = max(int(min_hubs), math.ceil(n_hubs / wanted))
    block = starts[:-1] // size  # each tube goes with the block of hubs its first hub falls in
    first_tubes = np.flatnonzero(np.r_[True, block[1:] > block[:-1]])
    tube_bounds = np.r_[first_tubes, n_tubes]
    caps_tube = np.searchsorted(starts, ring_hub[n_hubs:], side="right") - 1  # tube of each cap ring
    if np.any(np.diff(caps_tube) < 0):
        return whole
    cap_ring = n_hubs + np.searchsorted(caps_tube, tube_bounds, side="left")
    return Spans(starts[tube_bounds], cap_ring)
