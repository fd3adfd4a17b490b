"""The surface rebuilt by one thread per world (Warp): the CPU's path.

One launch does the whole rebuild of a world, in this order: hub frames
(:mod:`warp_tube.kernels.frames`), per-hub guard data
(:func:`~warp_tube.kernels.surface_guard.hub_guard`), guarded lengths
(:func:`~warp_tube.kernels.surface_guard.ring_guard`, guard on only), then points, normals and
their bounds (:func:`~warp_tube.kernels.surface_spokes.ring_vertices`). Each ring's frame is read
once for its spokes. The GPU's block kernel (:mod:`warp_tube.kernels.surface_block`) runs the same
functions in the same order on a warp per world, so both give the same points and normals.
"""

import warp as wp

from .frames import hub_local_frame, tube_rotation_minimizing_frames
from .options import CUDA_OPTIONS
from .surface_arrays import SurfaceArrays
from .surface_guard import hub_guard, ring_guard
from .surface_spokes import ring_vertices


@wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
def surface_world_kernel(arrays: SurfaceArrays, node_q: wp.array2d[wp.vec3]):
    """Rebuild one world's surface: frames, per-hub data, guarded lengths, points and normals, and
    their bounds; one thread per world.

    Args:
        arrays: the surface's arrays (:class:`~warp_tube.kernels.surface_arrays.SurfaceArrays`);
            writes ``surface_q_out``, ``surface_n_out`` and ``extent_out`` (``[min, max]`` corner
            of the world's points) and the scratch arrays.
        node_q: hub positions [length unit], shape (world_count, >= node_offset + node_count).
    """
    node_offset = arrays.node_offset
    tube_node_start = arrays.tube_node_start
    node_tube = arrays.node_tube
    w = wp.tid()
    hub_count = node_tube.shape[0]
    if arrays.local_frames != 0:
        for h in range(hub_count):
            hub_local_frame(
                w, h, node_offset, tube_node_start, node_tube, arrays.node_rest_t, arrays.node_rest_r, node_q,
                arrays.hub_t, arrays.hub_r,
            )  # fmt: skip
    else:
        for tube in range(tube_node_start.shape[0] - 1):
            tube_rotation_minimizing_frames(
                w, tube, node_offset, tube_node_start, arrays.node_rest_t, arrays.node_rest_r, node_q, arrays.hub_t,
                arrays.hub_r,
            )  # fmt: skip
    for h in range(hub_count):
        hub_guard(w, h, arrays, node_q)
    ring_count = arrays.ring_hub.shape[0]
    if arrays.guard_reach > 0.0:
        for ring in range(ring_count):
            ring_guard(w, ring, arrays, node_q)
    lo = wp.vec3(1.0e30)
    hi = wp.vec3(-1.0e30)
    for ring in range(ring_count):
        lo, hi = ring_vertices(w, ring, 0, 1, arrays, node_q, lo, hi)
    arrays.extent_out[w, 0] = lo
    arrays.extent_out[w, 1] = hi
