"""The assistant line of the paper (section 2.2): which springs a line point has, and their forces,
energy and stiffness blocks, for every centerline path (see :mod:`.springs`).

While a point force acts on node ``P_k``, line point ``P_i'`` (an offset copy of node ``P_i``) is
linked to ``P_i``, to the next line point by a chord, and by tractive springs to ``P_{i+1}`` on the
far side of the force point and ``P_{i-1}`` on the near side. Rest lengths [m] are set when the line
is built (``control.al_*``); stiffness ``seg_ke`` [N/m] and damping ``seg_kd`` [N s/m] are the
centerline segment's beside it.
"""

from __future__ import annotations

import warp as wp

from .springs import EPS, spring_damping_matrix, spring_dissipation, spring_energy, spring_force, spring_stiffness


#: Line springs per line point: its neighbours, in this order, are node ``P_i``, line point
#: ``P_{i+1}'``, node ``P_{i+1}`` and node ``P_{i-1}`` (see :func:`al_springs`).
AL_SPRINGS = 4

Mat43 = wp.types.matrix((4, 3), wp.Float)


@wp.func
def al_springs(i: int, k: int, start: int, end: int) -> wp.vec4i:
    """Which springs join assistant-line point ``P_i'`` of a tube with nodes ``start..end-1``,
    pushed at node ``k`` (section 2.2 of the seed paper), to its neighbours (:data:`AL_SPRINGS`),
    each spring owned by one line point:

    - the link ``P_i' - P_i``;
    - the chord ``P_i' - P_{i+1}'`` (the offset copy of structural spring ``i``);
    - the forward tractive spring ``P_i' - P_{i+1}`` for ``i >= k``;
    - the backward tractive spring ``P_i' - P_{i-1}`` for ``i <= k``.

    Per neighbour: 0, no spring; 1, a spring with the stiffness and damping of segment ``i``; 2,
    of segment ``i - 1`` (the link at a tube's last node, and the backward tractive spring). Rest
    lengths: the control's ``al_link_length``, ``al_chord_length``, ``al_fwd_length``,
    ``al_bwd_length`` of the point's slot, set when the line is built.
    """
    link = 1
    if i == end - 1:
        link = 2
    chord = 0
    fwd = 0
    if i < end - 1:
        chord = 1
        if i >= k:
            fwd = 1
    bwd = 0
    if i <= k and i > start:
        bwd = 2
    return wp.vec4i(link, chord, fwd, bwd)


@wp.func
def al_lane_diagonal(i: int, k: int, end: int) -> int:
    """Which tractive spring crosses from node ``i`` of a tube (nodes ``..end-1``) pushed at node
    ``k`` to node ``i + 1``: each such pair has exactly one (:func:`al_springs`): 1, the forward
    spring ``P_i' - P_{i+1}`` (``i >= k``); 0, the backward spring of the next point,
    ``P_{i+1}' - P_i`` (``i < k``); -1 at the tube's last node (none). Both have segment ``i``'s
    stiffness and damping. The on-chip kernel's thread at node ``i`` evaluates the link and the
    chord of line point ``P_i'`` and this spring (:func:`al_lane_forces`): three springs a
    thread, where a point's own springs are four at the force point."""
    if i >= end - 1:
        return -1
    if i >= k:
        return 1
    return 0


@wp.func
def al_lane_forces(d_link: wp.vec3, dv_link: wp.vec3, d_chord: wp.vec3, dv_chord: wp.vec3, d_diag: wp.vec3, dv_diag: wp.vec3,
                   rest_length: wp.vec3, link_ke: float, link_kd: float, ke: float, kd: float):  # fmt: skip
    """The three line springs of the on-chip thread at node ``i`` (:func:`al_lane_diagonal`), each
    given as ``d = xb - xa`` [m] and ``dv = vb - va`` [m/s] from its first end: the link from
    ``P_i'`` to ``P_i``, the chord from ``P_i'`` to ``P_{i+1}'`` and the tractive spring that
    crosses to node ``i + 1`` (forward: from ``P_i'`` to ``P_{i+1}``; backward: from ``P_i`` to
    ``P_{i+1}'``); ``rest_length`` [m] in that order, ``link_ke``, ``link_kd`` the link's
    stiffness [N/m] and damping [N s/m] (segment ``i``'s, ``i - 1``'s at a tube's last node),
    ``ke``, ``kd`` segment ``i``'s (zero at the last node: no chord, no tractive spring). Returns
    each spring's force on its first end [N] (:func:`~.springs.spring_force`); every spring is
    evaluated (no branch to split a warp; one with a zero ``d`` exerts none)."""
    return (spring_force(d_link, dv_link, rest_length[0], link_ke, link_kd),
            spring_force(d_chord, dv_chord, rest_length[1], ke, kd),
            spring_force(d_diag, dv_diag, rest_length[2], ke, kd))  # fmt: skip


@wp.func
def al_point_forces(springs: wp.vec4i, d: Mat43, dv: Mat43, rest_length: wp.vec4, ke: float, ke_prev: float, kd: float, kd_prev: float):
    """Forces of one line point's springs (:func:`al_springs`; those that are not there left out):
    ``d[s]`` and ``dv[s]`` are neighbour ``s``'s position [m] and velocity [m/s] minus the point's,
    ``ke``, ``kd`` the stiffness [N/m] and damping [N s/m] of segment ``i``, ``ke_prev``,
    ``kd_prev`` of segment ``i - 1``. Returns the force on the point [N] and, row ``s``, the force
    on neighbour ``s`` (zero where there is no spring). The per-tube and implicit kernels' form (a
    thread per tube); the on-chip kernel shares the springs among the threads of a tube
    (:func:`al_lane_forces`)."""
    r = type(d)()
    f = r[0]
    for s in range(AL_SPRINGS):
        if springs[s] != 0:
            fs = spring_force(
                d[s], dv[s], type(d[0, 0])(rest_length[s]),
                type(d[0, 0])(al_segment(springs[s], ke, ke_prev)), type(d[0, 0])(al_segment(springs[s], kd, kd_prev)),
            )  # fmt: skip
            f = f + fs
            r[s] = -fs
    return f, r


@wp.func
def al_spring_block(springs: wp.vec4i, s: int, d: Mat43, rest_length: wp.vec4, ke: float, ke_prev: float, kd: float, kd_prev: float, h: wp.Float):
    """Implicit Euler's block ``h^2 K + h C`` [kg] of a line point's spring to neighbour ``s`` (as
    :func:`al_point_forces`; :func:`spring_stiffness`, :func:`spring_damping_matrix`); zero where
    there is no spring or it has no length."""
    ds = d[s]
    blk = wp.outer(ds, ds) * type(h)(0.0)
    if springs[s] != 0 and wp.length(ds) >= type(h)(EPS):
        blk = spring_stiffness(ds, type(h)(rest_length[s]), type(h)(al_segment(springs[s], ke, ke_prev))) * (h * h)
        blk = blk + spring_damping_matrix(ds, type(h)(al_segment(springs[s], kd, kd_prev))) * h
    return blk


@wp.func
def al_point_energy(springs: wp.vec4i, d: Mat43, d0: Mat43, rest_length: wp.vec4, ke: float, ke_prev: float, kd: float, kd_prev: float, h: wp.Float):
    """Energy [J] of one line point's springs (as :func:`al_point_forces`; :func:`spring_energy`)
    plus their damping's dissipation over a step of ``h`` [s] from end differences ``d0``
    (:func:`spring_dissipation`)."""
    e = type(h)(0.0)
    for s in range(AL_SPRINGS):
        if springs[s] != 0:
            e += spring_energy(d[s], type(h)(rest_length[s]), type(h)(al_segment(springs[s], ke, ke_prev)))
            e += spring_dissipation(d[s], d0[s], type(h)(al_segment(springs[s], kd, kd_prev)), h)
    return e


@wp.func
def al_segment(code: int, this: float, prev: float) -> float:
    """The parameter of segment ``i`` (code 1) or ``i - 1`` (code 2) (:func:`al_springs`)."""
    if code == 2:
        return prev
    return this
