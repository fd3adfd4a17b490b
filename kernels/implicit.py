"""Linearised implicit (backward) Euler for the centerline, one thread per (world, tube).

Each substep of length ``h`` [s] solves the coupled linear system of the seed paper's implicit
Euler, linearised once about the current state (one Newton step of backward Euler)::

    (M + h C + h^2 K) dv = h (f(x, v) - K u - C g)
    v' = v + dv          x' = x + h v'    (compensated sum, as the semi-implicit kernel)

- ``f`` [N]: every force of :mod:`warp_tube.kernels.springs` and ``integrate`` (structural
  springs ``ke (|d| - L)`` with damping ``kd`` along them, bending ``k/2 |kb - kb_target|^2``,
  returning springs, gravity, point forces) and the mass-proportional damping ``-alpha m v``.
- ``K`` [N/m]: stiffness. Structural spring: ``ke (n n^T + max(0, 1 - L/|d|) (I - n n^T))``, the
  exact Hessian with its transverse part clamped at zero when compressed, so ``K`` stays positive
  semi-definite. Bending: Gauss-Newton ``k J^T J``, ``J`` the Jacobian of the curvature binormal
  with respect to the stencil's three nodes (the target held fixed). Returning spring: ``ka I``.
- ``C`` [N s/m]: ``alpha M`` plus ``kd n n^T`` along every spring and ``kd_anchor I``: the exact
  velocity Jacobian of the damping forces (``kd = beta ke``).
- ``u`` [m] and ``g`` [m/s]: the displacement predicted from the current velocity (``h v``) and
  the prescribed velocity change; both are zero at free nodes except ``u = h v``. Pinned nodes are
  prescribed: their rows are replaced by the identity, their known motion to the interpolated pin
  target enters the right-hand side of their free neighbours through ``-K u - C g``.

Per tube the matrix is symmetric positive definite and block-banded: 3x3 blocks with bandwidth 2
(a bending stencil couples nodes ``j - 1`` and ``j + 1``). It is factored by a banded block
``L D L^T`` (no fill outside the band) and solved sequentially along the tube, in float64: with a
stiff tube and a 1/60 s step ``h^2 K`` exceeds ``M`` by up to ~1e8, past what float32 resolves.
"""

from __future__ import annotations

import functools

import warp as wp

from .integrate import ControlArrays, Features, ModelArrays, StateArrays
from .springs import curvature_targets, frame_forces

EPS64 = wp.constant(wp.float64(1.0e-12))


@wp.struct
class ImplicitScratch:
    """Per-substep scratch of the implicit kernel, all shaped (world_count, node_count).

    Attributes:
        node_kappa_target: curvature targets of curved rest shapes [1], vec3.
        node_f_frame: force of the targets' dependence on the shape [N], vec3.
        node_x0, node_v0: positions [m] and velocities [m/s] at the substep's start, vec3d.
        node_w: the Newton iterate's end-of-step velocity ``w`` [m/s], vec3d.
        node_r: ``h f - M (w - v0)`` [N s], then the solution ``dv`` [m/s], vec3d.
        mat_d: diagonal blocks ``A_ii`` [kg], then the factor's ``D_i``, mat33d.
        mat_dinv: ``D_i^-1`` [1/kg], mat33d.
        mat_l1: ``A_{i+1,i}`` [kg], then the factor's ``L_{i+1,i}`` [1], mat33d.
        mat_l2: ``A_{i+2,i}`` [kg], then the factor's ``L_{i+2,i}`` [1], mat33d.
    """

    node_kappa_target: wp.array2d[wp.vec3]
    node_f_frame: wp.array2d[wp.vec3]
    node_x0: wp.array2d[wp.vec3d]
    node_v0: wp.array2d[wp.vec3d]
    node_w: wp.array2d[wp.vec3d]
    node_r: wp.array2d[wp.vec3d]
    mat_d: wp.array2d[wp.mat33d]
    mat_dinv: wp.array2d[wp.mat33d]
    mat_l1: wp.array2d[wp.mat33d]
    mat_l2: wp.array2d[wp.mat33d]


@wp.func
def position64(node_q: wp.array2d[wp.vec3], node_q_lo: wp.array2d[wp.vec3], w: int, i: int) -> wp.vec3d:
    """Compensated position ``node_q + node_q_lo`` of node ``i`` [m], in float64."""
    return wp.vec3d(node_q[w, i]) + wp.vec3d(node_q_lo[w, i])


@wp.func
def spring_stiffness(d: wp.vec3d, rest_length: float, ke: float) -> wp.mat33d:
    """Stiffness block [N/m] of a spring with end difference ``d`` [m]: the Hessian of
    ``ke/2 (|d| - L)^2``, ``ke (n n^T + (1 - L/|d|) (I - n n^T))``, with the transverse factor
    clamped at 0 (a compressed spring would otherwise give a negative eigenvalue)."""
    length = wp.length(d)
    nn = wp.outer(d, d) / (length * length)
    t = wp.max(wp.float64(1.0) - wp.float64(rest_length) / length, wp.float64(0.0))
    return (nn + (wp.identity(n=3, dtype=wp.float64) - nn) * t) * wp.float64(ke)


@wp.func
def bend_jacobians(a: wp.vec3d, b: wp.vec3d):
    """Curvature binormal ``kb = 2 a x b / D`` (``D = |a||b| + a.b``) of edges ``a``, ``b`` [m] and
    its Jacobians ``dkb/da``, ``dkb/db`` [1/m]; returns ``(kb, Ja, Jb)``.

    ``Ja = -(2 [b]x + kb (|b|/|a| a + b)^T) / D``, ``Jb = (2 [a]x - kb (|a|/|b| b + a)^T) / D``;
    the same floor on ``D`` as :func:`warp_tube.kernels.springs.curvature_binormal`.
    """
    la = wp.length(a)
    lb = wp.length(b)
    den = wp.max(la * lb + wp.dot(a, b), wp.float64(1.0e-6) * la * lb + EPS64)
    inv = wp.float64(1.0) / den
    two = wp.float64(2.0)
    kb = wp.cross(a, b) * (two * inv)
    ja = (wp.skew(b) * (-two) - wp.outer(kb, a * (lb / wp.max(la, EPS64)) + b)) * inv
    jb = (wp.skew(a) * two - wp.outer(kb, b * (la / wp.max(lb, EPS64)) + a)) * inv
    return kb, ja, jb


@wp.func
def factor_solve(w: int, start: int, end: int, s: ImplicitScratch):
    """Solve the tube's banded system in place: ``s.node_r`` becomes ``A^-1 s.node_r``.

    Block ``L D L^T`` with unit lower ``L`` of bandwidth 2::

        D_i       = A_ii - L_{i,i-1} D_{i-1} L_{i,i-1}^T - L_{i,i-2} D_{i-2} L_{i,i-2}^T
        L_{i+1,i} = (A_{i+1,i} - L_{i+1,i-1} D_{i-1} L_{i,i-1}^T) D_i^-1
        L_{i+2,i} = A_{i+2,i} D_i^-1

    then forward substitution, ``D^-1``, back substitution.

    Each ``D_i`` is stored symmetrised. In floating point ``L D L^T`` is symmetric only to
    round-off, and this recurrence, which reads the lower band only, does not damp the skew part
    of ``D``: it grows by about 1.5x a node (measured with bending, 0.01 m segments, 1/240 s).
    Seeded at 1e-30 by a straight tube's round-off, it reaches O(1) after ~150 nodes and the
    solve is wrong for the rest of the tube (a free-falling rod's tail fell at a tenth of g).
    With ``D_i`` kept exactly symmetric, ``L D L^T`` is exactly symmetric and its difference from
    ``A`` is a sum of per-block round-off that does not accumulate along the tube.
    """
    half = wp.float64(0.5)
    for i in range(start, end):
        d = s.mat_d[w, i]
        if i - 1 >= start:
            l = s.mat_l1[w, i - 1]
            d = d - l * s.mat_d[w, i - 1] * wp.transpose(l)
        if i - 2 >= start:
            l = s.mat_l2[w, i - 2]
            d = d - l * s.mat_d[w, i - 2] * wp.transpose(l)
        d = (d + wp.transpose(d)) * half
        s.mat_d[w, i] = d
        dinv = wp.inverse(d)
        s.mat_dinv[w, i] = dinv
        if i + 1 < end:
            a1 = s.mat_l1[w, i]
            if i - 1 >= start:
                a1 = a1 - s.mat_l2[w, i - 1] * s.mat_d[w, i - 1] * wp.transpose(s.mat_l1[w, i - 1])
            s.mat_l1[w, i] = a1 * dinv
        if i + 2 < end:
            s.mat_l2[w, i] = s.mat_l2[w, i] * dinv
    for i in range(start, end):
        y = s.node_r[w, i]
        if i - 1 >= start:
            y = y - s.mat_l1[w, i - 1] * s.node_r[w, i - 1]
        if i - 2 >= start:
            y = y - s.mat_l2[w, i - 2] * s.node_r[w, i - 2]
        s.node_r[w, i] = y
    for k in range(end - start):
        i = end - 1 - k
        x = s.mat_dinv[w, i] * s.node_r[w, i]
        if i + 1 < end:
            x = x - wp.transpose(s.mat_l1[w, i]) * s.node_r[w, i + 1]
        if i + 2 < end:
            x = x - wp.transpose(s.mat_l2[w, i]) * s.node_r[w, i + 2]
        s.node_r[w, i] = x


@functools.cache
def make_implicit_kernel(features: Features):
    """The implicit substep kernel specialised to ``features`` (cached: one compile per combination).

    The assistant line is not handled here (callers use the semi-implicit solver for it).
    """
    features = Features(*(bool(v) for v in features))
    BENDING = features.bending
    CURVED = features.curved
    ANCHORS = features.anchors
    GRAVITY = features.gravity
    MASS_DAMPING = features.mass_damping
    SPRING_DAMPING = features.spring_damping
    EXTERNAL = features.external

    @wp.func
    def set_iterate(
        w: int,
        pw: int,
        start: int,
        end: int,
        h: wp.float64,
        step: wp.float64,
        model: ModelArrays,
        scratch: ImplicitScratch,
        q: wp.array2d[wp.vec3],
        q_lo: wp.array2d[wp.vec3],
        qd: wp.array2d[wp.vec3],
    ):
        """Free nodes: ``w + step dv`` (``dv`` in ``scratch.node_r``) into ``qd``, and the consistent
        position ``x0 + h (w + step dv)`` into ``q + q_lo`` (compensated: ``q`` is its float32
        rounding, ``q_lo`` the rest)."""
        for i in range(start, end):
            if model.node_inv_mass[pw, i] > 0.0:
                v_new = scratch.node_w[w, i] + scratch.node_r[w, i] * step
                x_new = scratch.node_x0[w, i] + v_new * h
                hi = wp.vec3(x_new)
                q[w, i] = hi
                q_lo[w, i] = wp.vec3(x_new - wp.vec3d(hi))
                qd[w, i] = wp.vec3(v_new)

    @wp.func
    def merit(
        w: int,
        pw: int,
        start: int,
        end: int,
        h: wp.float64,
        model: ModelArrays,
        control: ControlArrays,
        scratch: ImplicitScratch,
        q: wp.array2d[wp.vec3],
        q_lo: wp.array2d[wp.vec3],
    ) -> wp.float64:
        """Incremental potential [J] of the end-of-step positions ``y`` in ``q + q_lo``::

            G(y) = sum m/(2 h^2) |y - x0 - h v0|^2 + E(y) - (m g + f_ext) . y + D(y)

        whose stationary point is the backward Euler step (``E``: spring, bending and returning
        energy; ``D``: damping as a dissipation potential, ``alpha m / (2h) |y - x0|^2`` and
        ``kd / (2h) ((d - d0) . n)^2`` along springs with ``n`` taken at ``y``). Pinned nodes'
        terms are constant and left out. Used by the line search only.
        """
        g = wp.float64(0.0)
        half = wp.float64(0.5)
        if wp.static(CURVED):
            curvature_targets(w, pw, start, end, q, model.node_rest_q, model.node_kappa_rest, scratch.node_kappa_target)
        for i in range(start, end):
            if model.node_inv_mass[pw, i] == 0.0:
                continue
            m = wp.float64(model.node_mass[pw, i])
            y = position64(q, q_lo, w, i)
            dy = y - scratch.node_x0[w, i]
            g += half * m * wp.length_sq(dy - scratch.node_v0[w, i] * h) / (h * h)
            if wp.static(MASS_DAMPING):
                g += half * wp.float64(model.node_damping[pw, i]) * m * wp.length_sq(dy) / h
            if wp.static(ANCHORS):
                ka = wp.float64(model.node_anchor_k[pw, i])
                if ka > wp.float64(0.0):
                    g += half * ka * wp.length_sq(y - wp.vec3d(model.node_rest_q[pw, i]))
                    g += half * wp.float64(model.node_anchor_kd[pw, i]) * wp.length_sq(dy) / h
            if wp.static(GRAVITY):
                g -= m * wp.dot(wp.vec3d(model.gravity), y)
            if wp.static(EXTERNAL):
                g -= wp.dot(wp.vec3d(control.node_f_ext[w, i]), y)
        for i in range(start, end - 1):
            d = position64(q, q_lo, w, i + 1) - position64(q, q_lo, w, i)
            length = wp.length(d)
            stretch = length - wp.float64(model.seg_rest_length[pw, i])
            g += half * wp.float64(model.seg_ke[pw, i]) * stretch * stretch
            if wp.static(SPRING_DAMPING):
                if length > EPS64:
                    dd = wp.dot(d - (scratch.node_x0[w, i + 1] - scratch.node_x0[w, i]), d / length)
                    g += half * wp.float64(model.seg_kd[pw, i]) * dd * dd / h
        if wp.static(BENDING):
            for j in range(start + 1, end - 1):
                kbend = wp.float64(model.node_bend_k[pw, j])
                if kbend == wp.float64(0.0):
                    continue
                xa = position64(q, q_lo, w, j - 1)
                xb = position64(q, q_lo, w, j)
                xc = position64(q, q_lo, w, j + 1)
                kb, ja, jb = bend_jacobians(xb - xa, xc - xb)
                if wp.static(CURVED):
                    kb = kb - wp.vec3d(scratch.node_kappa_target[w, j])
                g += half * kbend * wp.length_sq(kb)
        return g

    @wp.func
    def newton_iteration(
        w: int,
        pw: int,
        start: int,
        end: int,
        h: wp.float64,
        model: ModelArrays,
        control: ControlArrays,
        scratch: ImplicitScratch,
        q: wp.array2d[wp.vec3],
        q_lo: wp.array2d[wp.vec3],
        qd: wp.array2d[wp.vec3],
        first: bool,
    ) -> wp.float64:
        """One Newton iteration of the substep, with a backtracking line search.

        The iterate is the end-of-step guess ``(y, w)``, ``y = x0 + h w``, held in ``q + q_lo``
        and ``qd`` (and ``w`` in float64 in ``scratch.node_w``); pinned nodes already sit at their
        targets. The first iteration starts from ``y = x0``, ``w = 0``, where it is exactly the
        linearised backward Euler step ``(M + h C + h^2 K) dv = h (f(x0, v0) - h K v0)`` written
        for ``v' = w + dv``. It solves ``(M + h C + h^2 K) dv = h f(y, w) - M (w - v0)``, then
        halves the step ``s`` from 1 until the incremental potential :func:`merit` does not
        increase (at most 8 halvings; see below), and sets ``w += s dv``. Returns ``max |h s dv|`` [m].
        """
        h2 = h * h
        zero3 = wp.vec3d(wp.float64(0.0))
        zero33 = wp.mat33d(wp.float64(0.0))
        eye = wp.identity(n=3, dtype=wp.float64)
        g0 = merit(w, pw, start, end, h, model, control, scratch, q, q_lo)  # also the curvature targets
        # Per node: inertia, point forces and the diagonal mass terms.
        for i in range(start, end):
            scratch.mat_l1[w, i] = zero33
            scratch.mat_l2[w, i] = zero33
            if model.node_inv_mass[pw, i] == 0.0:
                scratch.node_r[w, i] = zero3
                scratch.mat_d[w, i] = eye
                continue
            x = position64(q, q_lo, w, i)
            v = scratch.node_w[w, i]
            m = wp.float64(model.node_mass[pw, i])
            # r collects f - M (w - v0) / h (times h below).
            f = (scratch.node_v0[w, i] - v) * (m / h)
            a = eye * m
            if wp.static(MASS_DAMPING):
                alpha = wp.float64(model.node_damping[pw, i])
                f = f - v * (alpha * m)
                a = a + eye * (h * alpha * m)
            if wp.static(ANCHORS):
                ka = wp.float64(model.node_anchor_k[pw, i])
                if ka > wp.float64(0.0):
                    kda = wp.float64(model.node_anchor_kd[pw, i])
                    f = f - (x - wp.vec3d(model.node_rest_q[pw, i])) * ka - v * kda
                    a = a + eye * (h2 * ka + h * kda)
            if wp.static(GRAVITY):
                f = f + wp.vec3d(model.gravity) * m
            if wp.static(EXTERNAL):
                f = f + wp.vec3d(control.node_f_ext[w, i])
            scratch.node_r[w, i] = f
            scratch.mat_d[w, i] = a
        # Structural springs, each once: force on both ends and the blocks.
        for i in range(start, end - 1):
            d = position64(q, q_lo, w, i + 1) - position64(q, q_lo, w, i)
            length = wp.length(d)
            if length < EPS64:
                continue
            n = d / length
            ke = model.seg_ke[pw, i]
            fs = n * (wp.float64(ke) * (length - wp.float64(model.seg_rest_length[pw, i])))
            blk = spring_stiffness(d, model.seg_rest_length[pw, i], ke) * h2
            if wp.static(SPRING_DAMPING):
                c = wp.outer(n, n) * wp.float64(model.seg_kd[pw, i])
                fs = fs + c * (wp.vec3d(qd[w, i + 1]) - wp.vec3d(qd[w, i]))
                blk = blk + c * h
            free_a = model.node_inv_mass[pw, i] > 0.0
            free_b = model.node_inv_mass[pw, i + 1] > 0.0
            if free_a:
                scratch.node_r[w, i] = scratch.node_r[w, i] + fs
                scratch.mat_d[w, i] = scratch.mat_d[w, i] + blk
            if free_b:
                scratch.node_r[w, i + 1] = scratch.node_r[w, i + 1] - fs
                scratch.mat_d[w, i + 1] = scratch.mat_d[w, i + 1] + blk
            if free_a and free_b:
                scratch.mat_l1[w, i] = scratch.mat_l1[w, i] - blk
        if wp.static(BENDING):
            # Bending stencils: force -J_m^T k (kb - target), Gauss-Newton blocks k J_m^T J_n.
            for j in range(start + 1, end - 1):
                kbend = wp.float64(model.node_bend_k[pw, j])
                if kbend == wp.float64(0.0):
                    continue
                xa = position64(q, q_lo, w, j - 1)
                xb = position64(q, q_lo, w, j)
                xc = position64(q, q_lo, w, j + 1)
                kb, ja, jb = bend_jacobians(xb - xa, xc - xb)
                if wp.static(CURVED):
                    kb = kb - wp.vec3d(scratch.node_kappa_target[w, j])
                j0 = -ja
                j1 = ja - jb
                j2 = jb
                sv = kb * kbend
                hk = h2 * kbend
                f0 = model.node_inv_mass[pw, j - 1] > 0.0
                f1 = model.node_inv_mass[pw, j] > 0.0
                f2 = model.node_inv_mass[pw, j + 1] > 0.0
                if f0:
                    scratch.node_r[w, j - 1] = scratch.node_r[w, j - 1] - wp.transpose(j0) * sv
                    scratch.mat_d[w, j - 1] = scratch.mat_d[w, j - 1] + wp.transpose(j0) * j0 * hk
                if f1:
                    scratch.node_r[w, j] = scratch.node_r[w, j] - wp.transpose(j1) * sv
                    scratch.mat_d[w, j] = scratch.mat_d[w, j] + wp.transpose(j1) * j1 * hk
                if f2:
                    scratch.node_r[w, j + 1] = scratch.node_r[w, j + 1] - wp.transpose(j2) * sv
                    scratch.mat_d[w, j + 1] = scratch.mat_d[w, j + 1] + wp.transpose(j2) * j2 * hk
                if f0 and f1:
                    scratch.mat_l1[w, j - 1] = scratch.mat_l1[w, j - 1] + wp.transpose(j1) * j0 * hk
                if f1 and f2:
                    scratch.mat_l1[w, j] = scratch.mat_l1[w, j] + wp.transpose(j2) * j1 * hk
                if f0 and f2:
                    scratch.mat_l2[w, j - 1] = scratch.mat_l2[w, j - 1] + wp.transpose(j2) * j0 * hk
        if wp.static(CURVED):
            # The targets move with the shape: their exact force (see springs.frame_forces).
            for i in range(start, end):
                scratch.node_f_frame[w, i] = wp.vec3(0.0)
            frame_forces(w, pw, start, end, q, q_lo, model.node_rest_q, model.node_bend_k, scratch.node_kappa_target, scratch.node_f_frame)
            for i in range(start, end):
                if model.node_inv_mass[pw, i] > 0.0:
                    scratch.node_r[w, i] = scratch.node_r[w, i] + wp.vec3d(scratch.node_f_frame[w, i])
        for i in range(start, end):
            scratch.node_r[w, i] = scratch.node_r[w, i] * h
        factor_solve(w, start, end, scratch)
        step = wp.float64(1.0)
        for k in range(9):
            set_iterate(w, pw, start, end, h, step, model, scratch, q, q_lo, qd)
            # Accept within round-off (1e-9 relative, float64 sums of float32-stored positions):
            # near equilibrium the change of G is below it and a strict test would creep.
            if merit(w, pw, start, end, h, model, control, scratch, q, q_lo) <= g0 + wp.float64(1.0e-9) * wp.abs(g0):
                break
            step = step * wp.float64(0.5)
            if k == 8:
                # No decrease along dv (round-off level): the first iteration keeps its shortest
                # step (dv is a descent direction there), a later one keeps the previous iterate.
                if not first:
                    step = wp.float64(0.0)
                    set_iterate(w, pw, start, end, h, step, model, scratch, q, q_lo, qd)
                else:
                    step = step * wp.float64(2.0)
        moved = wp.float64(0.0)
        for i in range(start, end):
            if model.node_inv_mass[pw, i] > 0.0:
                dv = scratch.node_r[w, i] * step
                scratch.node_w[w, i] = scratch.node_w[w, i] + dv
                moved = wp.max(moved, wp.length(dv) * h)
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
        early once an iteration moves no node by more than ``tolerance`` [m]. Thread (world,
        tube). Model arrays (1 or world_count, node_count) are read at row ``w % rows``; state,
        control and scratch arrays are (world_count, node_count). Pins move linearly from
        ``control.pin_q_start`` to ``control.pin_q_end`` over the call.
        """
        w, t = wp.tid()
        pw = w % model.node_mass.shape[0]
        start = model.tube_node_start[t]
        end = model.tube_node_start[t + 1]
        h = wp.float64(dt)
        q = state_out.node_q
        q_lo = state_out.node_q_lo
        qd = state_out.node_qd
        for i in range(start, end):
            q[w, i] = state_in.node_q[w, i]
            q_lo[w, i] = state_in.node_q_lo[w, i]
            qd[w, i] = state_in.node_qd[w, i]
        for step in range(substep_count):
            frac = float(step + 1) / float(substep_count)
            # Start of the substep: x0, v0; the first iterate y = x0, w = 0, pins at their targets.
            for i in range(start, end):
                x0 = position64(q, q_lo, w, i)
                scratch.node_x0[w, i] = x0
                scratch.node_v0[w, i] = wp.vec3d(qd[w, i])
                scratch.node_w[w, i] = wp.vec3d(wp.float64(0.0))
                if model.node_inv_mass[pw, i] == 0.0:
                    x_pin = wp.lerp(control.pin_q_start[w, i], control.pin_q_end[w, i], frac)
                    qd[w, i] = wp.vec3((wp.vec3d(x_pin) - x0) / h)
                    q[w, i] = x_pin
                    q_lo[w, i] = wp.vec3(0.0)
                else:
                    qd[w, i] = wp.vec3(0.0)
            for it in range(iterations):
                moved = newton_iteration(w, pw, start, end, h, model, control, scratch, q, q_lo, qd, it == 0)
                if moved <= wp.float64(tolerance):
                    break

    return implicit_substeps
