"""Semi-implicit Euler integration of the centerline, specialised to a scene's features.

:func:`make_kernels` builds, for one combination of :class:`~.springs.Features`, the per-tube
kernel ``substeps``: one thread per (world, tube) runs a whole frame's substeps in a loop, with no
round trip to Python between them (the CPU path: a launch costs ~15 us there, a substep of a
20-point tube well under that; on CUDA, the path of tubes longer than the on-chip kernel's block).
Each spring and stencil of :mod:`.springs` is evaluated once and added to all its nodes; the
curved frames are carried along the tube in order (:func:`~.bending.curvature_targets`,
:func:`~.bending.frame_forces`).

Features a scene does not use are compiled out with ``wp.static``: a straight tube with no anchors,
gravity, damping or assistant line evaluates only its structural and bending springs.

Update per substep (mass-proportional damping ``alpha`` taken implicitly, so it never limits the
time step)::

    v' = (v + dt * f / m) / (1 + alpha * dt)        x' = x + dt * v'   (compensated sum)

Pinned nodes (inverse mass 0) follow their targets, interpolated linearly over the frame from
``pin_q_start`` to ``pin_q_end``; their velocity is the target's.
"""

from __future__ import annotations

import functools

import warp as wp

from .assistant_line import al_point_forces, al_springs
from .bending import (
    bend_gradients,
    curvature_targets,
    frame_forces,
)
from .springs import (
    ControlArrays,
    Features,
    ModelArrays,
    StateArrays,
    frame_left,
    make_node_terms,
    node_delta,
    pack,
    pin_step,
    spring_force,
)

__all__ = ["ControlArrays", "Features", "ModelArrays", "ScratchArrays", "StateArrays", "make_kernels", "pack"]


@wp.struct
class ScratchArrays:
    """Per-substep scratch of the per-tube kernel: forces [N] and curvature targets."""

    node_f: wp.array2d[wp.vec3]
    al_f: wp.array2d[wp.vec3]
    node_kappa_target: wp.array2d[wp.vec3]


@wp.func
def al_point(model: ModelArrays, control: ControlArrays, s: StateArrays, w: int, pw: int, a: int, i: int, start: int, end: int):
    """The springs of line point ``P_i'`` of force ``a`` (:func:`~.springs.al_springs`): the force
    on it [N] and, row by row, on its neighbours (node ``i``, line point ``i + 1``, node ``i + 1``,
    node ``i - 1``; :func:`~.springs.al_point_forces`). Positions are compensated."""
    p = model.al_start[a] + (i - start)
    ip = wp.min(i + 1, end - 1)
    im = wp.max(i - 1, start)
    q = p + (ip - i)
    x = s.al_q[w, p]
    lo = s.al_q_lo[w, p]
    v = s.al_qd[w, p]
    d = wp.matrix_from_rows(
        (s.node_q[w, i] - x) + (s.node_q_lo[w, i] - lo),
        (s.al_q[w, q] - x) + (s.al_q_lo[w, q] - lo),
        (s.node_q[w, ip] - x) + (s.node_q_lo[w, ip] - lo),
        (s.node_q[w, im] - x) + (s.node_q_lo[w, im] - lo),
    )
    dv = wp.matrix_from_rows(s.node_qd[w, i] - v, s.al_qd[w, q] - v, s.node_qd[w, ip] - v, s.node_qd[w, im] - v)
    rest = wp.vec4(control.al_link_length[w, p], control.al_chord_length[w, p], control.al_fwd_length[w, p], control.al_bwd_length[w, p])
    return al_point_forces(
        al_springs(i, model.force_node[a], start, end), d, dv, rest,
        model.seg_ke[pw, i], model.seg_ke[pw, im], model.seg_kd[pw, i], model.seg_kd[pw, im],
    )  # fmt: skip


@functools.cache
def make_kernels(features: Features):
    """Kernels specialised to ``features``; cached, so each combination compiles once."""
    features = Features(*(bool(v) for v in features))
    BENDING = features.bending
    CURVED = features.curved
    SPRING_DAMPING = features.spring_damping
    AL = features.assistant_line
    load_node, node_force, _, _, _, advance = make_node_terms(features)

    @wp.kernel(enable_backward=False, module="unique")
    def substeps(
        substep_count: int,
        dt: float,
        model: ModelArrays,
        state_in: StateArrays,
        control: ControlArrays,
        scratch: ScratchArrays,
        state_out: StateArrays,
    ):
        """Advance one tube of one world by ``substep_count`` substeps of ``dt`` [s].

        Arguments are grouped in structs (fields as in :class:`ModelArrays` etc.) so that a
        recorded launch sets a handful of values instead of ~40.
        """
        node_inv_mass = model.node_inv_mass
        node_mass = model.node_mass
        node_damping = model.node_damping
        seg_ke = model.seg_ke
        seg_kd = model.seg_kd
        node_bend_k = model.node_bend_k
        node_q = state_out.node_q
        node_q_lo = state_out.node_q_lo
        node_qd = state_out.node_qd
        node_f = scratch.node_f
        al_f = scratch.al_f
        node_kappa_target = scratch.node_kappa_target
        w, t = wp.tid()
        pw = w % node_mass.shape[0]
        kt = w
        if node_kappa_target.shape[0] == 1:  # one row of targets serves every world
            kt = 0
        start = model.tube_node_start[t]
        end = model.tube_node_start[t + 1]
        for i in range(start, end):
            node_q[w, i] = state_in.node_q[w, i]
            node_q_lo[w, i] = state_in.node_q_lo[w, i]
            node_qd[w, i] = state_in.node_qd[w, i]
        if wp.static(AL):
            # Only built lines have slots in use (a force without one has none; an inactive line
            # is rebuilt from the centerline when it starts).
            for a in range(model.tube_force_start[t], model.tube_force_start[t + 1]):
                if control.al_active[w, a] != 0:
                    for p in range(model.al_start[a], model.al_start[a] + end - start):
                        state_out.al_q[w, p] = state_in.al_q[w, p]
                        state_out.al_q_lo[w, p] = state_in.al_q_lo[w, p]
                        state_out.al_qd[w, p] = state_in.al_qd[w, p]
        inv_count = 1.0 / float(substep_count)
        inv_dt = 1.0 / dt
        for step in range(substep_count):
            left = frame_left(step, substep_count, inv_count)
            if wp.static(CURVED):
                curvature_targets(w, pw, start, end, node_q, node_q_lo, model.node_rest_q, model.node_kappa_rest, model.node_bend_k,
                                  model.node_inv_mass, node_kappa_target)
            for i in range(start, end):
                node_f[w, i] = node_force(load_node(model, control, w, pw, i), node_q[w, i], node_qd[w, i])
            # Each spring and bending stencil once, added to all its nodes (one thread owns the
            # tube); one pass over the edges, the stencil at node i taking edges i - 1 and i.
            e_prev = wp.vec3(0.0)
            for i in range(start, end - 1):
                e = node_delta(node_q, node_q_lo, w, i, i + 1)
                kd = float(0.0)
                if wp.static(SPRING_DAMPING):
                    kd = seg_kd[pw, i]
                fs = spring_force(e, node_qd[w, i + 1] - node_qd[w, i], model.seg_rest_length[pw, i], seg_ke[pw, i], kd)
                node_f[w, i] = node_f[w, i] + fs
                node_f[w, i + 1] = node_f[w, i + 1] - fs
                if wp.static(BENDING):
                    if i > start:
                        kb = node_bend_k[pw, i]
                        if kb != 0.0:
                            ga, gb, kappa = bend_gradients(e_prev, e, node_kappa_target[kt, i], kb)
                            node_f[w, i - 1] = node_f[w, i - 1] + ga
                            node_f[w, i] = node_f[w, i] + gb - ga
                            node_f[w, i + 1] = node_f[w, i + 1] - gb
                e_prev = e
            if wp.static(CURVED):
                frame_forces(w, pw, start, end, node_q, node_q_lo, model.node_rest_q, node_bend_k, node_kappa_target, node_f)
            if wp.static(AL):
                # Each line spring once, owned by a line point (springs.al_springs).
                for a in range(model.tube_force_start[t], model.tube_force_start[t + 1]):
                    if control.al_active[w, a] != 0:
                        p0 = model.al_start[a]
                        for p in range(p0, p0 + end - start):
                            al_f[w, p] = wp.vec3(0.0)
                        for i in range(start, end):
                            p = p0 + (i - start)
                            f, r = al_point(model, control, state_out, w, pw, a, i, start, end)
                            al_f[w, p] = al_f[w, p] + f
                            node_f[w, i] = node_f[w, i] + r[0]
                            if i < end - 1:
                                al_f[w, p + 1] = al_f[w, p + 1] + r[1]
                                node_f[w, i + 1] = node_f[w, i + 1] + r[2]
                            if i > start:
                                node_f[w, i - 1] = node_f[w, i - 1] + r[3]
            for i in range(start, end):
                im = node_inv_mass[pw, i]
                if im == 0.0:
                    x_new, v_new = pin_step(control.pin_q_start[w, i], control.pin_q_end[w, i], left, node_q[w, i], inv_dt)
                    node_qd[w, i] = v_new
                    node_q[w, i] = x_new
                    node_q_lo[w, i] = wp.vec3(0.0)
                else:
                    x_new, lo_new, v_new = advance(node_q[w, i], node_q_lo[w, i], node_qd[w, i], node_f[w, i], im, node_damping[pw, i], dt)
                    node_q[w, i] = x_new
                    node_q_lo[w, i] = lo_new
                    node_qd[w, i] = v_new
            if wp.static(AL):
                for a in range(model.tube_force_start[t], model.tube_force_start[t + 1]):
                    if control.al_active[w, a] != 0:
                        for i in range(start, end):
                            p = model.al_start[a] + (i - start)
                            x_new, lo_new, v_new = advance(
                                state_out.al_q[w, p], state_out.al_q_lo[w, p], state_out.al_qd[w, p], al_f[w, p],
                                1.0 / node_mass[pw, i], node_damping[pw, i], dt,
                            )  # fmt: skip
                            state_out.al_q[w, p] = x_new
                            state_out.al_q_lo[w, p] = lo_new
                            state_out.al_qd[w, p] = v_new

    return substeps
