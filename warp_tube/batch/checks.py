"""Per-world frame checks of a batch: ``Simulation``'s checks, world by world, so one variant can
fail while the others go on.

A world fails a frame when a position or velocity is not finite, a free point is farther than
``RUNAWAY_LENGTHS`` tube lengths from its rest position, or its kinetic energy exceeds ten times
the work its forces and gravity did plus a round-off floor (moving pins: no energy check), as in
``Simulation``. The sums run on the device (:class:`warp_tube.sim.checks.FrameChecks`, with each
world's own rest shape, masses, runaway distance and energy floor): the host reads five numbers
per world a frame, and whole arrays only to name the point of a world that failed.
"""

from __future__ import annotations

import numpy as np

from ..sim.checks import FrameChecks
from .worlds import Worlds

__all__ = ["WorldChecks"]


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
        # Each world's largest extent of a tube prim's rest points [m] (its tubes' points are its
        # rest positions, prim after prim)
        starts = worlds.prim_start
        rest = self.rest[:1] if worlds.rest_shared else self.rest  # (one world's, repeated: the same numbers)
        extent = np.max([np.ptp(rest[:, a:b], axis=1).max(axis=1) for a, b in zip(starts[:-1], starts[1:])], axis=0)
        extent = np.broadcast_to(extent, (W,))
        # Simulation's round-off floor of the energy check, per world.
        scale = np.maximum(np.maximum(extent, np.abs(self.rest).reshape(W, -1).max(axis=1)), 1e-9)
        energy_floor = np.sum(h.seg_ke, axis=1) * (1e-6 * scale) ** 2 + 1e-30
        self.device_checks = FrameChecks(worlds.model, extent=extent[:, None], energy_floor=energy_floor[:, None],
                                         gravity=gravity, rest_q=h.node_rest_q, node_mass=h.node_mass,
                                         node_inv_mass=h.node_inv_mass)  # fmt: skip
        self.device_checks.pin_allowance[:] = np.inf if moving_pins else 0.0

    @property
    def work(self) -> np.ndarray:
        """Work of the forces and gravity so far [J], per world (W,)."""
        return self.device_checks.work[:, 0]

    def distance(self, slot: int) -> np.ndarray:
        """Largest distance of a point from its rest position in the frame in host slot ``slot``
        [m], (W,)."""
        return self.device_checks.distance(slot)[:, 0]

    def stretch(self, slot: int) -> np.ndarray:
        """The largest factor by which a segment's length departs from its rest length in the frame
        in host slot ``slot`` (``max(l / l0, l0 / l)``) [1], (W,)."""
        return self.device_checks.stretch(slot)[:, 0]

    def launch(self, before, after, control, slot: int) -> None:
        """Queue the sums of the frame from state ``before`` to ``after`` and their copy back into
        host slot ``slot`` on the device's stream (see :meth:`check`)."""
        self.device_checks.launch(before, after, control, slot)

    def check(self, frame: int, after, alive: np.ndarray, slot: int) -> dict:
        """Problems of the frame :meth:`launch`-ed into ``slot`` (output frame ``frame`` to
        ``frame + 1``, ending at state ``after``), ``{world: message}``, among the ``alive``
        worlds, once the device's stream has reached it; the frame's work is counted for every
        world."""
        failures, work = self.device_checks.check_measured(self.device_checks.measured(slot), after)
        self.device_checks.accept(work)
        out = {}
        for f in failures:
            if alive[f.world] and f.world not in out:
                out[f.world] = self._message(frame, f.what, f.world, f.node)
        return out

    def kinetic_energy(self, qd: np.ndarray) -> np.ndarray:
        """Kinetic energy of the free points [J], per world, from velocities (W, N, 3) [m/s]."""
        return 0.5 * np.einsum("wn,wnk,wnk->w", self.device_checks.free_mass, qd, qd, dtype=np.float64)

    def _message(self, frame: int, what: str, world: int, node: int) -> str:
        starts = self.worlds.prim_start
        k = int(np.searchsorted(starts, node, side="right") - 1)
        scene = self.worlds.scenes[world]
        return f"numerical failure at frame {frame + 1}: {what} in {scene.tubes[k].path} point {node - int(starts[k])}"
