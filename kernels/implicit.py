"""Implicit (backward) Euler for the centerline and its assistant lines, one thread per (world, tube).

Each substep of length ``h`` [s] solves the coupled linear system of the seed paper's implicit
Euler, linearised about the current iterate (Newton steps of backward Euler)::

    (M + h C + h^2 K) dv = h (f(x, v) - K u - C g)
    v' = v + dv          x' = x + h v'    (compensated sum, as the semi-implicit kernel)

- ``f`` [N]: every force term of :mod:`warp_tube.kernels.springs` (structural and assistant-line
  springs ``ke (|d| - L)`` with damping ``kd`` along them, bending ``k/2 |kb - kb_target|^2`` with
  its curved-frame terms, the node terms) and the mass-proportional damping ``-alpha m v``.
- ``K`` [N/m]: stiffness, each term's block from :mod:`.springs` next to its force: the springs'
  exact Hessian with its transverse part clamped at zero when compressed (``spring_stiffness``),
  bending's Gauss-Newton ``k J^T J`` (``bend_jacobians``, the target held fixed), the node terms'
  ``ka I``.
- ``C`` [N s/m]: ``alpha M`` plus ``kd n n^T`` along every spring and ``kd_anchor I``: the exact
  velocity Jacobian of the damping forces.
- ``u`` [m] and ``g`` [m/s]: the displacement predicted from the current velocity (``h v``) and
  the prescribed velocity change; both are zero at free nodes except ``u = h v``. Pinned nodes are
  prescribed: their rows are replaced by the identity, their known motion to the interpolated pin
  target enters the right-hand side of their free neighbours through ``-K u - C g``.

Unknowns: every node and, on a tube with assistant lines (at most ``K`` per tube: the model's
``al_lines``), every line point beside it, ordered node by node: unknown ``u = i (1 + K) + m`` is
node ``i`` (``m = 0``) or the point of the tube's line ``m - 1`` at node ``i``. A line point has the
mass and mass damping of its node, as in the semi-implicit kernels; an inactive line's unknowns
are fixed (identity rows). In this order the matrix is symmetric positive definite and
block-banded, 3x3 blocks with bandwidth ``B = 2 (1 + K)`` (bending couples nodes two apart). It is
factored by a banded block ``L D L^T`` (no fill outside the band) and solved sequentially along the
tube, in float64: with a stiff tube and a 1/60 s step ``h^2 K`` exceeds ``M`` by up to ~1e8, past
what float32 resolves.
"""

from __future__ import annotations

import functools

import warp as wp

from .assistant_line import al_point_energy, al_point_forces, al_spring_block, al_springs
from .bending import (
    bend_energy,
    bend_jacobians,
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
    node_terms_have_blocks,
    pin_step,
    spring_damping_matrix,
    spring_dissipation,
    spring_energy,
    spring_force,
    spring_stiffness,
)

EPS64 = wp.constant(wp.float64(1.0e-12))

mat43d = wp.types.matrix((4, 3), wp.float64)


@wp.struct
class ImplicitScratch:
    """Per-substep scratch of the implicit kernel; U = node_count (1 + K) unknowns a world.

    Attributes:
        node_kappa_target: curvature targets of curved rest shapes [1], (W, N) vec3.
        node_f_frame: force of the targets' dependence on the shape [N], (W, N) vec3.
        x0, v0: positions [m] and velocities [m/s] at the substep's start, (W, U) vec3d.
        v_it: the Newton iterate's end-of-step velocity [m/s], (W, U) vec3d.
        r: ``h f - M (v_it - v0)`` [N s], then the solution ``dv`` [m/s], (W, U) vec3d.
        mat_d: diagonal blocks ``A_uu`` [kg], then the factor's ``D_u``, (W, U) mat33d.
        mat_dinv: ``D_u^-1`` [1/kg], (W, U) mat33d.
        mat_l: ``mat_l[w, u, d - 1]`` = ``A_{u+d,u}`` [kg], then the factor's ``L_{u+d,u}`` [1],
            (W, U, B) mat33d.
    """

    node_kappa_target: wp.array2d[wp.vec3]
    node_f_frame: wp.array2d[wp.vec3]
    x0: wp.array2d[wp.vec3d]
    v0: wp.array2d[wp.vec3d]
    v_it: wp.array2d[wp.vec3d]
    r: wp.array2d[wp.vec3d]
    mat_d: wp.array2d[wp.mat33d]
    mat_dinv: wp.array2d[wp.mat33d]
    mat_l: wp.array3d[wp.mat33d]


@functools.cache
def make_factor_solve(bandwidth: int):
    """``factor_solve(w, u0, u1, s)``: solve the banded system of unknowns ``u0..u1-1`` in place
    (``s.r`` becomes ``A^-1 s.r``), for block bandwidth ``bandwidth``; cached.

    Block ``L D L^T`` with unit lower ``L`` of bandwidth B::

        D_i       = A_ii - sum_m L_{i,i-m} D_{i-m} L_{i,i-m}^T
        L_{i+d,i} = (A_{i+d,i} - sum_m L_{i+d,i-m} D_{i-m} L_{i,i-m}^T) D_i^-1     (d + m <= B)

    then forward substitution, ``D^-1``, back substitution.

    Each ``D_i`` is stored symmetrised. In floating point ``L D L^T`` is symmetric only to
    round-off, and this recurrence, which reads the lower band only, does not damp the skew part
    of ``D``: it grows by about 1.5x a node (measured with bending, 0.01 m segments, 1/240 s).
    Seeded at 1e-30 by a straight tube's round-off, it reaches O(1) after ~150 nodes and the
    solve is wrong for the rest of the tube (a free-falling rod's tail fell at a tenth of g).
    With ``D_i`` kept exactly symmetric, ``L D L^T`` is exactly symmetric and its difference from
    ``A`` is a sum of per-block round-off that does not accumulate along the tube.
    """
    B = int(bandwidth)

    @wp.func
    def factor_solve(w: int, u0: int, u1: int, s: ImplicitScratch):
        half = wp.float64(0.5)
        for i in range(u0, u1):
            d = s.mat_d[w, i]
            for m in range(1, wp.static(B + 1)):
                if i - m >= u0:
                    l = s.mat_l[w, i - m, m - 1]
                    d = d - l * s.mat_d[w, i - m] * wp.transpose(l)
            d = (d + wp.transpose(d)) * half
            s.mat_d[w, i] = d
            dinv = wp.inverse(d)
            s.mat_dinv[w, i] = dinv
            for dd in range(1, wp.static(B + 1)):
                if i + dd < u1:
                    a = s.mat_l[w, i, dd - 1]
                    for m in range(1, wp.static(B)):
                        if dd + m <= wp.static(B) and i - m >= u0:
                            a = a - s.mat_l[w, i - m, dd + m - 1] * s.mat_d[w, i - m] * wp.transpose(s.mat_l[w, i - m, m - 1])
                    s.mat_l[w, i, dd - 1] = a * dinv
        for i in range(u0, u1):
            y = s.r[w, i]
            for m in range(1, wp.static(B + 1)):
                if i - m >= u0:
                    y = y - s.mat_l[w, i - m, m - 1] * s.r[w, i - m]
            s.r[w, i] = y
        for k in range(u1 - u0):
            i = u1 - 1 - k
            x = s.mat_dinv[w, i] * s.r[w, i]
            for dd in range(1, wp.static(B + 1)):
                if i + dd < u1:
                    x = x - wp.transpose(s.mat_l[w, i, dd - 1]) * s.r[w, i + dd]
            s.r[w, i] = x

    return factor_solve


@wp.func(inline=True)
def unknown_position(s: StateArrays, w: int, ref: wp.vec3i) -> wp.vec3d:
    """Compensated position [m] of an unknown (see ``unknown``), in float64."""
    if ref[0] == 1:
        return wp.vec3d(s.al_q[w, ref[1]]) + wp.vec3d(s.al_q_lo[w, ref[1]])
    return wp.vec3d(s.node_q[w, ref[1]]) + wp.vec3d(s.node_q_lo[w, ref[1]])


@wp.func(inline=True)
def node_position(s: StateArrays, w: int, i: int) -> wp.vec3d:
    """Compensated position [m] of node ``i``, in float64."""
    return wp.vec3d(s.node_q[w, i]) + wp.vec3d(s.node_q_lo[w, i])


@wp.func(inline=True)
def unknown_velocity(s: StateArrays, w: int, ref: wp.vec3i) -> wp.vec3d:
    """Velocity [m/s] of an unknown, in float64."""
    if ref[0] == 1:
        return wp.vec3d(s.al_qd[w, ref[1]])
    return wp.vec3d(s.node_qd[w, ref[1]])


@wp.func(inline=True)
def set_unknown(s: StateArrays, w: int, ref: wp.vec3i, x: wp.vec3d, v: wp.vec3d):
    """Store position ``x`` [m] (compensated: the float32 rounding and the rest) and velocity ``v``
    [m/s] of an unknown."""
    hi = wp.vec3(x)
    if ref[0] == 1:
        s.al_q[w, ref[1]] = hi
        s.al_q_lo[w, ref[1]] = wp.vec3(x - wp.vec3d(hi))
        s.al_qd[w, ref[1]] = wp.vec3(v)
    else:
        s.node_q[w, ref[1]] = hi
        s.node_q_lo[w, ref[1]] = wp.vec3(x - wp.vec3d(hi))
        s.node_qd[w, ref[1]] = wp.vec3(v)


@wp.func(inline=True)
def add_coupling(w: int, ua: int, ub: int, fa: wp.vec3d, blk: wp.mat33d, free_a: bool, free_b: bool, s: ImplicitScratch):
    """Add a two-ended term to the system: force ``fa`` [N] on unknown ``ua`` and ``-fa`` on
    ``ub``, block ``blk`` [kg] on both diagonals and ``-blk`` between them (fixed unknowns keep
    their identity rows)."""
    if free_a:
        s.r[w, ua] = s.r[w, ua] + fa
        s.mat_d[w, ua] = s.mat_d[w, ua] + blk
    if free_b:
        s.r[w, ub] = s.r[w, ub] - fa
        s.mat_d[w, ub] = s.mat_d[w, ub] + blk
    if free_a and free_b:
        lo = wp.min(ua, ub)
        s.mat_l[w, lo, wp.max(ua, ub) - lo - 1] = s.mat_l[w, lo, wp.max(ua, ub) - lo - 1] - blk


@functools.cache
def make_implicit_kernel(features: Features, al_lines: int = 0):
    """The implicit substep kernel specialised to ``features`` and at most ``al_lines``
    assistant lines per tube (cached: one compile per combination)."""
    features = Features(*(bool(v) for v in features))
    BENDING = features.bending
    CURVED = features.curved
    MASS_DAMPING = features.mass_damping
    SPRING_DAMPING = features.spring_damping
    AL = features.assistant_line and al_lines > 0
    K = int(al_lines) if AL else 0
    PER_NODE = 1 + K  # unknowns per node
    factor_solve = make_factor_solve(2 * PER_NODE)
    load_node, node_force, node_energy, node_stiffness, node_damping, _ = make_node_terms(features)
    NODE_STIFFNESS = node_terms_have_blocks(features)

    @wp.func(inline=True)
    def unknown(model: ModelArrays, control: ControlArrays, w: int, t: int, start: int, u: int) -> wp.vec3i:
        """``(kind, index, node)`` of unknown ``u``: kind 0, node ``index``; kind 1, line slot
        ``index``; kind -1, a point of an inactive line (fixed). ``node`` is the node it sits at."""
        if wp.static(PER_NODE == 1):
            return wp.vec3i(0, u, u)
        i = u // PER_NODE
        m = u - i * PER_NODE
        if m == 0:
            return wp.vec3i(0, i, i)
        a = model.tube_al_force[t, m - 1]
        if a >= 0:
            if control.al_active[w, a] != 0:
                return wp.vec3i(1, model.al_start[a] + i - start, i)
        return wp.vec3i(-1, 0, i)

    @wp.func(inline=True)
    def is_free(model: ModelArrays, pw: int, ref: wp.vec3i) -> bool:
        if ref[0] == 0:
            return model.node_inv_mass[pw, ref[1]] > 0.0
        return ref[0] == 1

    @wp.func
    def line_point(
        model: ModelArrays, control: ControlArrays, w: int, pw: int, t: int, start: int, end: int, u: int, ref: wp.vec3i,
        scratch: ImplicitScratch, state: StateArrays,
    ):  # fmt: skip
        """The springs of the line point at unknown ``u`` (``ref``; springs.al_springs) and its
        neighbours' unknowns, with the neighbours' positions [m], velocities [m/s] and
        start-of-step positions minus the point's, rows as springs.al_point_forces."""
        i = ref[2]
        m = u - i * PER_NODE
        ip = wp.min(i + 1, end - 1)
        im = wp.max(i - 1, start)
        nb = wp.vec4i(i * PER_NODE, ip * PER_NODE + m, ip * PER_NODE, im * PER_NODE)
        x = unknown_position(state, w, ref)
        v = unknown_velocity(state, w, ref)
        d = mat43d()
        dv = mat43d()
        d0 = mat43d()
        for s in range(4):
            rb = unknown(model, control, w, t, start, nb[s])
            d[s] = unknown_position(state, w, rb) - x
            dv[s] = unknown_velocity(state, w, rb) - v
            d0[s] = scratch.x0[w, nb[s]] - scratch.x0[w, u]
        p = ref[1]
        rest = wp.vec4(control.al_link_length[w, p], control.al_chord_length[w, p], control.al_fwd_length[w, p], control.al_bwd_length[w, p])
        springs = al_springs(i, model.force_node[model.tube_al_force[t, m - 1]], start, end)
        return springs, nb, d, dv, d0, rest

    @wp.func
    def line_damping(model: ModelArrays, pw: int, i: int) -> wp.vec2:
        """Spring damping [N s/m] of segments ``i`` and ``i - 1`` (zero without spring damping)."""
        if wp.static(SPRING_DAMPING):
            return wp.vec2(model.seg_kd[pw, i], model.seg_kd[pw, wp.max(i - 1, 0)])
        return wp.vec2(0.0)

    @wp.func
    def set_iterate(
        w: int, pw: int, t: int, start: int, end: int, h: wp.float64, step: wp.float64,
        model: ModelArrays, control: ControlArrays, scratch: ImplicitScratch, state: StateArrays,
    ):  # fmt: skip
        """Free unknowns: ``v_it + step dv`` (``dv`` in ``scratch.r``) and the consistent position
        ``x0 + h (v_it + step dv)`` into ``state``."""
        for u in range(start * PER_NODE, end * PER_NODE):
            ref = unknown(model, control, w, t, start, u)
            if is_free(model, pw, ref):
                v_new = scratch.v_it[w, u] + scratch.r[w, u] * step
                set_unknown(state, w, ref, scratch.x0[w, u] + v_new * h, v_new)

    @wp.func
    def merit(
        w: int, pw: int, t: int, start: int, end: int, h: wp.float64,
        model: ModelArrays, control: ControlArrays, scratch: ImplicitScratch, state: StateArrays,
    ) -> wp.float64:  # fmt: skip
        """Incremental potential [J] of the end-of-step positions ``y`` in ``state``::

            G(y) = sum m/(2 h^2) |y - x0 - h v0|^2 + E(y) + D(y)

        whose stationary point is the backward Euler step (``E``: the terms' energies, node terms
        included; ``D``: damping as a dissipation potential, ``alpha m / (2h) |y - x0|^2`` and the
        terms' own). Fixed unknowns' terms are constant and left out. Used by the line search only.
        """
        g = wp.float64(0.0)
        half = wp.float64(0.5)
        if wp.static(CURVED):
            curvature_targets(w, pw, start, end, state.node_q, state.node_q_lo, model.node_rest_q, model.node_kappa_rest, model.node_bend_k,
                              model.node_inv_mass, scratch.node_kappa_target)
        for u in range(start * PER_NODE, end * PER_NODE):
            ref = unknown(model, control, w, t, start, u)
            if not is_free(model, pw, ref):
                continue
            i = ref[2]
            m = wp.float64(model.node_mass[pw, i])
            y = unknown_position(state, w, ref)
            dy = y - scratch.x0[w, u]
            g += half * m * wp.length_sq(dy - scratch.v0[w, u] * h) / (h * h)
            if wp.static(MASS_DAMPING):
                g += half * wp.float64(model.node_damping[pw, i]) * m * wp.length_sq(dy) / h
            if ref[0] == 0:
                p = load_node(model, control, w, pw, i)
                g += node_energy(p, y)
                if wp.static(NODE_STIFFNESS):
                    g += half * wp.float64(node_damping(p)) * wp.length_sq(dy) / h
            if wp.static(AL):
                if ref[0] == 1:
                    springs, nb, d, dv, d0, rest = line_point(model, control, w, pw, t, start, end, u, ref, scratch, state)
                    c = line_damping(model, pw, i)
                    g += al_point_energy(springs, d, d0, rest, model.seg_ke[pw, i], model.seg_ke[pw, wp.max(i - 1, start)], c[0], c[1], h)
        for i in range(start, end - 1):
            ua = i * PER_NODE
            ub = ua + PER_NODE
            e = node_position(state, w, i + 1) - node_position(state, w, i)
            g += spring_energy(e, wp.float64(model.seg_rest_length[pw, i]), wp.float64(model.seg_ke[pw, i]))
            if wp.static(SPRING_DAMPING):
                g += spring_dissipation(e, scratch.x0[w, ub] - scratch.x0[w, ua], wp.float64(model.seg_kd[pw, i]), h)
        if wp.static(BENDING):
            for j in range(start + 1, end - 1):
                kbend = wp.float64(model.node_bend_k[pw, j])
                if kbend == wp.float64(0.0):
                    continue
                xa = node_position(state, w, j - 1)
                xb = node_position(state, w, j)
                xc = node_position(state, w, j + 1)
                g += bend_energy(xb - xa, xc - xb, wp.vec3d(scratch.node_kappa_target[w, j]), kbend)
        return g

    @wp.func
    def add_spring(
        w: int, ua: int, ub: int, d: wp.vec3d, dv: wp.vec3d, rest_length: float, ke: float, kd: float,
        h: wp.float64, free_a: bool, free_b: bool, scratch: ImplicitScratch,
    ):  # fmt: skip
        """A spring from unknown ``ua`` to ``ub`` (end difference ``d`` [m], velocity difference
        ``dv`` [m/s]): its force, stiffness and damping blocks."""
        if wp.length(d) < EPS64:
            return
        L = wp.float64(rest_length)
        k = wp.float64(ke)
        c = wp.float64(0.0)
        if wp.static(SPRING_DAMPING):
            c = wp.float64(kd)
        blk = spring_stiffness(d, L, k) * (h * h)
        if wp.static(SPRING_DAMPING):
            blk = blk + spring_damping_matrix(d, c) * h
        add_coupling(w, ua, ub, spring_force(d, dv, L, k, c), blk, free_a, free_b, scratch)

    @wp.func
    def newton_iteration(
        w: int, pw: int, t: int, start: int, end: int, h: wp.float64,
        model: ModelArrays, control: ControlArrays, scratch: ImplicitScratch, state: StateArrays, first: bool,
    ) -> wp.float64:  # fmt: skip
        """One Newton iteration of the substep, with a backtracking line search.

        The iterate is the end-of-step guess ``(y, v_it)``, ``y = x0 + h v_it``, held in ``state``
        (and ``v_it`` in float64 in ``scratch``); pinned nodes already sit at their targets. The
        first iteration starts from ``y = x0``, ``v_it = 0``, where it is exactly the linearised
        backward Euler step ``(M + h C + h^2 K) dv = h (f(x0, v0) - h K v0)`` written for
        ``v' = v_it + dv``. It solves ``(M + h C + h^2 K) dv = h f(y, v_it) - M (v_it - v0)``, then
        halves the step ``s`` from 1 until the incremental potential :func:`merit` does not
        increase (at most 8 halvings; see below), and sets ``v_it += s dv``. Returns
        ``max |h s dv|`` [m].
        """
        h2 = h * h
        zero3 = wp.vec3d(wp.float64(0.0))
        zero33 = wp.mat33d(wp.float64(0.0))
        eye = wp.identity(n=3, dtype=wp.float64)
        g0 = merit(w, pw, t, start, end, h, model, control, scratch, state)  # also the curvature targets
        # Per unknown: inertia, mass damping and the node terms.
        for u in range(start * PER_NODE, end * PER_NODE):
            for b in range(wp.static(2 * PER_NODE)):
                scratch.mat_l[w, u, b] = zero33
            ref = unknown(model, control, w, t, start, u)
            if not is_free(model, pw, ref):
                scratch.r[w, u] = zero3
                scratch.mat_d[w, u] = eye
                continue
            i = ref[2]
            v = scratch.v_it[w, u]
            m = wp.float64(model.node_mass[pw, i])
            # r collects f - M (v_it - v0) / h (times h below).
            f = (scratch.v0[w, u] - v) * (m / h)
            a = eye * m
            if wp.static(MASS_DAMPING):
                alpha = wp.float64(model.node_damping[pw, i])
                f = f - v * (alpha * m)
                a = a + eye * (h * alpha * m)
            if ref[0] == 0:
                p = load_node(model, control, w, pw, i)
                f = f + node_force(p, unknown_position(state, w, ref), v)
                if wp.static(NODE_STIFFNESS):
                    a = a + eye * (h2 * wp.float64(node_stiffness(p)) + h * wp.float64(node_damping(p)))
            scratch.r[w, u] = f
            scratch.mat_d[w, u] = a
        # Structural springs, each once: force on both ends and the blocks.
        for i in range(start, end - 1):
            ra = wp.vec3i(0, i, i)
            rb = wp.vec3i(0, i + 1, i + 1)
            add_spring(
                w, i * PER_NODE, (i + 1) * PER_NODE,
                unknown_position(state, w, rb) - unknown_position(state, w, ra),
                unknown_velocity(state, w, rb) - unknown_velocity(state, w, ra),
                model.seg_rest_length[pw, i], model.seg_ke[pw, i], model.seg_kd[pw, i], h,
                is_free(model, pw, ra), is_free(model, pw, rb), scratch,
            )  # fmt: skip
        if wp.static(AL):
            # Line springs, each once (owned by a line point, springs.al_springs).
            for u in range(start * PER_NODE, end * PER_NODE):
                ref = unknown(model, control, w, t, start, u)
                if ref[0] == 1:
                    i = ref[2]
                    springs, nb, d, dv, d0, rest = line_point(model, control, w, pw, t, start, end, u, ref, scratch, state)
                    c = line_damping(model, pw, i)
                    ke = model.seg_ke[pw, i]
                    ke_prev = model.seg_ke[pw, wp.max(i - 1, start)]
                    f, r = al_point_forces(springs, d, dv, rest, ke, ke_prev, c[0], c[1])
                    for s in range(4):
                        if springs[s] != 0:
                            blk = al_spring_block(springs, s, d, rest, ke, ke_prev, c[0], c[1], h)
                            rb = unknown(model, control, w, t, start, nb[s])
                            add_coupling(w, u, nb[s], -r[s], blk, True, is_free(model, pw, rb), scratch)
        if wp.static(BENDING):
            # Bending stencils: force -J_m^T k (kb - target), Gauss-Newton blocks k J_m^T J_n.
            for j in range(start + 1, end - 1):
                kbend = wp.float64(model.node_bend_k[pw, j])
                if kbend == wp.float64(0.0):
                    continue
                xa = node_position(state, w, j - 1)
                xb = node_position(state, w, j)
                xc = node_position(state, w, j + 1)
                kb, ja, jb = bend_jacobians(xb - xa, xc - xb)
                if wp.static(CURVED):
                    kb = kb - wp.vec3d(scratch.node_kappa_target[w, j])
                j0 = -ja
                j1 = ja - jb
                j2 = jb
                sv = kb * kbend
                hk = h2 * kbend
                u0 = (j - 1) * PER_NODE
                u1 = j * PER_NODE
                u2 = (j + 1) * PER_NODE
                f0 = model.node_inv_mass[pw, j - 1] > 0.0
                f1 = model.node_inv_mass[pw, j] > 0.0
                f2 = model.node_inv_mass[pw, j + 1] > 0.0
                if f0:
                    scratch.r[w, u0] = scratch.r[w, u0] - wp.transpose(j0) * sv
                    scratch.mat_d[w, u0] = scratch.mat_d[w, u0] + wp.transpose(j0) * j0 * hk
                if f1:
                    scratch.r[w, u1] = scratch.r[w, u1] - wp.transpose(j1) * sv
                    scratch.mat_d[w, u1] = scratch.mat_d[w, u1] + wp.transpose(j1) * j1 * hk
                if f2:
                    scratch.r[w, u2] = scratch.r[w, u2] - wp.transpose(j2) * sv
                    scratch.mat_d[w, u2] = scratch.mat_d[w, u2] + wp.transpose(j2) * j2 * hk
                if f0 and f1:
                    scratch.mat_l[w, u0, PER_NODE - 1] = scratch.mat_l[w, u0, PER_NODE - 1] + wp.transpose(j1) * j0 * hk
                if f1 and f2:
                    scratch.mat_l[w, u1, PER_NODE - 1] = scratch.mat_l[w, u1, PER_NODE - 1] + wp.transpose(j2) * j1 * hk
                if f0 and f2:
                    scratch.mat_l[w, u0, 2 * PER_NODE - 1] = scratch.mat_l[w, u0, 2 * PER_NODE - 1] + wp.transpose(j2) * j0 * hk
        if wp.static(CURVED):
            # The targets move with the shape: their exact force (bending.frame_forces).
            for i in range(start, end):
                scratch.node_f_frame[w, i] = wp.vec3(0.0)
            frame_forces(w, pw, start, end, state.node_q, state.node_q_lo, model.node_rest_q, model.node_bend_k, scratch.node_kappa_target, scratch.node_f_frame)
            for i in range(start, end):
                if model.node_inv_mass[pw, i] > 0.0:
                    scratch.r[w, i * PER_NODE] = scratch.r[w, i * PER_NODE] + wp.vec3d(scratch.node_f_frame[w, i])
        for u in range(start * PER_NODE, end * PER_NODE):
            scratch.r[w, u] = scratch.r[w, u] * h
        factor_solve(w, start * PER_NODE, end * PER_NODE, scratch)
        step = wp.float64(1.0)
        # Halve until G decreases: an ill-conditioned direction (a hard push folding a short, wide
        # tube) can need far more halvings than a well-posed one, and keeping a step that raised G
        # left a frame with many times the energy put in; 2^-39 is below any useful move.
        for k in range(40):
            set_iterate(w, pw, t, start, end, h, step, model, control, scratch, state)
            # Accept within round-off (1e-9 relative, float64 sums of float32-stored positions):
            # near equilibrium the change of G is below it and a strict test would creep.
            if merit(w, pw, t, start, end, h, model, control, scratch, state) <= g0 + wp.float64(1.0e-9) * wp.abs(g0):
                break
            step = step * wp.float64(0.5)
            if k == 39:
                # No decrease along dv (round-off level): the first iteration keeps its shortest
                # step (dv is a descent direction there), a later one keeps the previous iterate.
                if not first:
                    step = wp.float64(0.0)
                    set_iterate(w, pw, t, start, end, h, step, model, control, scratch, state)
                else:
                    step = step * wp.float64(2.0)
        moved = wp.float64(0.0)
        for u in range(start * PER_NODE, end * PER_NODE):
            if is_free(model, pw, unknown(model, control, w, t, start, u)):
                delta = scratch.r[w, u] * step
                scratch.v_it[w, u] = scratch.v_it[w, u] + delta
                moved = wp.max(moved, wp.length(delta) * h)
        return moved

    @wp.kernel(enable_backward=False, module="unique")
    def implicit_substeps(
        substep_count: int,
        dt: float,
        iterations: int,
        tolerance: float,
        model: ModelArrays,
        state_in: StateArrays,
        control: ControlArrays,
        scratch: ImplicitScratch,
        state_out: StateArrays,
    ):
        """Advance one tube of one world by ``substep_count`` implicit substeps of ``dt`` [s].

        Each substep runs up to ``iterations`` Newton iterations (1: the linearised step), stopping
        early once an iteration moves no unknown by more than ``tolerance`` [m]. Thread (world,
        tube). Model arrays (1 or world_count, node_count) are read at row ``w % rows``; state,
        control and scratch arrays are (world_count, ...). Pins move linearly from
        ``control.pin_q_start`` to ``control.pin_q_end`` over the call.
        """
        w, t = wp.tid()
        pw = w % model.node_mass.shape[0]
        start = model.tube_node_start[t]
        end = model.tube_node_start[t + 1]
        h = wp.float64(dt)
        for i in range(start, end):
            state_out.node_q[w, i] = state_in.node_q[w, i]
            state_out.node_q_lo[w, i] = state_in.node_q_lo[w, i]
            state_out.node_qd[w, i] = state_in.node_qd[w, i]
        if wp.static(AL):
            for u in range(start * PER_NODE, end * PER_NODE):
                ref = unknown(model, control, w, t, start, u)
                if ref[0] == 1:
                    state_out.al_q[w, ref[1]] = state_in.al_q[w, ref[1]]
                    state_out.al_q_lo[w, ref[1]] = state_in.al_q_lo[w, ref[1]]
                    state_out.al_qd[w, ref[1]] = state_in.al_qd[w, ref[1]]
        inv_count = 1.0 / float(substep_count)
        for step in range(substep_count):
            left = frame_left(step, substep_count, inv_count)
            # Start of the substep: x0, v0; the first iterate y = x0, v_it = 0, pins at their targets.
            for u in range(start * PER_NODE, end * PER_NODE):
                ref = unknown(model, control, w, t, start, u)
                if ref[0] < 0:
                    continue
                x0 = unknown_position(state_out, w, ref)
                scratch.x0[w, u] = x0
                scratch.v0[w, u] = unknown_velocity(state_out, w, ref)
                scratch.v_it[w, u] = wp.vec3d(wp.float64(0.0))
                i = ref[1]
                if ref[0] == 0 and model.node_inv_mass[pw, i] == 0.0:
                    x_pin, v_pin = pin_step(control.pin_q_start[w, i], control.pin_q_end[w, i], left, x0, wp.float64(1.0) / h)
                    state_out.node_qd[w, i] = wp.vec3(v_pin)
                    state_out.node_q[w, i] = x_pin
                    state_out.node_q_lo[w, i] = wp.vec3(0.0)
                elif ref[0] == 0:
                    state_out.node_qd[w, i] = wp.vec3(0.0)
                else:
                    state_out.al_qd[w, i] = wp.vec3(0.0)
            for it in range(iterations):
                moved = newton_iteration(w, pw, t, start, end, h, model, control, scratch, state_out, it == 0)
                if moved <= wp.float64(tolerance):
                    break

    return implicit_substeps
