"""When a point force's assistant line is built, kept or removed, and laying it, on the device.

The rule of section 2.2 of the seed paper as :mod:`warp_tube.sim.control` states it, for every
world and force at once, before a frame's substeps (no round trip to the host):

- :func:`assistant_line_rule`, a thread per (world ``w``, force ``a``): a zero force removes its
  line (``al_active`` 0); a built line is kept while the force's direction stays within the
  rebuild angle of the one it was built with (``dot >= cos_rebuild``); otherwise the line is
  (re)built from the current shape, offset along the force's part across the tube (its tangent:
  the central difference of the positions about the force's node), unless that part is shorter
  than ``sin_min`` (the force along the axis: no line). Sets ``lay[w, a]`` to 1 and the unit
  offset direction ``lay_dir[w, a]`` where a line is laid now.
- :func:`lay_assistant_lines`, a thread per (world, line slot): where ``lay`` is set, puts line
  point ``P_i'`` at ``P_i + r_i * lay_dir``, moving with ``P_i``, and gives its springs their rest
  lengths from these positions (unstrained). Every other slot keeps its values bit for bit.

Positions are taken and laid in float64 (float32 plus its low-order part, as the state stores
them), so that a line starts unstrained in the integrators' arithmetic.

Shapes (W worlds, F forces, N nodes a world, L line slots a world): ``force``, ``al_dir``,
``lay_dir`` (W, F) vec3d [N, unit, unit]; ``al_active``, ``lay`` (W, F) int; ``node_q``,
``node_q_lo`` (W, N) vec3 [m], ``node_qd`` (W, N) vec3 [m/s], ``node_radius`` (W, N) float64 [m];
``al_q``, ``al_q_lo`` (W, L) vec3 [m], ``al_qd`` (W, L) vec3 [m/s], the four rest lengths (W, L)
float32 [m] (``al_link_length``, ``al_chord_length``, ``al_fwd_length``, ``al_bwd_length`` of
:class:`~warp_tube.model.tube.TubeControl`); topology as :class:`~warp_tube.model.tube.TubeModel`.
"""

from __future__ import annotations

import warp as wp


@wp.func
def compensated(q: wp.array2d[wp.vec3], q_lo: wp.array2d[wp.vec3], w: int, i: int) -> wp.vec3d:
    """Position [m] of node ``i`` of world ``w`` in float64: float32 plus its low-order part."""
    return wp.vec3d(q[w, i]) + wp.vec3d(q_lo[w, i])


@wp.kernel(enable_backward=False)
def assistant_line_rule(
    force: wp.array2d[wp.vec3d],
    uses_al: wp.array[wp.int32],
    force_node: wp.array[int],
    force_tube: wp.array[int],
    tube_node_start: wp.array[int],
    node_q: wp.array2d[wp.vec3],
    node_q_lo: wp.array2d[wp.vec3],
    cos_rebuild: wp.float64,
    sin_min: wp.float64,
    al_dir: wp.array2d[wp.vec3d],
    al_active: wp.array2d[int],
    lay_dir: wp.array2d[wp.vec3d],
    lay: wp.array2d[int],
):
    w, a = wp.tid()
    lay[w, a] = 0
    if uses_al[a] == 0:
        return
    f = force[w, a]
    mag = wp.length(f)
    if mag == wp.float64(0.0):
        al_active[w, a] = 0
        return
    d = f / mag
    if al_active[w, a] != 0 and wp.dot(d, al_dir[w, a]) >= cos_rebuild:
        return
    t = force_tube[a]
    s = tube_node_start[t]
    e = tube_node_start[t + 1]
    k = force_node[a]
    tangent = compensated(node_q, node_q_lo, w, wp.min(k + 1, e - 1)) - compensated(node_q, node_q_lo, w, wp.max(k - 1, s))
    tangent = tangent / wp.max(wp.length(tangent), wp.float64(1.0e-30))
    across = d - wp.dot(d, tangent) * tangent
    al_dir[w, a] = d
    n_across = wp.length(across)
    if n_across < sin_min:
        al_active[w, a] = 0
        return
    lay_dir[w, a] = across / n_across
    lay[w, a] = 1
    al_active[w, a] = 1


@wp.kernel(enable_backward=False)
def lay_assistant_lines(
    lay: wp.array2d[int],
    lay_dir: wp.array2d[wp.vec3d],
    al_force_index: wp.array[int],
    al_start: wp.array[int],
    force_tube: wp.array[int],
    tube_node_start: wp.array[int],
    node_q: wp.array2d[wp.vec3],
    node_q_lo: wp.array2d[wp.vec3],
    node_qd: wp.array2d[wp.vec3],
    node_radius: wp.array2d[wp.float64],
    al_q: wp.array2d[wp.vec3],
    al_q_lo: wp.array2d[wp.vec3],
    al_qd: wp.array2d[wp.vec3],
    al_link_length: wp.array2d[float],
    al_chord_length: wp.array2d[float],
    al_fwd_length: wp.array2d[float],
    al_bwd_length: wp.array2d[float],
):
    w, p = wp.tid()
    a = al_force_index[p]
    if lay[w, a] == 0:
        return
    t = force_tube[a]
    s = tube_node_start[t]
    e = tube_node_start[t + 1]
    i = s + p - al_start[a]
    off = lay_dir[w, a]
    x = compensated(node_q, node_q_lo, w, i)
    xp = x + node_radius[w, i] * off
    hi = wp.vec3(xp)
    al_q[w, p] = hi
    al_q_lo[w, p] = wp.vec3(xp - wp.vec3d(hi))
    al_qd[w, p] = node_qd[w, i]
    al_link_length[w, p] = float(wp.length(xp - x))
    if i < e - 1:
        x_next = compensated(node_q, node_q_lo, w, i + 1)
        xp_next = x_next + node_radius[w, i + 1] * off
        al_chord_length[w, p] = float(wp.length(xp_next - xp))
        al_fwd_length[w, p] = float(wp.length(x_next - xp))
    if i > s:
        al_bwd_length[w, p] = float(wp.length(compensated(node_q, node_q_lo, w, i - 1) - xp))
