"""Frame checks: did a frame blow up, and where.

Each frame end is checked for non-finite positions, a point running away (farther than
:data:`RUNAWAY_LENGTHS` tube lengths from rest), and a kinetic energy above what the point forces
and gravity can have put in (a blow-up). The sums run on the device
(:func:`warp_tube.kernels.checks.frame_sums_kernel`); the host reads five numbers per (world,
group) a frame and looks at whole arrays only to name the point of a frame that failed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from ..kernels.checks import SUMS, frame_sums_kernel

__all__ = ["FrameChecks", "Failure", "RUNAWAY_LENGTHS", "ENERGY_MARGIN", "HOST_SLOTS", "IMMEDIATE", "wait_for_stream"]

#: host copies of a frame's sums: two for frames in flight one after another, one for a frame
#: measured and read at once (:data:`IMMEDIATE`)
HOST_SLOTS = 3
IMMEDIATE = 2

#: a free point farther than this many tube lengths from its rest position is a blow-up.
RUNAWAY_LENGTHS = 1.0e3
#: kinetic energy may exceed the work put in by this factor before a frame counts as a blow-up
#: (the springs' energy is >= 0 and damping only takes energy; the margin covers the error of
#: measuring the work at frame ends).
ENERGY_MARGIN = 10.0


def wait_for_stream(device) -> None:
    """Wait until ``device``'s current stream has done what was queued on it (not other streams:
    a batch's copies back run beside it); nothing on the CPU, where launches return when done."""
    device = wp.get_device(device)
    if device.is_cuda:
        wp.synchronize_stream(wp.get_stream(device))


@dataclass(frozen=True)
class Failure:
    """A failed frame of one group: ``what`` went wrong, at model node ``node`` of world ``world``."""

    group: int
    world: int
    node: int
    what: str


class FrameChecks:
    """Device-side frame checks of a model, per world and group.

    Args:
        model: the :class:`~warp_tube.model.tube.TubeModel`.
        node_group: (node_count,) int, the group of each node (default: one group).
        extent: size of each group's tubes [m], shape (groups,), or (worlds, groups) where each
            world's differ, for the runaway distance.
        energy_floor: [J], (groups,) or (worlds, groups): kinetic energy that never counts as a
            blow-up (round-off).
        gravity: (3,) [m/s^2] or None.
        rest_q: rest positions [m], (worlds, node_count, 3), where each world has its own (a
            batch's variants); default: the model's, shared by every world.
        node_mass, node_inv_mass: node masses [kg] and their inverses [1/kg] (0 where pinned),
            (worlds, node_count), with ``rest_q``; default: the model's.
    """

    def __init__(self, model, node_group=None, extent=None, energy_floor=None, gravity=None, rest_q=None, node_mass=None,
                 node_inv_mass=None):  # fmt: skip
        h = model.host
        n = model.node_count
        self.model = model
        self.device = model.device
        group = np.zeros(n, dtype=np.int32) if node_group is None else np.asarray(node_group, dtype=np.int32)
        self.group_count = int(group.max()) + 1 if n else 1
        self.node_group = group
        G, W = self.group_count, model.world_count
        extent = np.asarray(1.0 if extent is None else extent, dtype=np.float64)
        self.extent = np.broadcast_to(extent, (W, G) if extent.ndim == 2 else (G,)).copy()
        floor = np.asarray(0.0 if energy_floor is None else energy_floor, dtype=np.float64)
        self.energy_floor = np.broadcast_to(floor, (W, G) if floor.ndim == 2 else (G,)).copy()
        # One runaway distance for the launch: the smallest; a group (or world) whose own limit is
        # larger is re-checked against it on the host (rare: only when something is that far).
        self.limits = RUNAWAY_LENGTHS * np.maximum(self.extent, 1e-9)
        #: rest positions [m] (rows, N, 3) and masses [kg] (rows, N): one row, or one per world
        self.rest_q = (h.node_rest_q if rest_q is None else np.asarray(rest_q, dtype=np.float64)).reshape(-1, n, 3)
        self.node_mass = (h.node_mass if node_mass is None else np.asarray(node_mass, dtype=np.float64)).reshape(-1, n)
        inv_mass = (h.node_inv_mass if node_inv_mass is None else np.asarray(node_inv_mass)).reshape(-1, n)
        self.free_mass = self.node_mass * (inv_mass > 0)
        self.gravity = np.zeros(3) if gravity is None else np.asarray(gravity, dtype=np.float64)
        d = self.device
        self._group = wp.array(group, dtype=int, device=d)
        self._free_mass = wp.array(self.free_mass, dtype=float, device=d)
        self._rest = wp.array(self.rest_q, dtype=wp.vec3, device=d)
        self._sums = wp.zeros((W, G, SUMS), dtype=float, device=d)
        # their copies on the host, page-locked on a GPU (copied back without waiting: see launch),
        # in HOST_SLOTS slots: frames in flight one after another each have their own
        pinned = wp.get_device(d).is_cuda
        self._sums_host = [wp.zeros((W, G, SUMS), dtype=float, device="cpu", pinned=pinned) for _ in range(HOST_SLOTS)]
        self._launches = {}
        #: work of the forces and gravity so far [J], per (world, group), float64
        self.work = np.zeros((W, G))
        #: the largest it has been at a kept frame's end [J]: the budget's base (see check_measured)
        self.work_peak = np.zeros((W, G))
        #: energy moving pins may put in [J] per group: not measured, so unbounded where they move
        self.pin_allowance = np.zeros(G)

    def measure(self, before, after, control):
        """Per (world, group): ``(bad, kinetic [J], work of this frame [J])`` as NumPy arrays."""
        self.launch(before, after, control)
        wait_for_stream(self.device)
        return self.measured()

    def launch(self, before, after, control, slot: int = IMMEDIATE) -> None:
        """Start measuring the frame from ``before`` to ``after``: the sums' kernel and their copy
        to host slot ``slot`` (0 to :data:`HOST_SLOTS` - 1), queued on the device's stream;
        :meth:`measured` reads them once the stream has reached them (a batch waits for the
        stream once for its frame's every read, and reads a frame while the next one runs)."""
        # One recorded launch per set of arrays (a run swaps two states); the launch holds the
        # arrays, so their addresses identify them for as long as it is kept.
        key = (before.node_q.ptr, after.node_q.ptr, after.node_qd.ptr, control.node_f_ext.ptr)
        launch = self._launches.get(key)
        if launch is None:
            W, N = self.model.world_count, self.model.node_count
            launch = wp.launch(
                frame_sums_kernel, dim=(W, N), device=self.device,
                inputs=[before.node_q, after.node_q, after.node_qd, control.node_f_ext, self._rest,
                        self.model.seg_rest_length, self._group, self._free_mass, wp.vec3(*self.gravity),
                        float(self.limits.min())],
                outputs=[self._sums], record_cmd=True,
            )  # fmt: skip
            self._launches[key] = launch
        self._sums.zero_()
        launch.launch()
        wp.copy(self._sums_host[slot], self._sums)

    def measured(self, slot: int = IMMEDIATE):
        """:meth:`measure`'s result for the frame launched into host slot ``slot``
        (:meth:`launch`), once the device's stream has reached it."""
        s = self._sums_host[slot].numpy()[..., :3].astype(np.float64)
        return s[..., 0], s[..., 1], s[..., 2]

    def distance(self, slot: int = IMMEDIATE) -> np.ndarray:
        """Largest distance of a finite node from rest in the frame measured into host slot
        ``slot`` [m], (W, G) (zero before the first frame), once the device's stream has reached it."""
        return self._sums_host[slot].numpy()[..., 3].astype(np.float64)

    def stretch(self, slot: int = IMMEDIATE) -> np.ndarray:
        """The largest factor by which a segment's length departs from its rest length in the frame
        measured into host slot ``slot``, stretched or compressed (``max(l / l0, l0 / l)``, 1 at
        rest, and where a group has no segment) [1], (W, G), once the device's stream has reached it."""
        return np.maximum(self._sums_host[slot].numpy()[..., 4].astype(np.float64), 1.0)

    def check(self, before, after, control) -> tuple[list[Failure], np.ndarray]:
        """Failures of the frame from ``before`` to ``after`` (empty when it is good), and its
        work per (world, group) [J], to be added with :meth:`accept` once the frame is kept."""
        return self.check_measured(self.measure(before, after, control), after)

    def check_measured(self, measured, after) -> tuple[list[Failure], np.ndarray]:
        """:meth:`check` from the frame's :meth:`measured` sums (``after``: its end state, read
        only to name the point of a failure)."""
        bad, ke, work = measured
        # The budget is based on the most work done at any frame's end so far, not the work now:
        # an undamped tube under a constant force returns to where it started every period, with
        # the work back to ~0 while the integrator's velocity, half a substep behind, is not. A
        # blow-up grows past any fixed budget all the same.
        done = np.maximum(self.work_peak, self.work + work)
        budget = ENERGY_MARGIN * np.maximum(done, 0.0) + self.energy_floor + self.pin_allowance
        failures = []
        q = None
        for w, g in zip(*np.nonzero((bad > 0) | (ke > budget))):
            if q is None:
                q = after.node_q.numpy().astype(np.float64)
                qd = after.node_qd.numpy()
            failure = self._locate(int(w), int(g), q[w], qd[w], bad[w, g] > 0, budget[w, g])
            if failure is not None:
                failures.append(failure)
        return failures, work

    def accept(self, work: np.ndarray) -> None:
        """Count a kept frame's work (from :meth:`check`)."""
        self.work += work
        np.maximum(self.work_peak, self.work, out=self.work_peak)

    def _locate(self, w, g, q, qd, flagged, budget) -> Failure | None:
        nodes = np.flatnonzero(self.node_group == g)
        row = w % len(self.rest_q)
        x = q[nodes]
        if flagged:
            finite = np.isfinite(x).all(axis=1) & np.isfinite(qd[nodes]).all(axis=1)
            if not finite.all():
                return Failure(g, w, int(nodes[np.argmin(finite)]), "non-finite positions")
            dist = np.linalg.norm(x - self.rest_q[row, nodes], axis=1)
            limit = self.limits[w, g] if self.limits.ndim == 2 else self.limits[g]
            if dist.max() > limit:
                return Failure(g, w, int(nodes[np.argmax(dist)]), f"a point more than {RUNAWAY_LENGTHS:g} tube lengths from rest")
            # Beyond the launch's limit but within this group's own: not a failure by itself.
            v = qd[nodes].astype(np.float64)
            ke = 0.5 * float(np.einsum("n,nk,nk->", self.free_mass[row, nodes], v, v))
            if not ke > budget:
                return None
        v = qd[nodes]
        hot = int(np.argmax(np.einsum("nk,nk->n", v, v) * self.node_mass[row, nodes]))
        return Failure(g, w, int(nodes[hot]), "kinetic energy beyond the work the forces did (a blow-up)")
