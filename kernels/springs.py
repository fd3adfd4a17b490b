"""Forces of the deformable centerline, as `wp.func`s that gather onto one node.

Every force a node feels is computed from its own neighbourhood (two nodes either side), so a
node's force is one function call and no atomics are needed: the per-tube substep kernel and the
per-node kernel of :mod:`warp_tube.kernels.integrate` share these functions.

Array conventions (see ``warp_tube.model.tube.TubeModel``): nodes of all tubes of one world are
concatenated; state arrays are (world_count, node_count); parameter arrays are
(1 or world_count, node_count) and read at row ``pw = w % rows``. Segment ``i`` joins node ``i``
to node ``i + 1`` of the same tube. Units: m, kg, s, N.
"""

import warp as wp

from .frames import rotate_minimal

EPS = wp.constant(1.0e-12)


@wp.func
def spring_force(d: wp.vec3, dv: wp.vec3, rest_length: float, ke: float, kd: float) -> wp.vec3:
    """Force on end ``a`` of a spring from ``a`` to ``b`` [N], given ``d = xb - xa`` [m] and
    ``dv = vb - va`` [m/s].

    Hookean along the spring, ``ke * (|d| - L)``, plus damping along it, ``kd * dv . d_hat``. A
    zero-length spring exerts no force (no direction to push along).
    """
    length = wp.length(d)
    if length < EPS:
        return wp.vec3(0.0)
    n = d / length
    return n * (ke * (length - rest_length) + kd * wp.dot(dv, n))


@wp.func
def node_delta(node_q: wp.array2d[wp.vec3], node_q_lo: wp.array2d[wp.vec3], w: int, i: int, j: int) -> wp.vec3:
    """``x_j - x_i`` [m] from the compensated positions ``node_q + node_q_lo``.

    The float32 difference of nearby positions is exact, so adding the difference of the
    low-order parts recovers the segment to well below the positions' own rounding (which times a
    stiff spring would be force noise that heats a long undamped run).
    """
    return (node_q[w, j] - node_q[w, i]) + (node_q_lo[w, j] - node_q_lo[w, i])


@wp.func
def al_delta(
    al_q: wp.array2d[wp.vec3],
    al_q_lo: wp.array2d[wp.vec3],
    w: int,
    p: int,
    node_q: wp.array2d[wp.vec3],
    node_q_lo: wp.array2d[wp.vec3],
    i: int,
) -> wp.vec3:
    """Assistant-line point ``p`` minus centerline node ``i`` [m], from compensated positions
    (see :func:`node_delta`)."""
    return (al_q[w, p] - node_q[w, i]) + (al_q_lo[w, p] - node_q_lo[w, i])


@wp.func
def curvature_binormal(a: wp.vec3, b: wp.vec3) -> wp.vec3:
    """Discrete curvature binormal ``2 a x b / (|a||b| + a.b)`` of edges ``a``, ``b`` [1].

    Its length is ``2 tan(phi / 2)`` for the turning angle ``phi`` between the edges.
    """
    la = wp.length(a)
    lb = wp.length(b)
    den = wp.max(la * lb + wp.dot(a, b), 1.0e-6 * la * lb + EPS)
    return wp.cross(a, b) * (2.0 / den)


@wp.func
def bend_gradients(a: wp.vec3, b: wp.vec3, kb_target: wp.vec3, k: float):
    """Bending forces of edges ``a``, ``b`` for energy ``k/2 |kb - kb_target|^2``.

    With ``kb = 2 a x b / D``, ``D = |a||b| + a.b`` and ``g = k (kb - kb_target)`` returns
    ``ga = (dkb/da)^T g`` and ``gb = (dkb/db)^T g``; the stencil nodes (prev, mid, next) get
    ``(+ga, gb - ga, -gb)``.
    """
    la = wp.length(a)
    lb = wp.length(b)
    den = wp.max(la * lb + wp.dot(a, b), 1.0e-6 * la * lb + EPS)
    inv = 1.0 / den
    kb = wp.cross(a, b) * (2.0 * inv)
    g = (kb - kb_target) * k
    kg = wp.dot(kb, g)
    ga = (2.0 * wp.cross(b, g) - kg * (a * (lb / wp.max(la, EPS)) + b)) * inv
    gb = (-2.0 * wp.cross(a, g) - kg * (b * (la / wp.max(lb, EPS)) + a)) * inv
    return ga, gb


@wp.func
def curvature_targets(
    w: int,
    pw: int,
    start: int,
    end: int,
    node_q: wp.array2d[wp.vec3],
    node_rest_q: wp.array2d[wp.vec3],
    node_kappa_rest: wp.array2d[wp.vec3],
    node_kappa_target_out: wp.array2d[wp.vec3],
):
    """Rest curvature of each interior node of one tube, carried into the current shape.

    The rest curvature binormal of node ``j`` is stored in the rest twist-free (Bishop) frame of
    edge ``j - 1`` as ``node_kappa_rest`` = (along tangent, along u, along v). The current Bishop
    frame is carried from the first edge (least rotation of its rest direction onto its current
    one) edge to edge by least rotations, and the target is rebuilt in it. A straight rest tube has
    zero targets and never calls this. The targets depend on the shape: :func:`frame_forces` adds
    the forces of that dependence.
    """
    t_rest = wp.normalize(node_rest_q[pw, start + 1] - node_rest_q[pw, start])
    t = wp.normalize(node_q[w, start + 1] - node_q[w, start])
    # Rest frame of the first edge: any fixed perpendicular pair; the stored coordinates use the
    # same construction (warp_tube.model.tube), so only consistency matters.
    u_rest = wp.vec3(1.0, 0.0, 0.0)
    if wp.abs(t_rest[0]) > 0.6:
        u_rest = wp.vec3(0.0, 1.0, 0.0)
    u_rest = wp.normalize(u_rest - t_rest * wp.dot(u_rest, t_rest))
    u = rotate_minimal(t_rest, t, u_rest)
    node_kappa_target_out[w, start] = wp.vec3(0.0)
    node_kappa_target_out[w, end - 1] = wp.vec3(0.0)
    for j in range(start + 1, end - 1):
        c = node_kappa_rest[pw, j]
        v = wp.cross(t, u)
        node_kappa_target_out[w, j] = t * c[0] + u * c[1] + v * c[2]
        t_next = wp.normalize(node_q[w, j + 1] - node_q[w, j])
        u = rotate_minimal(t, t_next, u)
        u = wp.normalize(u - t_next * wp.dot(u, t_next))
        t = t_next


@wp.func
def frame_forces(
    w: int,
    pw: int,
    start: int,
    end: int,
    node_q: wp.array2d[wp.vec3],
    node_q_lo: wp.array2d[wp.vec3],
    node_rest_q: wp.array2d[wp.vec3],
    node_bend_k: wp.array2d[float],
    node_kappa_target: wp.array2d[wp.vec3],
    node_f_out: wp.array2d[wp.vec3],
):
    """Add to ``node_f_out`` [N] the forces from the targets' dependence on the shape.

    The target ``T_j`` of the stencil at ``j`` lives in the Bishop frame of edge ``j - 1``, which
    moves with the shape: by the angular velocity ``t x dt + dpsi t``. With ``g_j = k_j (kb_j - T_j)``
    and ``h_j = T_j x g_j`` the energy changes by ``(t x h_j) . de_{j-1} / |e_{j-1}|`` (the frame
    following its edge) and by ``mu_j dpsi_{j-1}``, ``mu_j = -t_{j-1} . h_j`` (its twist). The
    twist of a Bishop frame accumulates along the tube: each transport at node ``k`` adds
    ``-kb_k / 2 . (de_{k-1} / |e_{k-1}| + de_k / |e_k|)`` (discrete parallel-transport holonomy), and
    the first frame ``-kb_0 / 2 . de_0 / |e_0|`` with ``kb_0`` the binormal from its rest to its
    current direction. So each transport is weighted by the suffix sum ``M_k = sum_{j > k} mu_j``,
    one backward pass. With these terms the bending force is the exact gradient of the energy.
    """
    m_sum = float(0.0)
    for jj in range(end - start - 2):
        j = end - 2 - jj
        a = node_delta(node_q, node_q_lo, w, j - 1, j)
        b = node_delta(node_q, node_q_lo, w, j, j + 1)
        la = wp.length(a)
        lb = wp.length(b)
        ta = a / la
        kb = curvature_binormal(a, b)
        tgt = node_kappa_target[w, j]
        h = wp.cross(tgt, (kb - tgt) * node_bend_k[pw, j])
        # The frame of edge j-1 follows its edge: dE/de_{j-1} = (t x h) / |e_{j-1}|.
        grad = wp.cross(ta, h) / la
        # The transport at node j (edges j-1 -> j) twists every later frame: weight M_j.
        tw = kb * (-0.5 * m_sum)
        grad_a = grad + tw / la
        grad_b = tw / lb
        # Edge e_i = x_{i+1} - x_i: dE/dx_{i+1} = G, dE/dx_i = -G; force = -gradient.
        node_f_out[w, j] = node_f_out[w, j] - grad_a + grad_b
        node_f_out[w, j - 1] = node_f_out[w, j - 1] + grad_a
        node_f_out[w, j + 1] = node_f_out[w, j + 1] - grad_b
        m_sum += -wp.dot(ta, h)
    # The first frame: least rotation from the first edge's rest direction.
    e0 = node_delta(node_q, node_q_lo, w, start, start + 1)
    l0 = wp.length(e0)
    t_rest = wp.normalize(node_rest_q[pw, start + 1] - node_rest_q[pw, start])
    kb0 = curvature_binormal(t_rest, e0)
    g0 = kb0 * (-0.5 * m_sum / l0)
    node_f_out[w, start + 1] = node_f_out[w, start + 1] - g0
    node_f_out[w, start] = node_f_out[w, start] + g0
