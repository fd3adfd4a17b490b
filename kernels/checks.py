"""Frame checks on the device: per (world, group) sums that tell the host whether a frame failed.

A *group* is a set of tubes that fail together: every tube of a scene run alone is one group; a
batch gives each variant its own group, so one variant blowing up does not stop the others.

:func:`frame_sums_kernel` runs a thread per (world, node) at the end of a frame and accumulates,
per (world, group), into ``sums[w, g]`` (one array, so the host zeroes and copies it back once):

- ``[0]`` bad: the number of nodes whose position is not finite or lies farther than ``limit`` [m]
  from its rest position (a runaway);
- ``[1]`` kinetic: the kinetic energy of the free nodes, ``sum m |v|^2 / 2`` [J];
- ``[2]`` work: the work of the point forces and gravity over the frame,
  ``sum (f_ext + m_free g) . (x_after - x_before)`` [J] (forces are held over a frame, so this is
  exact for them);
- ``[3]`` far: the largest distance of a finite node from its rest position [m];
- ``[4]`` strain: the largest factor by which a segment's length departs from its rest length,
  stretched or compressed (``max(l / l0, l0 / l)``, segments between finite nodes; 0 where the
  group has none).

Shapes: positions and velocities (world, node) vec3 [m, m/s]; ``rest_q`` (rows, node) vec3 [m] and
``node_free_mass`` (rows, node) [kg] (0 for pinned nodes), world ``w`` reading row ``w % rows``
(one row shared by every world, or one per world); ``seg_rest_length`` (rows, node) [m] the rest
length of the segment from each node to the next (0 at a tube's last node), read the same way;
``node_group`` (node,) int; ``sums`` (world, group, :data:`SUMS`) float, zeroed by the host
before the launch.
"""

from __future__ import annotations

import warp as wp

#: numbers per (world, group) in ``sums``
SUMS = 5


@wp.kernel(enable_backward=False)
def frame_sums_kernel(
    q_before: wp.array2d[wp.vec3],
    q_after: wp.array2d[wp.vec3],
    qd_after: wp.array2d[wp.vec3],
    f_ext: wp.array2d[wp.vec3],
    rest_q: wp.array2d[wp.vec3],
    seg_rest_length: wp.array2d[float],
    node_group: wp.array[int],
    node_free_mass: wp.array2d[float],
    gravity: wp.vec3,
    limit: float,
    sums: wp.array3d[float],
):
    w, n = wp.tid()
    g = node_group[n]
    row = w % rest_q.shape[0]
    x = q_after[w, n]
    v = qd_after[w, n]
    d = x - rest_q[row, n]
    far = wp.dot(d, d)
    # A NaN fails every comparison: count what is not provably finite and near.
    finite = far < limit * limit and wp.dot(v, v) < 1.0e30
    if not finite:
        wp.atomic_add(sums, w, g, 0, 1.0)
        return
    wp.atomic_max(sums, w, g, 3, wp.sqrt(far))
    l0 = seg_rest_length[w % seg_rest_length.shape[0], n]
    if l0 > 0.0:
        r = wp.length(q_after[w, n + 1] - x) / l0
        if r >= 0.0 and r < 1.0e30:  # (not a NaN or an infinity: the next node's own test fails the frame)
            wp.atomic_max(sums, w, g, 4, wp.max(r, 1.0 / wp.max(r, 1.0e-30)))
    m = node_free_mass[row, n]
    f = f_ext[w, n] + m * gravity
    wp.atomic_add(sums, w, g, 1, 0.5 * m * wp.dot(v, v))
    wp.atomic_add(sums, w, g, 2, wp.dot(f, x - q_before[w, n]))
