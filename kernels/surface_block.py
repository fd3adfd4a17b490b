"""The surface rebuilt by one warp per span of a world (Warp): the GPU's path.

:func:`make_surface_block_kernel` builds, per block shape, a kernel that runs the work of the
world kernel (:mod:`warp_tube.kernels.surface_world`) spread over the :data:`WORLD_LANES` lanes of
a warp, phase by phase, with the same functions in the same order, so both give the same points and
normals. A span is a run of whole tubes of a world (``SurfaceArrays.span_*``): a batch's worlds
are one span each, and a world of many tubes (a scene run alone) is split into spans so that its
tubes are rebuilt by many warps; a world's bounds are then reduced over its spans by
:func:`span_extent_kernel`. Launched with ``wp.launch_tiled``; on the CPU (tests) a block's threads
are fibers.
"""

import functools

import warp as wp

from .frames import hub_local_frame, hub_tangent, reflect_frame, reflection_pair_a, reflection_pair_b, tube_start_normal
from .options import CUDA_OPTIONS
from .surface_arrays import SurfaceArrays
from .surface_guard import hub_guard, ring_guard
from .surface_spokes import ring_vertices

WORLD_LANES = 32
"""Threads of :func:`make_surface_block_kernel`'s kernel per world (one warp)."""

SURFACE_RING_LANES = 8
"""Lanes of a world's warp that share a ring (at most; fewer with fewer spokes)."""


@wp.func
def span_ring(k: int, h_first: int, body_rings: int, cap_first: int):
    """Ring ``k`` of a span: its body rings (the span's hubs' indices), then its cap rings."""
    if k < body_rings:
        return h_first + k
    return cap_first + k - body_rings


@functools.cache
def make_surface_block_kernel(worlds_per_block: int, min_blocks: int, split: bool = False):
    """The GPU rebuild, a warp of :data:`WORLD_LANES` threads per world (``split``: per span of a
    world), ``worlds_per_block`` warps per block, compiled for at least ``min_blocks`` resident
    blocks per multiprocessor (CUDA ``__launch_bounds__``; 0: no such bound). Cached per
    arguments. Without ``split`` the span arrays are not read (a world is one span)."""
    B = WORLD_LANES * int(worlds_per_block)
    bounds = (B, int(min_blocks)) if min_blocks else B

    @wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS, launch_bounds=bounds)
    def surface_block_kernel(arrays: SurfaceArrays, node_q: wp.array2d[wp.vec3]):
        """A span of a world's surface rebuilt by one warp (``wp.launch_tiled`` over blocks of
        ``worlds_per_block`` warps, warp ``u`` taking span ``u % span_count`` of world
        ``u // span_count``), phase by phase:

        1. frames: local ones by a lane per hub; rotation-minimizing ones a chunk of hubs at a
           time, each step's reflections by a lane per hub, their product along the tube by the
           warp's lane 0 (:func:`~warp_tube.kernels.frames.reflect_frame`);
        2. per-hub guard data (:func:`~warp_tube.kernels.surface_guard.hub_guard`), a lane per hub;
        3. guarded lengths (:func:`~warp_tube.kernels.surface_guard.ring_guard`), a lane per ring
           (guard on only);
        4. points and normals (:func:`~warp_tube.kernels.surface_spokes.ring_vertices`):
           :data:`SURFACE_RING_LANES` lanes to a ring, several rings at a time, so that a ring's
           reads serve several spokes and runs of consecutive lanes write consecutive vertices;
        5. the points' bounds, reduced over the warp (halving, five rounds) into ``extent_out``
           (a world of several spans: into ``span_bounds``).

        A phase reads what the previous one wrote (scratch arrays in ``arrays``) after a block
        barrier (the write of one element of a shared tile, which every thread reaches).

        Args:
            arrays: the surface's arrays (:class:`~warp_tube.kernels.surface_arrays.SurfaceArrays`).
            node_q: hub positions [length unit], shape (world_count, >= node_offset + node_count).
        """
        node_offset = arrays.node_offset
        tube_node_start = arrays.tube_node_start
        node_tube = arrays.node_tube
        block, thread = wp.tid()
        u = block * wp.static(worlds_per_block) + thread // WORLD_LANES  # the warp's span of a world
        spans = int(1)
        w = u
        span = int(0)
        h_first = int(0)
        h_end = node_tube.shape[0]
        hubs_max = h_end
        cap_first = h_end
        body_rings = h_end
        ring_count = arrays.ring_hub.shape[0]
        if wp.static(split):
            spans = arrays.span_count
            w = u // spans
            span = u - w * spans
            h_first = arrays.span_hub_start[span]
            h_end = arrays.span_hub_start[span + 1]
            hubs_max = arrays.span_hubs_max
            cap_first = arrays.span_cap_ring[span]
            body_rings = h_end - h_first  # (a body ring has its hub's index)
            ring_count = body_rings + arrays.span_cap_ring[span + 1] - cap_first
        lane = thread % WORLD_LANES
        active = w < node_q.shape[0]
        pw = w % arrays.node_rest_t.shape[0]  # row of the rest frames
        guard = arrays.guard_reach > 0.0
        barrier = wp.tile_zeros(shape=(wp.static(B),), dtype=int, storage="shared")
        step_a = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec4, storage="shared")
        step_b = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec4, storage="shared")
        step_c = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec4, storage="shared")
        r_carried = wp.vec3(0.0)

        if arrays.local_frames != 0:
            if active:
                for h in range(h_first + lane, h_end, WORLD_LANES):
                    hub_local_frame(
                        w, h, node_offset, tube_node_start, node_tube, arrays.node_rest_t, arrays.node_rest_r, node_q,
                        arrays.hub_t, arrays.hub_r,
                    )  # fmt: skip
        else:
            # Rotation-minimizing frames, a chunk of WORLD_LANES hubs at a time: every lane finds
            # its hub's tangent and the two reflections of the step that reaches it (or, at a
            # tube's first hub, its start normal), which depend on positions and tangents only;
            # then the world's lane 0 carries the normal along the chunk through them, one hub
            # after the other, so only that short product is sequential. Every warp of the block
            # goes round as often (the most hubs of a span): each round ends in a block barrier.
            base = thread - lane
            for chunk in range(0, hubs_max, WORLD_LANES):
                h = h_first + chunk + lane
                a = wp.vec4(0.0)
                b = wp.vec4(0.0)
                c = wp.vec4(0.0)
                if active and h < h_end:
                    tube = node_tube[h]
                    start = tube_node_start[tube]
                    first = node_offset + start
                    last = node_offset + tube_node_start[tube + 1] - 1
                    t = hub_tangent(node_q, w, node_offset + h, first, last)
                    arrays.hub_t[w, h] = t
                    if h == start:
                        r = tube_start_normal(arrays.node_rest_t[pw, h], arrays.node_rest_r[pw, h], t)
                        a = wp.vec4(r[0], r[1], r[2], 0.0)
                        c = wp.vec4(t[0], t[1], t[2], 1.0)
                    else:
                        t0 = hub_tangent(node_q, w, node_offset + h - 1, first, last)
                        a = reflection_pair_a(node_q[w, node_offset + h - 1], node_q[w, node_offset + h])
                        b = reflection_pair_b(a, t0, t)
                        c = wp.vec4(t[0], t[1], t[2], 0.0)
                step_a[thread] = a
                step_b[thread] = b
                step_c[thread] = c
                if active and lane == 0:
                    for k in range(wp.min(WORLD_LANES, h_end - h_first - chunk)):
                        a = step_a[base + k]
                        c = step_c[base + k]
                        if c[3] > 0.0:
                            r_carried = wp.vec3(a[0], a[1], a[2])
                        else:
                            r_carried = reflect_frame(r_carried, a, step_b[base + k], wp.vec3(c[0], c[1], c[2]))
                        arrays.hub_r[w, h_first + chunk + k] = r_carried
                barrier[thread] = 4  # the chunk's steps are read before the next chunk's overwrite them
        barrier[thread] = 1
        if active:
            for h in range(h_first + lane, h_end, WORLD_LANES):
                hub_guard(w, h, arrays, node_q)
        barrier[thread] = 2
        if guard:
            if active:
                for k in range(lane, ring_count, WORLD_LANES):
                    ring = k
                    if wp.static(split):
                        ring = span_ring(k, h_first, body_rings, cap_first)
                    ring_guard(w, ring, arrays, node_q)
            barrier[thread] = 3
        lows = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec3, storage="shared")
        highs = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec3, storage="shared")
        lanes = wp.min(arrays.spoke_count, SURFACE_RING_LANES)
        rings_per_pass = WORLD_LANES // lanes
        sub = lane % lanes
        group = lane // lanes
        lo = wp.vec3(1.0e30)
        hi = wp.vec3(-1.0e30)
        if active:
            for first in range(0, ring_count, rings_per_pass):
                k = first + group
                if group < rings_per_pass and k < ring_count:
                    ring = k
                    if wp.static(split):
                        ring = span_ring(k, h_first, body_rings, cap_first)
                    lo, hi = ring_vertices(w, ring, sub, lanes, arrays, node_q, lo, hi)
        # The warp's bounds by halving: in each round the lower half takes in the upper half's
        # (which writes back what it holds, so reading it while it is written is harmless).
        lows[thread] = lo
        highs[thread] = hi
        step = int(wp.static(WORLD_LANES // 2))
        while step > 0:
            if lane < step:
                lo = wp.min(lo, lows[thread + step])
                hi = wp.max(hi, highs[thread + step])
            lows[thread] = lo
            highs[thread] = hi
            step = step // 2
        if active and lane == 0:
            if wp.static(split):  # reduced over the world's spans by span_extent_kernel
                arrays.span_bounds[w, span, 0] = lo
                arrays.span_bounds[w, span, 1] = hi
            else:
                arrays.extent_out[w, 0] = lo
                arrays.extent_out[w, 1] = hi

    return surface_block_kernel


@wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
def span_extent_kernel(span_bounds: wp.array3d[wp.vec3], extent_out: wp.array2d[wp.vec3]):
    """Each world's ``[min, max]`` corner from its spans' (a thread per world; exact in any order)."""
    w = wp.tid()
    lo = span_bounds[w, 0, 0]
    hi = span_bounds[w, 0, 1]
    for s in range(1, span_bounds.shape[1]):
        lo = wp.min(lo, span_bounds[w, s, 0])
        hi = wp.max(hi, span_bounds[w, s, 1])
    extent_out[w, 0] = lo
    extent_out[w, 1] = hi
