"""Semi-implicit Euler integration of the centerline, specialised to a scene's features.

:func:`make_kernels` builds, for one combination of :class:`~.springs.Features`, kernels that
sum the force terms of :mod:`.springs`:

- ``substeps``: one thread per (world, tube) runs a whole frame's substeps in a loop, with no
  round trip to Python between them (the CPU path: a launch costs ~15 us there, a substep of a
  20-point tube well under that). Each spring and stencil is evaluated once and added to all
  its nodes.
- ``step_nodes`` (+ ``step_al``, ``targets``): one thread per (world, node) advances one substep
  from ``*_in`` to ``*_out``, gathering the terms around its node.

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

from .springs import (
    ControlArrays,
    Features,
    ModelArrays,
    StateArrays,
    al_point_forces,
    al_springs,
    bend_gradients,
    curvature_targets,
    frame_forces,
    make_node_terms,
    node_delta,
    pack,
    spring_force,
)

__all__ = ["ControlArrays", "Features", "ModelArrays", "ScratchArrays", "StateArrays", "make_kernels", "pack"]


@wp.struct
class ScratchArrays:
    """Per-substep scratch of the per-tube kernel: forces [N] and curvature targets."""

    node_f: wp.array2d[wp.vec3]
    al_f: wp.array2d[wp.vec3]
    node_kappa_target: wp.array2d[wp.vec3]


#: Options of the per-node (CUDA path) kernels' modules: fast approximate division and square root.
CUDA_OPTIONS = {"fast_math": True}


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
        for step in range(substep_count):
            frac = float(step + 1) / float(substep_count)
            if wp.static(CURVED):
                curvature_targets(w, pw, start, end, node_q, model.node_rest_q, model.node_kappa_rest, node_kappa_target)
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
                    x_new = wp.lerp(control.pin_q_start[w, i], control.pin_q_end[w, i], frac)
                    node_qd[w, i] = (x_new - node_q[w, i]) / dt
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

    @wp.kernel(enable_backward=False, module="unique")
    def targets(
        model: ModelArrays,
        state_in: StateArrays,
        # out:
        node_kappa_target: wp.array2d[wp.vec3],
        node_f_frame: wp.array2d[wp.vec3],
    ):
        """Curvature targets of curved rest shapes and the forces of their dependence on the
        shape [N], one thread per (world, tube)."""
        w, t = wp.tid()
        pw = w % model.node_rest_q.shape[0]
        start = model.tube_node_start[t]
        end = model.tube_node_start[t + 1]
        curvature_targets(w, pw, start, end, state_in.node_q, model.node_rest_q, model.node_kappa_rest, node_kappa_target)
        for i in range(start, end):
            node_f_frame[w, i] = wp.vec3(0.0)
        frame_forces(w, pw, start, end, state_in.node_q, state_in.node_q_lo, model.node_rest_q, model.node_bend_k, node_kappa_target, node_f_frame)

    @wp.func
    def al_node_force(model: ModelArrays, control: ControlArrays, s: StateArrays, w: int, pw: int, t: int, i: int, start: int, end: int) -> wp.vec3:
        """Force [N] on node ``i`` from the line springs that end on it (owned by line points
        ``i``, ``i - 1`` forward, ``i + 1`` backward)."""
        f = wp.vec3(0.0)
        for a in range(model.tube_force_start[t], model.tube_force_start[t + 1]):
            if control.al_active[w, a] != 0:
                fp, r = al_point(model, control, s, w, pw, a, i, start, end)
                f += r[0]
                if i > start:
                    fp, r = al_point(model, control, s, w, pw, a, i - 1, start, end)
                    f += r[2]
                if i < end - 1:
                    fp, r = al_point(model, control, s, w, pw, a, i + 1, start, end)
                    f += r[3]
        return f

    @wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
    def step_nodes(
        frac: float,
        dt: float,
        node_tube: wp.array[int],
        model: ModelArrays,
        state_in: StateArrays,
        control: ControlArrays,
        node_kappa_target: wp.array2d[wp.vec3],
        node_f_frame: wp.array2d[wp.vec3],
        # out:
        node_q_out: wp.array2d[wp.vec3],
        node_q_lo_out: wp.array2d[wp.vec3],
        node_qd_out: wp.array2d[wp.vec3],
    ):
        """One substep of ``dt`` [s] for one node; ``frac`` is the pin targets' progress."""
        w, i = wp.tid()
        pw = w % model.node_mass.shape[0]
        im = model.node_inv_mass[pw, i]
        node_q_in = state_in.node_q
        node_q_lo_in = state_in.node_q_lo
        node_qd_in = state_in.node_qd
        if im == 0.0:
            x_new = wp.lerp(control.pin_q_start[w, i], control.pin_q_end[w, i], frac)
            node_qd_out[w, i] = (x_new - node_q_in[w, i]) / dt
            node_q_out[w, i] = x_new
            node_q_lo_out[w, i] = wp.vec3(0.0)
            return
        t = node_tube[i]
        start = model.tube_node_start[t]
        end = model.tube_node_start[t + 1]
        # Each node evaluates its two springs and three bending stencils itself, from the four
        # edges around it, each formed once from the compensated positions.
        v = node_qd_in[w, i]
        f = wp.vec3(0.0)
        zero = wp.vec3(0.0)
        em2 = zero
        em1 = zero
        e0 = zero
        ep1 = zero
        if i - 1 >= start:
            em1 = node_delta(node_q_in, node_q_lo_in, w, i - 1, i)
            kd = float(0.0)
            if wp.static(SPRING_DAMPING):
                kd = model.seg_kd[pw, i - 1]
            f += spring_force(-em1, node_qd_in[w, i - 1] - v, model.seg_rest_length[pw, i - 1], model.seg_ke[pw, i - 1], kd)
        if i + 1 < end:
            e0 = node_delta(node_q_in, node_q_lo_in, w, i, i + 1)
            kd = float(0.0)
            if wp.static(SPRING_DAMPING):
                kd = model.seg_kd[pw, i]
            f += spring_force(e0, node_qd_in[w, i + 1] - v, model.seg_rest_length[pw, i], model.seg_ke[pw, i], kd)
        if wp.static(BENDING):
            kt = w % node_kappa_target.shape[0]
            if i + 1 < end - 1:
                ep1 = node_delta(node_q_in, node_q_lo_in, w, i + 1, i + 2)
                k = model.node_bend_k[pw, i + 1]
                if k != 0.0:
                    ga, gb, kb = bend_gradients(e0, ep1, node_kappa_target[kt, i + 1], k)
                    f += ga
            if i > start and i < end - 1:
                k = model.node_bend_k[pw, i]
                if k != 0.0:
                    ga, gb, kb = bend_gradients(em1, e0, node_kappa_target[kt, i], k)
                    f += gb - ga
            if i - 1 > start:
                em2 = node_delta(node_q_in, node_q_lo_in, w, i - 2, i - 1)
                k = model.node_bend_k[pw, i - 1]
                if k != 0.0:
                    ga, gb, kb = bend_gradients(em2, em1, node_kappa_target[kt, i - 1], k)
                    f -= gb
        if wp.static(CURVED):
            f += node_f_frame[w, i]
        f += node_force(load_node(model, control, w, pw, i), node_q_in[w, i], v)
        if wp.static(AL):
            f += al_node_force(model, control, state_in, w, pw, t, i, start, end)
        x_new, lo_new, v_new = advance(node_q_in[w, i], node_q_lo_in[w, i], v, f, im, model.node_damping[pw, i], dt)
        node_q_out[w, i] = x_new
        node_q_lo_out[w, i] = lo_new
        node_qd_out[w, i] = v_new

    @wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
    def step_al(
        dt: float,
        force_tube: wp.array[int],
        al_force_index: wp.array[int],
        model: ModelArrays,
        state_in: StateArrays,
        control: ControlArrays,
        # out:
        al_q_out: wp.array2d[wp.vec3],
        al_q_lo_out: wp.array2d[wp.vec3],
        al_qd_out: wp.array2d[wp.vec3],
    ):
        """One substep for one assistant-line point (thread per (world, AL slot)): its own springs
        and the chord owned by the point before it."""
        w, p = wp.tid()
        a = al_force_index[p]
        if control.al_active[w, a] == 0:
            return
        pw = w % model.node_mass.shape[0]
        t = force_tube[a]
        start = model.tube_node_start[t]
        end = model.tube_node_start[t + 1]
        i = start + (p - model.al_start[a])
        f, r = al_point(model, control, state_in, w, pw, a, i, start, end)
        if i > start:
            fp, r = al_point(model, control, state_in, w, pw, a, i - 1, start, end)
            f += r[1]
        x_new, lo_new, v_new = advance(state_in.al_q[w, p], state_in.al_q_lo[w, p], state_in.al_qd[w, p], f, 1.0 / model.node_mass[pw, i], model.node_damping[pw, i], dt)
        al_q_out[w, p] = x_new
        al_q_lo_out[w, p] = lo_new
        al_qd_out[w, p] = v_new

    return substeps, targets, step_nodes, step_al
