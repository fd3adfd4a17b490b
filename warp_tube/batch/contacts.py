"""Contact between distant parts of each world's tubes, as ``Simulation`` finds it alone.

Contact is not modelled: where distant parts of a variant's tubes come closer than the sum of
their radii, they pass through each other. ``Simulation`` warns of it once (world 0, the first
frame it happens); a batch records, per world, the first frame at whose end it happened (the
summary's ``contact_frame``), by the same test: one :class:`~warp_tube.sim.proximity.ContactMonitor`
over all worlds, each world a group of its own (its own radii and rest arclengths), the deepest
overlap of every world from one launch a frame, and a world that newly overlaps confirmed on the
host (float64) as ``Simulation`` confirms it.
"""

from __future__ import annotations

import numpy as np

from ..sim.proximity import ContactMonitor, rest_arclength
from .worlds import Worlds

__all__ = ["WorldContacts", "PAIRS_MAX"]

#: worlds of at most this many points test all their pairs each frame; larger ones query a hash
#: grid (pairs grow with the square of the points, a frame's simulation with the points)
PAIRS_MAX = 32


class WorldContacts:
    """First contact frame of every world of a batch.

    Args:
        worlds: the worlds (W worlds of N nodes).

    Attributes:
        frame: (W,) int, per world the first frame at whose end distant parts of its tubes
            overlapped, -1 while they have not.
    """

    def __init__(self, worlds: Worlds):
        h, m = worlds.host, worlds.model
        W, N = h.node_rest_q.shape[:2]
        start = np.asarray(m.host.tube_node_start, dtype=np.int64)  # one world's layout
        starts = (start[:-1][None, :] + N * np.arange(W)[:, None]).reshape(-1)
        rest = h.node_rest_q[:1] if worlds.rest_shared else h.node_rest_q  # (one world's, repeated: the same numbers)
        arc = np.broadcast_to(rest_arclength(rest, start), (W, N))
        self.monitor = ContactMonitor(h.node_rest_q.reshape(-1, 3), h.node_radius.reshape(-1), np.append(starts, W * N),
                                      device=m.device, node_group=np.repeat(np.arange(W), N),
                                      node_arc=arc.reshape(-1), small=PAIRS_MAX)  # fmt: skip
        self.frame = np.full(W, -1, dtype=np.int64)

    def launch(self, q, slot: int) -> None:
        """Queue the test of positions ``q`` (W, N) vec3 [m] (the state at the end of a frame:
        every world's points, the monitor's groups) and its copy back into host slot ``slot`` on
        the device's stream (see :meth:`check`)."""
        self.monitor.launch(q, slot)

    def check(self, frame: int, q, alive: np.ndarray, slot: int) -> None:
        """Record ``frame`` for the ``alive`` worlds whose positions ``q``, :meth:`launch`-ed into
        ``slot`` (the state at the end of that frame), first put distant parts of their tubes in
        contact, once the device's stream has reached them (``q`` is read again only to confirm
        a new contact)."""
        gap = self.monitor.measured(slot)
        new = np.flatnonzero((gap < 0.0) & (self.frame < 0) & alive)
        if len(new):
            host = q.numpy().reshape(-1, 3).astype(np.float64)
            for w in new.tolist():
                if self.monitor.closest(host, group=w) is not None:
                    self.frame[w] = frame
