"""Semi-implicit Euler with a whole frame's substeps kept on chip: one CUDA block per group of tubes.

:func:`make_onchip_kernel` builds, for one combination of :class:`~.integrate.Features` and one
block size, a kernel launched with ``wp.launch_tiled`` over (world blocks, node groups): each block
owns whole tubes, one thread per node. A thread loads its node's state and parameters into
registers once, then for every substep

1. writes its compensated position ``(q, q_lo)`` into a shared-memory tile (the element write ends
   in a block barrier),
2. reads its neighbours' positions (up to two either side, same tube) from that tile, evaluates
   its two structural springs and three bending stencils exactly as ``step_nodes`` of
   :mod:`.integrate` does, and advances its own state in registers,

and after the last substep stores the state once. The tile is double-buffered by substep parity,
so one barrier per substep suffices: a thread writes buffer ``s % 2`` only after the barrier of
substep ``s - 1``, which every thread passes after its reads of substep ``s - 2``.

Block layout (set by the host, :class:`warp_tube.centerline.explicit.SemiImplicitEulerSolver`): the tubes of one
world are packed, in order, into groups of at most ``block_dim`` nodes (``group_node_start``); a
block holds ``worlds_per_block`` copies of one group from consecutive worlds, each in ``slot``
consecutive lanes (``slot`` is the largest group's node count). So a tube must fit in one block:
at most ``block_dim`` <= 1024 points.

Features: structural and bending springs of a straight rest shape, pins (inverse mass 0, targets
lerped from ``pin_q_start`` to ``pin_q_end`` over the frame), anchors, gravity, mass-proportional
damping and external point forces. Curved rest shapes, spring damping and the assistant line are
not supported (:data:`UNSUPPORTED`): they need per-tube passes or extra state.

On the CPU the same kernel runs when ``wp.config.enable_cpu_blocks`` is set (Warp's cooperative
fibers stand in for a block's threads, the barrier switches between them): slow, for testing.
"""

from __future__ import annotations

import functools

import warp as wp

from .integrate import CUDA_OPTIONS, Features
from .springs import bend_gradients, spring_force

#: Features the on-chip kernel does not implement.
UNSUPPORTED = ("curved", "spring_damping", "assistant_line")

#: Largest block (threads = nodes) of the on-chip kernel; longer tubes need another path.
MAX_BLOCK_DIM = 1024

vec6 = wp.types.vector(length=6, dtype=wp.float32)


@wp.func
def pack6(q: wp.vec3, q_lo: wp.vec3) -> vec6:
    """A compensated position ``(q, q_lo)`` [m] as one shared-memory element."""
    return vec6(q[0], q[1], q[2], q_lo[0], q_lo[1], q_lo[2])


@wp.func
def delta6(a: vec6, b: vec6) -> wp.vec3:
    """``x_b - x_a`` [m] from packed compensated positions, as ``node_delta`` forms it."""
    return wp.vec3(b[0] - a[0], b[1] - a[1], b[2] - a[2]) + wp.vec3(b[3] - a[3], b[4] - a[4], b[5] - a[5])


@functools.cache
def make_onchip_kernel(features: Features, block_dim: int):
    """The on-chip substep kernel for ``features`` and ``block_dim`` threads per block; cached."""
    features = Features(*(bool(v) for v in features))
    bad = [name for name in UNSUPPORTED if features._asdict()[name]]
    if bad:
        raise ValueError(f"the on-chip kernel does not support: {', '.join(bad)}")
    if not 1 <= block_dim <= MAX_BLOCK_DIM:
        raise ValueError(f"block_dim must be in [1, {MAX_BLOCK_DIM}], got {block_dim}")
    BENDING = features.bending
    ANCHORS = features.anchors
    GRAVITY = features.gravity
    MASS_DAMPING = features.mass_damping
    EXTERNAL = features.external
    B = int(block_dim)

    @wp.func
    def advance(x: wp.vec3, lo: wp.vec3, v: wp.vec3, f: wp.vec3, inv_mass: float, alpha: float, dt: float):
        """Semi-implicit Euler step with compensated position sum, as ``advance`` of
        :mod:`.integrate`; returns (x', lo', v')."""
        v_new = v + f * (inv_mass * dt)
        if wp.static(MASS_DAMPING):
            v_new = v_new / (1.0 + alpha * dt)
        y = v_new * dt + lo
        x_new = x + y
        return x_new, y - (x_new - x), v_new

    @wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
    def substeps_onchip(
        substep_count: int,
        dt: float,
        slot: int,
        worlds_per_block: int,
        # model:
        group_node_start: wp.array[int],
        node_tube: wp.array[int],
        tube_node_start: wp.array[int],
        node_rest_q: wp.array2d[wp.vec3],
        node_mass: wp.array2d[float],
        node_inv_mass: wp.array2d[float],
        node_damping: wp.array2d[float],
        seg_rest_length: wp.array2d[float],
        seg_ke: wp.array2d[float],
        node_bend_k: wp.array2d[float],
        node_anchor_k: wp.array2d[float],
        node_anchor_kd: wp.array2d[float],
        gravity: wp.vec3,
        # state in:
        node_q_in: wp.array2d[wp.vec3],
        node_q_lo_in: wp.array2d[wp.vec3],
        node_qd_in: wp.array2d[wp.vec3],
        # control:
        node_f_ext: wp.array2d[wp.vec3],
        pin_q_start: wp.array2d[wp.vec3],
        pin_q_end: wp.array2d[wp.vec3],
        # out:
        node_q_out: wp.array2d[wp.vec3],
        node_q_lo_out: wp.array2d[wp.vec3],
        node_qd_out: wp.array2d[wp.vec3],
    ):
        """Advance the nodes of one group of tubes in ``worlds_per_block`` worlds by
        ``substep_count`` substeps of ``dt`` [s]; one thread per node, state in registers and
        positions exchanged through shared memory."""
        block, g, lane = wp.tid()
        c = lane // slot
        w = block * worlds_per_block + c
        i = group_node_start[g] + (lane - c * slot)
        active = c < worlds_per_block and w < node_q_in.shape[0] and i < group_node_start[g + 1]

        zero = wp.vec3(0.0)
        x = zero
        lo = zero
        v = zero
        f_grav = zero
        f_ext = zero
        x_rest = zero
        x_pin0 = zero
        x_pin1 = zero
        start = int(0)
        end = int(0)
        im = float(0.0)
        alpha = float(0.0)
        ka = float(0.0)
        kad = float(0.0)
        # Springs i-1 (to the previous node) and i, bending stencils at i-1, i, i+1.
        len_m1 = float(0.0)
        ke_m1 = float(0.0)
        len_0 = float(0.0)
        ke_0 = float(0.0)
        kb_m1 = float(0.0)
        kb_0 = float(0.0)
        kb_p1 = float(0.0)
        if active:
            pw = w % node_mass.shape[0]
            t = node_tube[i]
            start = tube_node_start[t]
            end = tube_node_start[t + 1]
            x = node_q_in[w, i]
            lo = node_q_lo_in[w, i]
            v = node_qd_in[w, i]
            im = node_inv_mass[pw, i]
            alpha = node_damping[pw, i]
            x_pin0 = pin_q_start[w, i]
            x_pin1 = pin_q_end[w, i]
            if i - 1 >= start:
                len_m1 = seg_rest_length[pw, i - 1]
                ke_m1 = seg_ke[pw, i - 1]
            if i + 1 < end:
                len_0 = seg_rest_length[pw, i]
                ke_0 = seg_ke[pw, i]
            if wp.static(BENDING):
                if i - 1 > start:
                    kb_m1 = node_bend_k[pw, i - 1]
                if i > start and i < end - 1:
                    kb_0 = node_bend_k[pw, i]
                if i + 1 < end - 1:
                    kb_p1 = node_bend_k[pw, i + 1]
            if wp.static(ANCHORS):
                ka = node_anchor_k[pw, i]
                kad = node_anchor_kd[pw, i]
                x_rest = node_rest_q[pw, i]
            if wp.static(GRAVITY):
                f_grav = gravity * node_mass[pw, i]
            if wp.static(EXTERNAL):
                f_ext = node_f_ext[w, i]

        buf = wp.tile_zeros(shape=(2, B), dtype=vec6, storage="shared")
        for step in range(substep_count):
            p = step % 2
            own = pack6(x, lo)
            # Every thread reaches this write: it ends in the block barrier.
            buf[p, lane] = own
            if active:
                if im == 0.0:
                    x_new = wp.lerp(x_pin0, x_pin1, float(step + 1) / float(substep_count))
                    v = (x_new - x) / dt
                    x = x_new
                    lo = zero
                else:
                    f = zero
                    em2 = zero
                    em1 = zero
                    e0 = zero
                    ep1 = zero
                    # Each neighbour read once from the tile; edges as node_delta forms them.
                    s_m1 = own
                    s_p1 = own
                    if i - 1 >= start:
                        s_m1 = wp.tile_extract(buf, p, lane - 1)
                        em1 = delta6(s_m1, own)
                        f += spring_force(-em1, zero, len_m1, ke_m1, 0.0)
                    if i + 1 < end:
                        s_p1 = wp.tile_extract(buf, p, lane + 1)
                        e0 = delta6(own, s_p1)
                        f += spring_force(e0, zero, len_0, ke_0, 0.0)
                    if wp.static(BENDING):
                        if i + 1 < end - 1:
                            ep1 = delta6(s_p1, wp.tile_extract(buf, p, lane + 2))
                            if kb_p1 != 0.0:
                                ga, gb, kb = bend_gradients(e0, ep1, zero, kb_p1)
                                f += ga
                        if i > start and i < end - 1:
                            if kb_0 != 0.0:
                                ga, gb, kb = bend_gradients(em1, e0, zero, kb_0)
                                f += gb - ga
                        if i - 1 > start:
                            em2 = delta6(wp.tile_extract(buf, p, lane - 2), s_m1)
                            if kb_m1 != 0.0:
                                ga, gb, kb = bend_gradients(em2, em1, zero, kb_m1)
                                f -= gb
                    # The other forces (gravity and the external force fixed over the frame),
                    # summed in the order node_force of .integrate uses.
                    fo = f_grav + f_ext
                    if wp.static(ANCHORS):
                        if ka > 0.0:
                            fo = fo - (x - x_rest) * ka - v * kad
                    f += fo
                    x, lo, v = advance(x, lo, v, f, im, alpha, dt)
        if active:
            node_q_out[w, i] = x
            node_q_lo_out[w, i] = lo
            node_qd_out[w, i] = v

    return substeps_onchip
