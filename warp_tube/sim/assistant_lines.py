"""The assistant-line rule of a model's forces, run on the model's device before each frame.

:class:`AssistantLines` holds the rule's own arrays and launches
:mod:`warp_tube.kernels.assistant_rule`: each world's lines are built, kept or removed from its
forces and its current shape, with no copy of the state to the host. ``warp-tube run``
(:class:`~warp_tube.sim.control.FrameControl`) and ``warp-tube batch``
(:class:`~warp_tube.batch.control.WorldControl`) both use it, so a variant in a batch and the same
scene run alone build the same lines bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..kernels.assistant_rule import assistant_line_rule, lay_assistant_lines

__all__ = ["AssistantLines", "AL_REBUILD_ANGLE", "AL_MIN_ANGLE"]

#: the assistant line is rebuilt when its force turns by more than this [rad].
AL_REBUILD_ANGLE = math.radians(45.0)
#: no assistant line is built for a force within this angle of the tube's axis [rad].
AL_MIN_ANGLE = math.radians(15.0)


class AssistantLines:
    """The rule's state on the device: each world's force vectors, the direction each line was
    built with, and where lines are laid this frame.

    Args:
        model: the :class:`~warp_tube.model.tube.TubeModel` (topology, world count, device).
        node_radius: tube radius at each node [m]: (N,), shared by every world, or (W, N).
    """

    def __init__(self, model, node_radius: np.ndarray):
        self.model = m = model
        W, F = m.world_count, max(m.force_count, 1)
        r = np.asarray(node_radius, dtype=np.float64)
        r = np.broadcast_to(r, (W, m.node_count)) if r.ndim == 1 else r
        dev = m.device
        self.node_radius = wp.array(np.ascontiguousarray(r), dtype=wp.float64, device=dev)
        uses = np.zeros(F, dtype=np.int32)
        uses[: m.force_count] = np.asarray(m.host.force_uses_al, dtype=np.int32)
        self.uses_al = wp.array(uses, dtype=wp.int32, device=dev)
        self.force = wp.zeros((W, F), dtype=wp.vec3d, device=dev)
        self.al_dir = wp.zeros((W, F), dtype=wp.vec3d, device=dev)
        self.lay_dir = wp.zeros((W, F), dtype=wp.vec3d, device=dev)
        self.lay = wp.zeros((W, F), dtype=int, device=dev)
        # The two launches recorded per (state, control) pair (a run alternates two states): a
        # recorded launch costs a few microseconds on the CPU, a new one tens. Each holds its
        # arrays, so their addresses identify them for as long as it is kept.
        self._launches: dict = {}
        self._forces_last = None  # the forces last uploaded (held forces go up once)

    def set_forces(self, forces: np.ndarray) -> None:
        """Each world's model forces [N], (W, F, 3) or (F, 3) for every world alike (model order);
        uploaded only where they differ from the last ones given."""
        f = np.array(forces, dtype=np.float64)  # (a copy: the caller may change its array later)
        if self._forces_last is not None and np.array_equal(f, self._forces_last):
            return
        self._forces_last = f
        if f.ndim == 2:
            f = np.broadcast_to(f, (self.model.world_count, *f.shape))
        self.force.assign(np.ascontiguousarray(f))

    def update(self, state, control) -> None:
        """Build, keep or remove each world's lines for the frame starting from ``state`` (the
        forces last given to :meth:`set_forces`), writing the lines' state into ``state`` and their
        rest lengths and flags into ``control``."""
        m = self.model
        if not m.force_count or not m.al_slots:
            return
        key = (state.node_q.ptr, state.al_q.ptr, control.al_active.ptr)
        launches = self._launches.get(key)
        if launches is None:
            rule = wp.launch(assistant_line_rule, dim=(m.world_count, m.force_count),
                             inputs=[self.force, self.uses_al, m.force_node, m.force_tube, m.tube_node_start, state.node_q,
                                     state.node_q_lo, wp.float64(math.cos(AL_REBUILD_ANGLE)), wp.float64(math.sin(AL_MIN_ANGLE))],
                             outputs=[self.al_dir, control.al_active, self.lay_dir, self.lay], device=m.device,
                             record_cmd=True)  # fmt: skip
            lay = wp.launch(lay_assistant_lines, dim=(m.world_count, m.al_slots),
                            inputs=[self.lay, self.lay_dir, m.al_force_index, m.al_start, m.force_tube, m.tube_node_start,
                                    state.node_q, state.node_q_lo, state.node_qd, self.node_radius],
                            outputs=[state.al_q, state.al_q_lo, state.al_qd, control.al_link_length, control.al_chord_length,
                                     control.al_fwd_length, control.al_bwd_length], device=m.device, record_cmd=True)  # fmt: skip
            if len(self._launches) >= 8:
                self._launches.clear()
            launches = self._launches[key] = (rule, lay)
        for launch in launches:
            launch.launch()
