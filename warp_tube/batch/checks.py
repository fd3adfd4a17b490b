"""Per-world frame checks of a batch: ``Simulation``'s checks, world by world, so one variant can
fail while the others go on.

A world fails a frame when a position is not finite, a free point is farther than
``RUNAWAY_LENGTHS`` tube lengths from its rest position, or its kinetic energy exceeds ten times
the work its forces and gravity did plus a round-off floor (moving pins: no energy check), as in
``Simulation._check``. The checks run on the host from the positions and velocities the batch
copies back each frame (device-side checks are a later step).
"""

from __future__ import annotations

import numpy as np

from ..sim.checks import RUNAWAY_LENGTHS
from .worlds import Worlds

__all__ = ["WorldChecks", "work_of"]


def work_of(force_node, f_ext, q_before, q_after, free_mass, gravity) -> np.ndarray:
    """Work [J] of the point forces and gravity over one frame, per world (``Simulation``'s
    bookkeeping): ``f . dq`` at the force nodes (forces are held over a frame, so that is exact)
    and ``g . (sum m x_after - sum m x_before)``.

    Args:
        force_node: node of each force, (F,).
        f_ext: the frame's forces at those nodes [N], (W, F, 3), or None.
        q_before, q_after: positions [m], (W, N, 3).
        free_mass: mass of the free nodes [kg], (W, N) (0 where pinned).
        gravity: [m/s^2], or None.
    """
    w = np.zeros(len(q_after))
    if f_ext is not None and len(force_node):
        dq = q_after[:, force_node].astype(np.float64) - q_before[:, force_node]
        w += np.einsum("wnk,wnk->w", f_ext.astype(np.float64), dq)
    if gravity is not None and any(gravity):
        g = np.asarray(gravity, dtype=np.float64)
        w += (np.einsum("wn,wnk->wk", free_mass, q_after) - np.einsum("wn,wnk->wk", free_mass, q_before)) @ g
    return w


class WorldChecks:
    """Frame checks and energy bookkeeping for every world of a batch.

    Args:
        worlds: the worlds.
        gravity: gravitational acceleration [m/s^2] or None.
        moving_pins: whether pins move (then the energy check is off, as in ``Simulation``).
    """

    def __init__(self, worlds: Worlds, gravity, moving_pins: bool):
        h = worlds.host
        W = worlds.world_count
        self.worlds = worlds
        self.rest = h.node_rest_q
        self.rest32 = self.rest.astype(np.float32)
        self.free_mass = h.node_mass * (h.node_inv_mass > 0)
        extent = np.array([max(float(np.ptp(t.points, axis=0).max()) for t in s.tubes) for s in worlds.scenes])
        self.limit = RUNAWAY_LENGTHS * np.maximum(extent, 1e-9)
        # Simulation's round-off floor of the energy check, per world.
        scale = np.maximum(np.maximum(extent, np.abs(self.rest).reshape(W, -1).max(axis=1)), 1e-9)
        self.energy_floor = np.sum(h.seg_ke, axis=1) * (1e-6 * scale) ** 2 + 1e-30
        self.allowance = np.inf if moving_pins else 0.0
        self.gravity = gravity
        self.force_node = np.asarray(worlds.model.host.force_node, dtype=np.int64)
        self.work = np.zeros(W)  # work done so far [J]

    def frame_work(self, q_before: np.ndarray, q_after: np.ndarray, f_ext: np.ndarray | None) -> np.ndarray:
        """Work [J] of the forces and gravity over a frame, per world: ``f . dq`` at the force
        nodes (forces are held over a frame) and ``g . (sum m x_after - sum m x_before)``."""
        return work_of(self.force_node, f_ext, q_before, q_after, self.free_mass, self.gravity)

    def check(self, frame: int, q: np.ndarray, qd: np.ndarray, work: np.ndarray, alive: np.ndarray) -> dict:
        """Problems of the frame ending at output frame ``frame``, ``{world: message}``, among the
        ``alive`` worlds; ``work``: per-world work up to the frame's end [J]."""
        out = {}
        dev = np.abs(q - self.rest32).reshape(len(q), -1).max(axis=1)
        suspect = np.flatnonzero(alive & ~(dev < self.limit))  # NaN fails the comparison
        for w in suspect:
            bad = ~np.isfinite(q[w]).all(axis=-1)
            far = ~bad & (np.linalg.norm(q[w] - self.rest[w], axis=-1) > self.limit[w])
            if bad.any() or far.any():
                node = int(np.argmax(bad | far))
                what = "non-finite positions" if bad.any() else f"a point more than {RUNAWAY_LENGTHS:g} tube lengths from rest"
                out[int(w)] = self._message(frame, what, w, node)
        ke = self.kinetic_energy(qd)
        budget = 10.0 * np.maximum(work, 0.0) + self.energy_floor + self.allowance
        for w in np.flatnonzero(alive & (ke > budget)):
            if int(w) in out:
                continue
            node = int(np.argmax(np.einsum("nk,nk->n", qd[w], qd[w]) * self.worlds.host.node_mass[w]))
            out[int(w)] = self._message(frame, "kinetic energy beyond the work the forces did (a blow-up)", w, node)
        return out

    def kinetic_energy(self, qd: np.ndarray) -> np.ndarray:
        """Kinetic energy of the free points [J], per world."""
        return 0.5 * np.einsum("wn,wnk,wnk->w", self.free_mass, qd, qd, dtype=np.float64)

    def _message(self, frame: int, what: str, world: int, node: int) -> str:
        starts = self.worlds.prim_start
        k = int(np.searchsorted(starts, node, side="right") - 1)
        scene = self.worlds.scenes[world]
        return f"numerical failure at frame {frame + 1}: {what} in {scene.tubes[k].path} point {node - int(starts[k])}"
