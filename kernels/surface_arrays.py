"""What the surface kernels read and write: the ring kinds of the ring table and
:class:`SurfaceArrays`, every array of one tube prim's surface but the hub positions.

A ring is a set of ``S`` spokes leaving one hub at the same angle ``theta`` to the hub tangent
(see :mod:`warp_tube.surface.topology` for the ring table): body rings at 90 degrees, cap rings at
smaller angles to the outward axis, and a cap's pole (one vertex, on the axis).

Batch layout: hub positions ``node_q`` [length unit] shaped (world_count, >= node_offset +
node_count) hold the hubs of all tubes of one world concatenated, this prim's from column
``node_offset`` on. Parameter arrays shaped (1 or world_count, ...) are read at row
``pw = w % rows``.
"""

import warp as wp

RING_BODY = wp.constant(0)
"""Ring kind: a ring of the tube's body (spokes at 90 degrees to the tangent)."""
RING_CAP = wp.constant(1)
"""Ring kind: a ring of a cap (spokes at a smaller angle to the outward axis)."""
RING_POLE = wp.constant(2)
"""Ring kind: a cap's pole (one vertex, on the axis)."""


@wp.struct
class SurfaceArrays:
    """The arguments of the surface kernels but the hub positions, in one struct: a recorded CPU
    launch sets each argument on every call, so two arguments cost less than ~30.

    Model (fixed for a builder's life):
        node_offset: column of ``node_q`` holding hub 0.
        spoke_count: spokes per ring, S.
        guard_reach: inner-bend guard fraction in (0, 1); 0 turns the guard off
            (:mod:`warp_tube.kernels.surface_guard`).
        tube_cell_radius: each tube's radius for the cell guard's window [length unit], shape (1 or
            world_count, tube_count): hubs less than ``CELL_WINDOW`` of it apart along the
            centerline (its prim's mean spoke length in that world).
        local_frames: 1 for the paper's local frames, 0 for rotation-minimizing ones.
        tube_node_start: first hub of each tube, (tube_count + 1,).
        node_tube: tube of each hub, (node_count,).
        node_rest_t, node_rest_r: rest unit tangents and spoke-0 normals [1], shape (1 or
            world_count, node_count) (see :mod:`warp_tube.kernels.frames`).
        hub_reach: largest spoke length of each hub [length unit], shape (1 or world_count,
            node_count).
        ring_hub, ring_kind, ring_cos, ring_sin, ring_vertex: the ring table, (ring_count,) each:
            hub, kind (:data:`RING_BODY`, :data:`RING_CAP`, :data:`RING_POLE`), cosine and sine of
            the spokes' angle to the tangent, first vertex.
        spoke_cos, spoke_sin: ``cos phi_j``, ``sin phi_j`` of each spoke, (S,).
        spoke_length: spoke lengths [length unit], shape (1 or world_count, node_count, S).
        hub_uniform: 1 where a hub and its neighbours have one spoke length all round, shape
            (1 or world_count, node_count) (see :func:`~warp_tube.kernels.surface_spokes.ring_vertices`).
        span_count, span_hub_start, span_cap_ring, span_hubs_max: the block kernel's spans of a
            world, each a warp's work: whole tubes, hubs ``span_hub_start[s] .. span_hub_start[s + 1]``
            (their body rings have the same indices) and cap rings ``span_cap_ring[s] ..
            span_cap_ring[s + 1]``, (span_count + 1,) each; the most hubs of a span. One span
            holds a world's tubes where the worlds alone fill the device.

    Scratch (per-hub data and guarded lengths, written and read within one rebuild):
        hub_t, hub_r: hub unit tangents and spoke-0 normals [1], shape (world_count, node_count).
        hub_kappa: curvature vector [1/length unit] (an end hub's is its interior neighbour's;
            zero for a tube of 2 hubs), shape (world_count, node_count).
        hub_chord: sum of the lengths of the hub's edges [length unit] (one at a tube's end),
            shape (world_count, node_count).
        hub_plane: guard planes relative to the hub, shape (world_count, node_count, 3)
            (:func:`~warp_tube.kernels.surface_guard.hub_guard`).
        hub_cell: cell range of each hub, shape (world_count, node_count); written with the guard
            on only.
        hub_free: free lengths [length unit] of the hub's body ring and of any of its rings, shape
            (world_count, node_count).
        surface_length: guarded spoke lengths [length unit], shape (world_count, vertex_count);
            written and read only for spokes longer than their ring's free length.
        span_bounds: ``[min, max]`` corner of each span's points [length unit], shape
            (world_count, span_count, 2), reduced into ``extent_out`` where a world has several spans.

    Out:
        surface_q_out: boundary points [length unit], shape (world_count, vertex_count).
        surface_n_out: unit outward normals [1], shape (world_count, vertex_count).
        extent_out: ``[min, max]`` corner of each world's points [length unit], shape
            (world_count, 2).
    """

    node_offset: int
    spoke_count: int
    guard_reach: float
    local_frames: int
    tube_node_start: wp.array[wp.int32]
    node_tube: wp.array[wp.int32]
    tube_cell_radius: wp.array2d[float]
    node_rest_t: wp.array2d[wp.vec3]
    node_rest_r: wp.array2d[wp.vec3]
    hub_reach: wp.array2d[float]
    ring_hub: wp.array[wp.int32]
    ring_kind: wp.array[wp.int32]
    ring_cos: wp.array[float]
    ring_sin: wp.array[float]
    ring_vertex: wp.array[wp.int32]
    spoke_cos: wp.array[float]
    spoke_sin: wp.array[float]
    spoke_length: wp.array3d[float]
    hub_uniform: wp.array2d[wp.int32]
    span_count: int
    span_hub_start: wp.array[wp.int32]
    span_cap_ring: wp.array[wp.int32]
    span_hubs_max: int
    # scratch:
    hub_t: wp.array2d[wp.vec3]
    hub_r: wp.array2d[wp.vec3]
    hub_kappa: wp.array2d[wp.vec3]
    hub_chord: wp.array2d[float]
    hub_plane: wp.array3d[wp.vec4]
    hub_cell: wp.array2d[wp.vec2i]
    hub_free: wp.array2d[wp.vec2]
    surface_length: wp.array2d[float]
    span_bounds: wp.array3d[wp.vec3]
    # out:
    surface_q_out: wp.array2d[wp.vec3]
    surface_n_out: wp.array2d[wp.vec3]
    extent_out: wp.array2d[wp.vec3]
