"""Semi-implicit Euler integration of the centerline, specialised to a scene's features.

:func:`make_kernels` builds, for one combination of :class:`Features`, two kernels that share the
same force functions:

- ``substeps``: one thread per (world, tube) runs a whole frame's substeps in a loop, with no
  round trip to Python between them (the CPU path: a launch costs ~15 us there, a substep of a
  20-point tube well under that).
- ``step_nodes`` (+ ``step_al``, ``targets``): one thread per (world, node) advances one substep
  from ``*_in`` to ``*_out`` (the GPU path; the host captures a frame's substeps in a graph).

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
from typing import NamedTuple

import warp as wp

from .options import CUDA_OPTIONS
from .springs import al_delta, bend_gradients, curvature_targets, frame_forces, node_delta, spring_force


@wp.struct
class ModelArrays:
    """The TubeModel arrays the per-tube kernel reads (units and shapes as in TubeModel)."""

    tube_node_start: wp.array[int]
    node_rest_q: wp.array2d[wp.vec3]
    node_mass: wp.array2d[float]
    node_inv_mass: wp.array2d[float]
    node_damping: wp.array2d[float]
    seg_rest_length: wp.array2d[float]
    seg_ke: wp.array2d[float]
    seg_kd: wp.array2d[float]
    node_bend_k: wp.array2d[float]
    node_kappa_rest: wp.array2d[wp.vec3]
    node_anchor_k: wp.array2d[float]
    node_anchor_kd: wp.array2d[float]
    gravity: wp.vec3
    tube_force_start: wp.array[int]
    force_node: wp.array[int]
    al_start: wp.array[int]


@wp.struct
class StateArrays:
    """A TubeState's arrays."""

    node_q: wp.array2d[wp.vec3]
    node_q_lo: wp.array2d[wp.vec3]
    node_qd: wp.array2d[wp.vec3]
    al_q: wp.array2d[wp.vec3]
    al_q_lo: wp.array2d[wp.vec3]
    al_qd: wp.array2d[wp.vec3]


@wp.struct
class ControlArrays:
    """A TubeControl's arrays."""

    node_f_ext: wp.array2d[wp.vec3]
    pin_q_start: wp.array2d[wp.vec3]
    pin_q_end: wp.array2d[wp.vec3]
    al_active: wp.array2d[int]
    al_link_length: wp.array2d[float]
    al_chord_length: wp.array2d[float]
    al_fwd_length: wp.array2d[float]
    al_bwd_length: wp.array2d[float]


@wp.struct
class ScratchArrays:
    """Per-substep scratch of the per-tube kernel: forces [N] and curvature targets."""

    node_f: wp.array2d[wp.vec3]
    al_f: wp.array2d[wp.vec3]
    node_kappa_target: wp.array2d[wp.vec3]


def pack(struct_type, source):
    """Fill a new ``struct_type`` from the same-named attributes of ``source``."""
    out = struct_type()
    for name in struct_type.vars:
        setattr(out, name, getattr(source, name))
    return out


class Features(NamedTuple):
    """Which terms a scene uses; each False term is compiled out."""

    bending: bool = True
    curved: bool = False
    anchors: bool = False
    gravity: bool = False
    mass_damping: bool = False
    spring_damping: bool = False
    external: bool = False
    assistant_line: bool = False


@functools.cache
def make_kernels(features: Features):
    """Kernels specialised to ``features``; cached, so each combination compiles once."""
    features = Features(*(bool(v) for v in features))
    BENDING = features.bending
    CURVED = features.curved
    ANCHORS = features.anchors
    GRAVITY = features.gravity
    MASS_DAMPING = features.mass_damping
    SPRING_DAMPING = features.spring_damping
    EXTERNAL = features.external
    AL = features.assistant_line

    @wp.func
    def node_force(
        w: int,
        pw: int,
        i: int,
        start: int,
        end: int,
        t: int,
        # model:
        node_rest_q: wp.array2d[wp.vec3],
        node_mass: wp.array2d[float],
        seg_rest_length: wp.array2d[float],
        seg_ke: wp.array2d[float],
        seg_kd: wp.array2d[float],
        node_bend_k: wp.array2d[float],
        node_anchor_k: wp.array2d[float],
        node_anchor_kd: wp.array2d[float],
        gravity: wp.vec3,
        tube_force_start: wp.array[int],
        force_node: wp.array[int],
        al_start: wp.array[int],
        # state in:
        node_q: wp.array2d[wp.vec3],
        node_q_lo: wp.array2d[wp.vec3],
        node_qd: wp.array2d[wp.vec3],
        node_kappa_target: wp.array2d[wp.vec3],
        al_q: wp.array2d[wp.vec3],
        al_q_lo: wp.array2d[wp.vec3],
        al_qd: wp.array2d[wp.vec3],
        # control:
        node_f_ext: wp.array2d[wp.vec3],
        al_active: wp.array2d[int],
        al_link_length: wp.array2d[float],
        al_fwd_length: wp.array2d[float],
        al_bwd_length: wp.array2d[float],
    ) -> wp.vec3:
        """Force on node ``i`` of world ``w`` [N] from everything but the structural and bending
        springs (both kernels add those stencil by stencil, each evaluated once)."""
        x = node_q[w, i]
        v = node_qd[w, i]
        f = wp.vec3(0.0)
        if wp.static(ANCHORS):
            ka = node_anchor_k[pw, i]
            if ka > 0.0:
                f -= (x - node_rest_q[pw, i]) * ka + v * node_anchor_kd[pw, i]
        if wp.static(GRAVITY):
            f += gravity * node_mass[pw, i]
        if wp.static(EXTERNAL):
            f += node_f_ext[w, i]
        if wp.static(AL):
            # Links P_i - P_i' and the tractive springs that end on P_i (see step_al).
            for a in range(tube_force_start[t], tube_force_start[t + 1]):
                if al_active[w, a] != 0:
                    p = al_start[a] + (i - start)
                    k = force_node[a]
                    s = wp.min(i, end - 2)
                    kd = float(0.0)
                    if wp.static(SPRING_DAMPING):
                        kd = seg_kd[pw, s]
                    f += spring_force(al_delta(al_q, al_q_lo, w, p, node_q, node_q_lo, i), al_qd[w, p] - v, al_link_length[w, p], seg_ke[pw, s], kd)
                    if i > k:
                        f += spring_force(al_delta(al_q, al_q_lo, w, p - 1, node_q, node_q_lo, i), al_qd[w, p - 1] - v, al_fwd_length[w, p - 1], seg_ke[pw, i - 1], kd)
                    if i < k:
                        f += spring_force(al_delta(al_q, al_q_lo, w, p + 1, node_q, node_q_lo, i), al_qd[w, p + 1] - v, al_bwd_length[w, p + 1], seg_ke[pw, i], kd)
        return f

    @wp.func
    def al_force(
        w: int,
        pw: int,
        a: int,
        p: int,
        i: int,
        start: int,
        end: int,
        # model:
        seg_ke: wp.array2d[float],
        seg_kd: wp.array2d[float],
        force_node: wp.array[int],
        # state in:
        node_q: wp.array2d[wp.vec3],
        node_q_lo: wp.array2d[wp.vec3],
        node_qd: wp.array2d[wp.vec3],
        al_q: wp.array2d[wp.vec3],
        al_q_lo: wp.array2d[wp.vec3],
        al_qd: wp.array2d[wp.vec3],
        # control:
        al_link_length: wp.array2d[float],
        al_chord_length: wp.array2d[float],
        al_fwd_length: wp.array2d[float],
        al_bwd_length: wp.array2d[float],
    ) -> wp.vec3:
        """Force on assistant-line point P_i' (AL slot ``p`` of force ``a``) [N].

        P_i' is linked to P_i, to its neighbours P_{i-1}', P_{i+1}' (the offset copy of the
        centerline's structural springs), and by a tractive spring to P_{i+1} when i >= k and to
        P_{i-1} when i <= k, k being the force's point (section 2.2 of the seed paper). Each spring
        has the axial stiffness of the centerline segment beside it.
        """
        x = al_q[w, p]
        v = al_qd[w, p]
        k = force_node[a]
        s = wp.min(i, end - 2)
        kd_link = float(0.0)
        if wp.static(SPRING_DAMPING):
            kd_link = seg_kd[pw, s]
        f = spring_force(-al_delta(al_q, al_q_lo, w, p, node_q, node_q_lo, i), node_qd[w, i] - v, al_link_length[w, p], seg_ke[pw, s], kd_link)
        if i > start:
            kd = float(0.0)
            if wp.static(SPRING_DAMPING):
                kd = seg_kd[pw, i - 1]
            f += spring_force((al_q[w, p - 1] - x) + (al_q_lo[w, p - 1] - al_q_lo[w, p]), al_qd[w, p - 1] - v, al_chord_length[w, p - 1], seg_ke[pw, i - 1], kd)
            if i <= k:
                f += spring_force(-al_delta(al_q, al_q_lo, w, p, node_q, node_q_lo, i - 1), node_qd[w, i - 1] - v, al_bwd_length[w, p], seg_ke[pw, i - 1], kd)
        if i < end - 1:
            kd = float(0.0)
            if wp.static(SPRING_DAMPING):
                kd = seg_kd[pw, i]
            f += spring_force((al_q[w, p + 1] - x) + (al_q_lo[w, p + 1] - al_q_lo[w, p]), al_qd[w, p + 1] - v, al_chord_length[w, p], seg_ke[pw, i], kd)
            if i >= k:
                f += spring_force(-al_delta(al_q, al_q_lo, w, p, node_q, node_q_lo, i + 1), node_qd[w, i + 1] - v, al_fwd_length[w, p], seg_ke[pw, i], kd)
        return f

    @wp.func
    def advance(x: wp.vec3, lo: wp.vec3, v: wp.vec3, f: wp.vec3, inv_mass: float, alpha: float, dt: float):
        """Semi-implicit Euler with implicit mass-proportional damping; returns (x', lo', v').

        The position sum is compensated (Kahan): ``lo`` carries the low-order bits that adding a
        small ``v dt`` to a float32 position drops. Without it the dropped bits act as white noise
        that heats the stiff axial modes of a long undamped run.
        """
        v_new = v + f * (inv_mass * dt)
        if wp.static(MASS_DAMPING):
            v_new = v_new / (1.0 + alpha * dt)
        y = v_new * dt + lo
        x_new = x + y
        return x_new, y - (x_new - x), v_new

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
        tube_node_start = model.tube_node_start
        node_rest_q = model.node_rest_q
        node_mass = model.node_mass
        node_inv_mass = model.node_inv_mass
        node_damping = model.node_damping
        seg_rest_length = model.seg_rest_length
        seg_ke = model.seg_ke
        seg_kd = model.seg_kd
        node_bend_k = model.node_bend_k
        node_kappa_rest = model.node_kappa_rest
        node_anchor_k = model.node_anchor_k
        node_anchor_kd = model.node_anchor_kd
        gravity = model.gravity
        tube_force_start = model.tube_force_start
        force_node = model.force_node
        al_start = model.al_start
        node_q_in = state_in.node_q
        node_q_lo_in = state_in.node_q_lo
        node_qd_in = state_in.node_qd
        al_q_in = state_in.al_q
        al_q_lo_in = state_in.al_q_lo
        al_qd_in = state_in.al_qd
        node_f_ext = control.node_f_ext
        pin_q_start = control.pin_q_start
        pin_q_end = control.pin_q_end
        al_active = control.al_active
        al_link_length = control.al_link_length
        al_chord_length = control.al_chord_length
        al_fwd_length = control.al_fwd_length
        al_bwd_length = control.al_bwd_length
        node_f = scratch.node_f
        al_f = scratch.al_f
        node_kappa_target = scratch.node_kappa_target
        node_q_out = state_out.node_q
        node_q_lo_out = state_out.node_q_lo
        node_qd_out = state_out.node_qd
        al_q_out = state_out.al_q
        al_q_lo_out = state_out.al_q_lo
        al_qd_out = state_out.al_qd
        w, t = wp.tid()
        pw = w % node_mass.shape[0]
        kt = w
        if node_kappa_target.shape[0] == 1:  # one row of targets serves every world
            kt = 0
        start = tube_node_start[t]
        end = tube_node_start[t + 1]
        for i in range(start, end):
            node_q_out[w, i] = node_q_in[w, i]
            node_q_lo_out[w, i] = node_q_lo_in[w, i]
            node_qd_out[w, i] = node_qd_in[w, i]
        if wp.static(AL):
            # Only built lines have slots in use (a force without one has none; an inactive line
            # is rebuilt from the centerline when it starts).
            for a in range(tube_force_start[t], tube_force_start[t + 1]):
                if al_active[w, a] != 0:
                    for p in range(al_start[a], al_start[a] + end - start):
                        al_q_out[w, p] = al_q_in[w, p]
                        al_q_lo_out[w, p] = al_q_lo_in[w, p]
                        al_qd_out[w, p] = al_qd_in[w, p]
        for step in range(substep_count):
            frac = float(step + 1) / float(substep_count)
            if wp.static(CURVED):
                curvature_targets(w, pw, start, end, node_q_out, node_rest_q, node_kappa_rest, node_kappa_target)
            for i in range(start, end):
                node_f[w, i] = node_force(
                    w, pw, i, start, end, t,
                    node_rest_q, node_mass, seg_rest_length, seg_ke, seg_kd, node_bend_k,
                    node_anchor_k, node_anchor_kd, gravity, tube_force_start, force_node, al_start,
                    node_q_out, node_q_lo_out, node_qd_out, node_kappa_target, al_q_out, al_q_lo_out, al_qd_out,
                    node_f_ext, al_active, al_link_length, al_fwd_length, al_bwd_length,
                )  # fmt: skip
            # Each spring and bending stencil once, added to all its nodes (one thread owns the
            # tube); one pass over the edges, the stencil at node i taking edges i - 1 and i.
            e_prev = wp.vec3(0.0)
            for i in range(start, end - 1):
                e = node_delta(node_q_out, node_q_lo_out, w, i, i + 1)
                kd = float(0.0)
                if wp.static(SPRING_DAMPING):
                    kd = seg_kd[pw, i]
                fs = spring_force(e, node_qd_out[w, i + 1] - node_qd_out[w, i], seg_rest_length[pw, i], seg_ke[pw, i], kd)
                node_f[w, i] = node_f[w, i] + fs
                node_f[w, i + 1] = node_f[w, i + 1] - fs
                if wp.static(BENDING):
                    if i > start:
                        kb = node_bend_k[pw, i]
                        if kb != 0.0:
                            ga, gb = bend_gradients(e_prev, e, node_kappa_target[kt, i], kb)
                            node_f[w, i - 1] = node_f[w, i - 1] + ga
                            node_f[w, i] = node_f[w, i] + gb - ga
                            node_f[w, i + 1] = node_f[w, i + 1] - gb
                e_prev = e
            if wp.static(CURVED):
                frame_forces(w, pw, start, end, node_q_out, node_q_lo_out, node_rest_q, node_bend_k, node_kappa_target, node_f)
            if wp.static(AL):
                for a in range(tube_force_start[t], tube_force_start[t + 1]):
                    if al_active[w, a] != 0:
                        for i in range(start, end):
                            p = al_start[a] + (i - start)
                            al_f[w, p] = al_force(
                                w, pw, a, p, i, start, end, seg_ke, seg_kd, force_node,
                                node_q_out, node_q_lo_out, node_qd_out, al_q_out, al_q_lo_out, al_qd_out,
                                al_link_length, al_chord_length, al_fwd_length, al_bwd_length,
                            )  # fmt: skip
            for i in range(start, end):
                im = node_inv_mass[pw, i]
                if im == 0.0:
                    x_new = wp.lerp(pin_q_start[w, i], pin_q_end[w, i], frac)
                    node_qd_out[w, i] = (x_new - node_q_out[w, i]) / dt
                    node_q_out[w, i] = x_new
                    node_q_lo_out[w, i] = wp.vec3(0.0)
                else:
                    x_new, lo_new, v_new = advance(node_q_out[w, i], node_q_lo_out[w, i], node_qd_out[w, i], node_f[w, i], im, node_damping[pw, i], dt)
                    node_q_out[w, i] = x_new
                    node_q_lo_out[w, i] = lo_new
                    node_qd_out[w, i] = v_new
            if wp.static(AL):
                for a in range(tube_force_start[t], tube_force_start[t + 1]):
                    if al_active[w, a] != 0:
                        for i in range(start, end):
                            p = al_start[a] + (i - start)
                            x_new, lo_new, v_new = advance(al_q_out[w, p], al_q_lo_out[w, p], al_qd_out[w, p], al_f[w, p], 1.0 / node_mass[pw, i], node_damping[pw, i], dt)
                            al_q_out[w, p] = x_new
                            al_q_lo_out[w, p] = lo_new
                            al_qd_out[w, p] = v_new

    @wp.kernel(enable_backward=False, module="unique")
    def targets(
        # model:
        tube_node_start: wp.array[int],
        node_rest_q: wp.array2d[wp.vec3],
        node_kappa_rest: wp.array2d[wp.vec3],
        node_bend_k: wp.array2d[float],
        # state in:
        node_q: wp.array2d[wp.vec3],
        node_q_lo: wp.array2d[wp.vec3],
        # out:
        node_kappa_target: wp.array2d[wp.vec3],
        node_f_frame: wp.array2d[wp.vec3],
    ):
        """Curvature targets of curved rest shapes and the forces of their dependence on the
        shape [N], one thread per (world, tube)."""
        w, t = wp.tid()
        pw = w % node_rest_q.shape[0]
        start = tube_node_start[t]
        end = tube_node_start[t + 1]
        curvature_targets(w, pw, start, end, node_q, node_rest_q, node_kappa_rest, node_kappa_target)
        for i in range(start, end):
            node_f_frame[w, i] = wp.vec3(0.0)
        frame_forces(w, pw, start, end, node_q, node_q_lo, node_rest_q, node_bend_k, node_kappa_target, node_f_frame)

    @wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
    def step_nodes(
        frac: float,
        dt: float,
        # model:
        node_tube: wp.array[int],
        tube_node_start: wp.array[int],
        node_rest_q: wp.array2d[wp.vec3],
        node_mass: wp.array2d[float],
        node_inv_mass: wp.array2d[float],
        node_damping: wp.array2d[float],
        seg_rest_length: wp.array2d[float],
        seg_ke: wp.array2d[float],
        seg_kd: wp.array2d[float],
        node_bend_k: wp.array2d[float],
        node_anchor_k: wp.array2d[float],
        node_anchor_kd: wp.array2d[float],
        gravity: wp.vec3,
        tube_force_start: wp.array[int],
        force_node: wp.array[int],
        al_start: wp.array[int],
        # state in:
        node_q_in: wp.array2d[wp.vec3],
        node_q_lo_in: wp.array2d[wp.vec3],
        node_qd_in: wp.array2d[wp.vec3],
        node_kappa_target: wp.array2d[wp.vec3],
        al_q_in: wp.array2d[wp.vec3],
        al_q_lo_in: wp.array2d[wp.vec3],
        al_qd_in: wp.array2d[wp.vec3],
        node_f_frame: wp.array2d[wp.vec3],
        # control:
        node_f_ext: wp.array2d[wp.vec3],
        pin_q_start: wp.array2d[wp.vec3],
        pin_q_end: wp.array2d[wp.vec3],
        al_active: wp.array2d[int],
        al_link_length: wp.array2d[float],
        al_fwd_length: wp.array2d[float],
        al_bwd_length: wp.array2d[float],
        # out:
        node_q_out: wp.array2d[wp.vec3],
        node_q_lo_out: wp.array2d[wp.vec3],
        node_qd_out: wp.array2d[wp.vec3],
    ):
        """One substep of ``dt`` [s] for one node; ``frac`` is the pin targets' progress."""
        w, i = wp.tid()
        pw = w % node_mass.shape[0]
        im = node_inv_mass[pw, i]
        if im == 0.0:
            x_new = wp.lerp(pin_q_start[w, i], pin_q_end[w, i], frac)
            node_qd_out[w, i] = (x_new - node_q_in[w, i]) / dt
            node_q_out[w, i] = x_new
            node_q_lo_out[w, i] = wp.vec3(0.0)
            return
        t = node_tube[i]
        start = tube_node_start[t]
        end = tube_node_start[t + 1]
        # Each node evaluates its two springs and three bending stencils itself, from the four
        # edges around it, each formed once from the compensated positions (measured on an H100:
        # 1.4x faster than evaluating each stencil once into memory and summing in a second kernel).
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
                kd = seg_kd[pw, i - 1]
            f += spring_force(-em1, node_qd_in[w, i - 1] - v, seg_rest_length[pw, i - 1], seg_ke[pw, i - 1], kd)
        if i + 1 < end:
            e0 = node_delta(node_q_in, node_q_lo_in, w, i, i + 1)
            kd = float(0.0)
            if wp.static(SPRING_DAMPING):
                kd = seg_kd[pw, i]
            f += spring_force(e0, node_qd_in[w, i + 1] - v, seg_rest_length[pw, i], seg_ke[pw, i], kd)
        if wp.static(BENDING):
            kt = w % node_kappa_target.shape[0]
            if i + 1 < end - 1:
                ep1 = node_delta(node_q_in, node_q_lo_in, w, i + 1, i + 2)
                k = node_bend_k[pw, i + 1]
                if k != 0.0:
                    ga, gb = bend_gradients(e0, ep1, node_kappa_target[kt, i + 1], k)
                    f += ga
            if i > start and i < end - 1:
                k = node_bend_k[pw, i]
                if k != 0.0:
                    ga, gb = bend_gradients(em1, e0, node_kappa_target[kt, i], k)
                    f += gb - ga
            if i - 1 > start:
                em2 = node_delta(node_q_in, node_q_lo_in, w, i - 2, i - 1)
                k = node_bend_k[pw, i - 1]
                if k != 0.0:
                    ga, gb = bend_gradients(em2, em1, node_kappa_target[kt, i - 1], k)
                    f -= gb
        if wp.static(CURVED):
            f += node_f_frame[w, i]
        f += node_force(
            w, pw, i, start, end, t,
            node_rest_q, node_mass, seg_rest_length, seg_ke, seg_kd, node_bend_k,
            node_anchor_k, node_anchor_kd, gravity, tube_force_start, force_node, al_start,
            node_q_in, node_q_lo_in, node_qd_in, node_kappa_target, al_q_in, al_q_lo_in, al_qd_in,
            node_f_ext, al_active, al_link_length, al_fwd_length, al_bwd_length,
        )  # fmt: skip
        x_new, lo_new, v_new = advance(node_q_in[w, i], node_q_lo_in[w, i], node_qd_in[w, i], f, im, node_damping[pw, i], dt)
        node_q_out[w, i] = x_new
        node_q_lo_out[w, i] = lo_new
        node_qd_out[w, i] = v_new

    @wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
    def step_al(
        dt: float,
        # model:
        force_tube: wp.array[int],
        tube_node_start: wp.array[int],
        node_mass: wp.array2d[float],
        node_damping: wp.array2d[float],
        seg_ke: wp.array2d[float],
        seg_kd: wp.array2d[float],
        force_node: wp.array[int],
        al_start: wp.array[int],
        al_force_index: wp.array[int],
        # state in:
        node_q_in: wp.array2d[wp.vec3],
        node_q_lo_in: wp.array2d[wp.vec3],
        node_qd_in: wp.array2d[wp.vec3],
        al_q_in: wp.array2d[wp.vec3],
        al_q_lo_in: wp.array2d[wp.vec3],
        al_qd_in: wp.array2d[wp.vec3],
        # control:
        al_active: wp.array2d[int],
        al_link_length: wp.array2d[float],
        al_chord_length: wp.array2d[float],
        al_fwd_length: wp.array2d[float],
        al_bwd_length: wp.array2d[float],
        # out:
        al_q_out: wp.array2d[wp.vec3],
        al_q_lo_out: wp.array2d[wp.vec3],
        al_qd_out: wp.array2d[wp.vec3],
    ):
        """One substep for one assistant-line point (thread per (world, AL slot))."""
        w, p = wp.tid()
        a = al_force_index[p]
        if al_active[w, a] == 0:
            return
        pw = w % node_mass.shape[0]
        t = force_tube[a]
        start = tube_node_start[t]
        end = tube_node_start[t + 1]
        i = start + (p - al_start[a])
        f = al_force(
            w, pw, a, p, i, start, end, seg_ke, seg_kd, force_node,
            node_q_in, node_q_lo_in, node_qd_in, al_q_in, al_q_lo_in, al_qd_in,
            al_link_length, al_chord_length, al_fwd_length, al_bwd_length,
        )  # fmt: skip
        x_new, lo_new, v_new = advance(al_q_in[w, p], al_q_lo_in[w, p], al_qd_in[w, p], f, 1.0 / node_mass[pw, i], node_damping[pw, i], dt)
        al_q_out[w, p] = x_new
        al_q_lo_out[w, p] = lo_new
        al_qd_out[w, p] = v_new

    return substeps, targets, step_nodes, step_al
