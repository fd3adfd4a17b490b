"""Solvers: launch order and scratch allocation for the centerline kernels.

``solver.step(state_in, state_out, control, dt)`` advances one substep;
``solver.integrate(state_in, state_out, control, dt, substeps)`` advances a whole frame. On the
CPU a frame is a single launch of the per-tube substep kernel; on CUDA it is ``substeps``
per-node launches. Either way a frame's launches are captured once into a graph and replayed
(:mod:`warp_tube.replay`; on the CPU through Warp's recorded-operation replay). With ``onchip=True`` a frame is one
launch of the on-chip kernel (:mod:`warp_tube.kernels.onchip`): a block per group of whole tubes
keeps their state in registers and shared memory over all the substeps.
"""

from __future__ import annotations

import logging

import numpy as np
import warp as wp

from warp_tube.kernels.integrate import ControlArrays, ModelArrays, ScratchArrays, StateArrays, make_kernels, pack
from warp_tube.kernels.onchip import MAX_BLOCK_DIM, UNSUPPORTED, make_onchip_kernel

#: threads per block of the on-chip kernel by default (H100: 5.9e10 hub-steps/s at 128 against
#: 5.4e10 at 256 and 5.0e10 at 512, 65,536 tubes x 32 points)
ONCHIP_BLOCK_DIM = 128

from ..model.tube import TubeControl, TubeModel, TubeState
from ..replay import GraphCache, cpu_blocks

__all__ = ["SemiImplicitEulerSolver"]

logger = logging.getLogger(__name__)


class SemiImplicitEulerSolver:
    """Semi-implicit (symplectic) Euler, specialised to the model's features.

    Args:
        model: the discretised scene.
        per_node: use the per-node kernels (default: on CUDA devices); else the per-tube loop.
        block_dim: CUDA threads per block (default 256 for the per-node kernels, 128 for the
            on-chip kernel: measured fastest on an H100).
        onchip: run each frame as one launch of the on-chip kernel (a block per group of whole
            tubes, substeps in registers and shared memory). Default: on CUDA whenever the model
            allows it. Not for curved rest shapes, spring damping or assistant lines (True:
            ValueError; default: the per-node path). Its block grows to the longest tube (rounded
            up to 32); a tube longer than 1,024 points falls back to the default path, logged.
            On the CPU it runs on Warp's cooperative CPU blocks (slow: for testing).
    """

    name = "semiImplicitEuler"

    def __init__(self, model: TubeModel, per_node: bool | None = None, block_dim: int | None = None, onchip: bool | None = None):
        self.model = model
        self.device = wp.get_device(model.device)
        self.per_node = self.device.is_cuda if per_node is None else per_node
        self.substeps_kernel, self.targets_kernel, self.step_kernel, self.al_kernel = make_kernels(model.features)
        self.block_dim = int(block_dim or 256)
        W, N = model.world_count, model.node_count
        slots = max(model.al_slots, 1)
        self._node_f = wp.zeros((W, N), dtype=wp.vec3, device=self.device)
        self._al_f = wp.zeros((W, slots), dtype=wp.vec3, device=self.device)
        rows = W if model.features.curved else 1
        self._kappa_target = wp.zeros((rows, N), dtype=wp.vec3, device=self.device)
        self._f_frame = wp.zeros((rows, N), dtype=wp.vec3, device=self.device)
        self._tmp = model.state() if self.per_node else None
        self._graphs = GraphCache(self.device)
        self._model_arrays = pack(ModelArrays, model)
        self._scratch = ScratchArrays()
        self._scratch.node_f, self._scratch.al_f, self._scratch.node_kappa_target = self._node_f, self._al_f, self._kappa_target
        self._commands = {}
        self.onchip_block_dim = None  # threads per block of the on-chip kernel, when it is used
        if onchip is None:
            onchip = self.device.is_cuda and not any(model.features._asdict()[name] for name in UNSUPPORTED)
        self._onchip_request = int(block_dim or ONCHIP_BLOCK_DIM)
        self.onchip = bool(onchip) and self._setup_onchip()

    # -- the on-chip path ---------------------------------------------------------------------
    def _setup_onchip(self) -> bool:
        """Check the model, pack tubes into blocks and build the kernel; False: fall back."""
        m = self.model
        bad = [name for name in UNSUPPORTED if m.features._asdict()[name]]
        if bad:
            raise ValueError(f"onchip=True does not support this model's {', '.join(bad)}; use onchip=False")
        starts = np.asarray(m.host["tube_node_start"], dtype=np.int64)
        longest = int(np.diff(starts).max())
        if longest > MAX_BLOCK_DIM:
            logger.warning("onchip: a tube of %d points exceeds the %d-thread block; using the default path", longest, MAX_BLOCK_DIM)
            return False
        block = min(self._onchip_request, MAX_BLOCK_DIM)
        if longest > block:
            block = -(-longest // 32) * 32
        # Whole tubes, in order, packed into groups of at most `block` nodes; a block holds as many
        # copies of a group (consecutive worlds) as fit.
        group = [0]
        for t in range(m.tube_count):
            if starts[t + 1] - group[-1] > block:
                group.append(int(starts[t]))
        group.append(int(starts[-1]))
        group = np.asarray(group)
        self._onchip_slot = int(np.diff(group).max())
        self._onchip_worlds_per_block = block // self._onchip_slot
        self.onchip_block_dim = block
        self._onchip_dim = (-(-m.world_count // self._onchip_worlds_per_block), len(group) - 1)
        self._onchip_group = wp.array(group.astype(np.int32), dtype=int, device=self.device)
        self.onchip_kernel = make_onchip_kernel(m.features, block)
        return True

    def _launch_onchip(self, s_in: TubeState, s_out: TubeState, c: TubeControl, dt: float, substeps: int):
        m = self.model
        with cpu_blocks():  # on the CPU a block's threads are fibers (opt-in)
            wp.launch_tiled(
                self.onchip_kernel, dim=self._onchip_dim, block_dim=self.onchip_block_dim, device=self.device,
                inputs=[int(substeps), float(dt), self._onchip_slot, self._onchip_worlds_per_block, self._onchip_group,
                        m.node_tube, m.tube_node_start, m.node_rest_q, m.node_mass, m.node_inv_mass, m.node_damping,
                        m.seg_rest_length, m.seg_ke, m.node_bend_k, m.node_anchor_k, m.node_anchor_kd, m.gravity,
                        s_in.node_q, s_in.node_q_lo, s_in.node_qd, c.node_f_ext, c.pin_q_start, c.pin_q_end],
                outputs=[s_out.node_q, s_out.node_q_lo, s_out.node_qd],
            )  # fmt: skip

    # -- one substep on the per-node path ------------------------------------------------------
    def _launch_step(self, s_in: TubeState, s_out: TubeState, c: TubeControl, dt: float, frac: float):
        m = self.model
        state, control = pack(StateArrays, s_in), pack(ControlArrays, c)
        if m.features.curved:
            wp.launch(self.targets_kernel, (m.world_count, m.tube_count), device=self.device,
                      inputs=[self._model_arrays, state], outputs=[self._kappa_target, self._f_frame])  # fmt: skip
        wp.launch(
            self.step_kernel, (m.world_count, m.node_count), device=self.device, block_dim=self.block_dim,
            inputs=[frac, dt, m.node_tube, self._model_arrays, state, control, self._kappa_target, self._f_frame],
            outputs=[s_out.node_q, s_out.node_q_lo, s_out.node_qd],
        )  # fmt: skip
        if m.features.assistant_line:
            wp.launch(
                self.al_kernel, (m.world_count, m.al_slots), device=self.device,
                inputs=[dt, m.force_tube, m.al_force_index, self._model_arrays, state, control],
                outputs=[s_out.al_q, s_out.al_q_lo, s_out.al_qd],
            )  # fmt: skip

    def _launch_substeps(self, s_in: TubeState, s_out: TubeState, c: TubeControl, dt: float, substeps: int):
        # A recorded launch replays without re-packing its ~40 arguments (~15 us on the CPU).
        key = (id(s_in), id(s_out), id(c))
        cached = self._commands.get(key)
        cmd = cached[-1] if cached is not None else None
        if cmd is not None:
            cmd.set_param_at_index(0, int(substeps))
            cmd.set_param_at_index(1, float(dt))
            cmd.launch()
            return
        cmd = wp.launch(
            self.substeps_kernel, (self.model.world_count, self.model.tube_count), device=self.device,
            inputs=[int(substeps), dt, self._model_arrays, pack(StateArrays, s_in), pack(ControlArrays, c),
                    self._scratch],
            outputs=[pack(StateArrays, s_out)],
            record_cmd=True,
        )  # fmt: skip
        cmd.launch()
        if len(self._commands) > 16:
            self._commands.clear()
        # Hold the states and control too: a recorded launch points at their arrays, and while
        # they are held no new object can reuse their ids.
        self._commands[key] = (s_in, s_out, c, cmd)

    def step(self, state_in: TubeState, state_out: TubeState, control: TubeControl, dt: float):
        """Advance one substep of ``dt`` [s]; pins reach ``control.pin_q_end``."""
        self.integrate(state_in, state_out, control, dt, 1)

    def integrate(self, state_in: TubeState, state_out: TubeState, control: TubeControl, dt: float, substeps: int):
        """Advance ``substeps`` substeps of ``dt`` [s] from ``state_in`` into ``state_out``.

        ``state_in`` is left unchanged; pins move linearly from ``control.pin_q_start`` to
        ``control.pin_q_end`` over the interval. The launches of a frame are captured once per
        (states, control, dt, substeps) and replayed (:mod:`warp_tube.replay`).
        """
        dt, substeps = float(dt), int(substeps)
        if self.onchip:
            launch = lambda: self._launch_onchip(state_in, state_out, control, dt, substeps)  # noqa: E731
        elif self.per_node:
            launch = lambda: self._chain(state_in, state_out, control, dt, substeps)  # noqa: E731
        else:
            launch = lambda: self._launch_substeps(state_in, state_out, control, dt, substeps)  # noqa: E731
        key = (id(state_in), id(state_out), id(control), dt, substeps)
        self._graphs.run(key, launch, hold=(state_in, state_out, control))

    def _chain(self, state_in, state_out, control, dt, substeps):
        src = state_in
        for s in range(substeps):
            dst = state_out if (substeps - s) % 2 == 1 else self._tmp
            self._launch_step(src, dst, control, float(dt), float(s + 1) / float(substeps))
            src = dst
