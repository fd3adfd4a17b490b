"""Semi-implicit Euler solver: launch order and scratch allocation for the centerline kernels.

``solver.step(state_in, state_out, control, dt)`` advances one substep;
``solver.integrate(state_in, state_out, control, dt, substeps)`` advances a whole frame in one
launch, of one of two kernels that sum the same force terms (:mod:`warp_tube.kernels.springs`):

- the on-chip kernel (:mod:`warp_tube.kernels.onchip`), the default on CUDA: a block per group of
  whole tubes keeps their state in registers and shared memory over all the substeps, a thread
  per node; every feature (curved rest shapes, both dampings, anchors, gravity, point forces and
  their assistant lines);
- the per-tube kernel (:mod:`warp_tube.kernels.integrate`), the default on the CPU, and the path
  on CUDA for a model with a tube longer than a block (:data:`MAX_BLOCK_DIM` points): one thread
  per (world, tube) runs the substeps along its tube in order. Correct on either device; on CUDA
  such a tube is advanced by a single thread, so it costs about what one CPU core would.

A frame's launch is captured once into a graph and replayed (:mod:`warp_tube.runtime.replay`; on the CPU
through Warp's recorded-operation replay).
"""

from __future__ import annotations

import logging

import numpy as np
import warp as wp

from warp_tube.kernels.integrate import ScratchArrays, make_kernels
from warp_tube.kernels.onchip import MAX_BLOCK_DIM, make_onchip_kernel
from warp_tube.kernels.springs import ControlArrays, ModelArrays, StateArrays, pack

from ..model.tube import TubeControl, TubeModel, TubeState
from ..runtime.replay import GraphCache, cpu_blocks

__all__ = ["SemiImplicitEulerSolver", "ONCHIP_BLOCK_DIM", "MAX_BLOCK_DIM", "EXCHANGES", "warp_aligned"]

#: threads per block of the on-chip kernel by default (H100, the minimal kernel before every
#: feature ran on chip: 5.9e10 hub-steps/s at 128 against 5.4e10 at 256 and 5.0e10 at 512,
#: 65,536 tubes x 32 points)
ONCHIP_BLOCK_DIM = 128

#: registers per thread the on-chip kernel is held to on CUDA where the compiler would take more:
#: fewer registers let more blocks share a multiprocessor, at the price of spills to local memory.
#: H100, 65,536 x 32-point tubes with every feature: 203 -> 128 registers (264 bytes spilled a
#: thread), 212 -> 156 us a substep; the assistant line alone 141 -> 128, 57 -> 50 us. A kernel
#: that fits is left as compiled (holding the minimal kernel, 88 registers, to 128 made it 7%
#: slower). `benchmarks/bench_centerline.py` reports each case's registers and spills.
ONCHIP_MAX_REGISTERS = 128

#: how the on-chip kernel's threads exchange neighbours' values: through warp shuffles (CUDA, every
#: tube within one warp of 32 threads), the scans of curved tubes through shuffles carried between
#: warps (CUDA, any layout; by request), through shared memory, or shuffles where they apply
EXCHANGES = ("auto", "shuffle", "mixed", "shared")

logger = logging.getLogger(__name__)


def pads_to_warps(exchange: str, curved: bool) -> bool:
    """Whether tubes of at most 32 points that the compact on-chip layout would let cross a warp
    boundary are laid out one group to a slot of 1, 2, 4, ... 32 lanes instead (some lanes idle),
    so that the exchange runs through warp shuffles: by request (``exchange="shuffle"``), and under
    ``"auto"`` for curved tubes, whose two scans a substep make the padded shuffles faster than the
    compact layout's shared memory (one H100, 65,536 tubes of 12, 20 and 24 points with every
    feature: 1.16-1.42x; curved alone 1.32-1.62x); straight tubes keep the compact layout (the
    minimal scene 1.18-1.39x faster there; BENCHMARKS.md, "Tubes that do not fill a warp")."""
    return exchange == "shuffle" or (exchange == "auto" and bool(curved))


def warp_aligned(tube_start: np.ndarray, group_start: np.ndarray, slot: int, copies: int) -> bool:
    """Whether every tube lies within one warp (32 threads) in the on-chip layout: the tubes of
    group ``g`` (node range ``group_start[g] .. group_start[g + 1]``) at lanes ``c * slot + (node -
    group_start[g])`` for copies ``c < copies`` of the group in a block."""
    starts = np.asarray(tube_start, dtype=np.int64)
    groups = np.asarray(group_start, dtype=np.int64)
    g = np.searchsorted(groups, starts[:-1], side="right") - 1  # each tube's group
    first = starts[:-1] - groups[g]
    last = starts[1:] - 1 - groups[g]
    c = np.arange(copies, dtype=np.int64)[:, None] * int(slot)
    return bool(np.all((c + first) // 32 == (c + last) // 32))


def twist_free(model: TubeModel) -> bool:
    """Whether a curved tube of ``model`` has a first edge that may turn (not both of its nodes
    pinned): its first frame is twisted to the bending energy's minimum
    (:func:`warp_tube.kernels.bending.curvature_targets`)."""
    if not (model.features.curved and model.features.bending):
        return False
    starts = np.asarray(model.host.tube_node_start, dtype=np.int64)
    inv = np.asarray(model.host.node_inv_mass)  # (the pins every world of a batch shares)
    return bool(np.any((np.diff(starts) >= 3) & ((inv[starts[:-1]] > 0) | (inv[starts[:-1] + 1] > 0))))


class SemiImplicitEulerSolver:
    """Semi-implicit (symplectic) Euler, specialised to the model's features.

    Args:
        model: the discretised scene.
        block_dim: threads per block of the on-chip kernel (default :data:`ONCHIP_BLOCK_DIM`);
            the block grows to the longest tube (rounded up to 32).
        onchip: run each frame as one launch of the on-chip kernel. Default: on CUDA. A model
            with a tube longer than :data:`MAX_BLOCK_DIM` points takes the per-tube kernel instead
            (logged). On the CPU the on-chip kernel runs on Warp's cooperative CPU blocks (slow:
            for testing).
        exchange: how the on-chip kernel's threads exchange their neighbours' values
            (:data:`EXCHANGES`): "shuffle" through registers (warp shuffles; CUDA, where every
            tube lies within one warp of the layout, which it pads where a world's tubes fit in
            a warp: each world in 1, 2, 4, ... 32 lanes), "mixed" (CUDA, any layout: the scans
            of curved tubes through shuffles, carried between warps through shared memory, the
            rest through shared memory; the order of a scan's products then depends on where a
            tube sits against warp boundaries, so a world's result can differ by round-off with
            its place in the block), "shared" through shared memory and block barriers; "auto"
            (default) shuffles where the layout has every tube within a warp or curved tubes of
            at most 32 points can be padded to whole warps (:func:`pads_to_warps`), else shared
            memory: in both a world computes the same whatever its place in the block, so a
            variant gives the same numbers in a batch and alone. All three exchange the same
            values and do the same arithmetic (the compiler's FMA contractions may differ:
            float32 round-off apart).
    """

    name = "semiImplicitEuler"

    def __init__(self, model: TubeModel, block_dim: int | None = None, onchip: bool | None = None,
                 exchange: str = "auto"):  # fmt: skip
        self.model = model
        self.device = wp.get_device(model.device)
        self.substeps_kernel = make_kernels(model.features)
        W, N = model.world_count, model.node_count
        self._scratch = ScratchArrays()
        self._scratch.node_f = wp.zeros((W, N), dtype=wp.vec3, device=self.device)
        self._scratch.al_f = wp.zeros((W, max(model.al_slots, 1)), dtype=wp.vec3, device=self.device)
        self._scratch.node_kappa_target = wp.zeros((W if model.features.curved else 1, N), dtype=wp.vec3, device=self.device)
        self._graphs = GraphCache(self.device)
        self._model_arrays = pack(ModelArrays, model)
        self._commands = {}
        self.onchip_block_dim = None  # threads per block of the on-chip kernel, when it is used
        self._onchip_request = int(block_dim or ONCHIP_BLOCK_DIM)
        if exchange not in EXCHANGES:
            raise ValueError(f"exchange must be one of {EXCHANGES}, got {exchange!r}")
        self._exchange_request = exchange
        self.onchip_exchange = None  # "shuffle", "mixed" or "shared", when the on-chip kernel is used
        self.onchip = bool(self.device.is_cuda if onchip is None else onchip) and self._setup_onchip()

    # -- the on-chip path ---------------------------------------------------------------------
    def _setup_onchip(self) -> bool:
        """Pack tubes into blocks and build the kernel; False: a tube is too long for a block."""
        m = self.model
        starts = np.asarray(m.host.tube_node_start, dtype=np.int64)
        longest = int(np.diff(starts).max())
        if longest > MAX_BLOCK_DIM:
            logger.warning("onchip: a tube of %d points exceeds the %d-thread block; using the per-tube kernel", longest, MAX_BLOCK_DIM)
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
        slot = int(np.diff(group).max())
        copies = block // slot
        # (judged on every copy a block can hold, not on the worlds there are: a variant run alone
        # takes the exchange its batch takes, and so the same arithmetic)
        aligned = warp_aligned(starts, group, slot, copies)
        exchange = self._exchange_request
        if self.device.is_cuda and not aligned and slot <= 32 and pads_to_warps(exchange, m.features.curved):
            # Groups of at most a warp: each copy in a slot of 1, 2, 4, ... 32 lanes, so that none
            # crosses a warp boundary (the lanes past a group's nodes idle)
            slot = 1 << (slot - 1).bit_length()
            copies = block // slot
            aligned = True
        free = twist_free(m)
        if exchange == "auto":
            exchange = "shuffle" if self.device.is_cuda and aligned else "shared"
        elif exchange == "mixed" and free:
            raise ValueError("exchange 'mixed': a curved tube free to turn needs the shared-memory or the shuffle exchange")
        elif exchange == "shuffle" and not (self.device.is_cuda and aligned):
            raise ValueError("exchange 'shuffle' needs a CUDA device and tubes that each lie within one warp of 32 threads")
        elif exchange == "mixed" and not self.device.is_cuda:
            raise ValueError("exchange 'mixed' needs a CUDA device (warp shuffles)")
        self._onchip_slot = slot
        self._onchip_worlds_per_block = copies
        self.onchip_block_dim = block
        self._onchip_dim = (-(-m.world_count // copies), len(group) - 1)
        self._onchip_group = wp.array(group.astype(np.int32), dtype=int, device=self.device)
        lines = m.al_lines if m.features.assistant_line else 0
        self.onchip_exchange = exchange
        self._onchip_free = free
        self.onchip_kernel = make_onchip_kernel(m.features, block, lines, exchange=exchange, twist_free=free)
        self._onchip_lines = lines
        self._onchip_registers_checked = not self.device.is_cuda
        return True

    def _hold_registers(self) -> None:
        """On the first launch outside a graph capture (where the kernel compiles anyway): swap in
        the variant held to :data:`ONCHIP_MAX_REGISTERS` if the compiler gave the kernel more."""
        self._onchip_registers_checked = True
        props = wp.get_cuda_kernel_properties(self.onchip_kernel, self.device, self.onchip_block_dim)
        if props["register_count"] > ONCHIP_MAX_REGISTERS:
            self.onchip_kernel = make_onchip_kernel(self.model.features, self.onchip_block_dim, self._onchip_lines,
                                                    max_registers=ONCHIP_MAX_REGISTERS, exchange=self.onchip_exchange,
                                                    twist_free=self._onchip_free)  # fmt: skip

    def _launch_onchip(self, s_in: TubeState, s_out: TubeState, c: TubeControl, dt: float, substeps: int):
        m = self.model
        if not self._onchip_registers_checked and not self.device.is_capturing:
            self._hold_registers()
        with cpu_blocks():  # on the CPU a block's threads are fibers (opt-in)
            wp.launch_tiled(
                self.onchip_kernel, dim=self._onchip_dim, block_dim=self.onchip_block_dim, device=self.device,
                inputs=[int(substeps), float(dt), self._onchip_slot, self._onchip_worlds_per_block, self._onchip_group,
                        m.node_tube, self._model_arrays, pack(StateArrays, s_in), pack(ControlArrays, c)],
                outputs=[pack(StateArrays, s_out)],
            )  # fmt: skip

    # -- the per-tube path ----------------------------------------------------------------------
    def _launch_substeps(self, s_in: TubeState, s_out: TubeState, c: TubeControl, dt: float, substeps: int):
        # A recorded launch replays without re-packing its arguments (~15 us on the CPU).
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
            inputs=[int(substeps), dt, self._model_arrays, pack(StateArrays, s_in), pack(ControlArrays, c), self._scratch],
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
        ``control.pin_q_end`` over the interval. The launch of a frame is captured once per
        (states, control, dt, substeps) and replayed (:mod:`warp_tube.runtime.replay`).
        """
        dt, substeps = float(dt), int(substeps)
        if self.onchip:
            launch = lambda: self._launch_onchip(state_in, state_out, control, dt, substeps)  # noqa: E731
        else:
            launch = lambda: self._launch_substeps(state_in, state_out, control, dt, substeps)  # noqa: E731
        key = (id(state_in), id(state_out), id(control), dt, substeps)
        self._graphs.run(key, launch, hold=(state_in, state_out, control))
