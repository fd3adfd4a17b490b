"""Bending and the curved rest shape's frames: the bending term of the centerline, defined once.

The bending stencil's force, energy and Gauss-Newton blocks (:func:`bend_gradients`, its unit form
:func:`bend_gradients_unit` that the on-chip kernel calls with tangents it has at hand,
:func:`bend_energy`, :func:`bend_jacobians`), and for curved rest shapes the target in the
Bishop frame and the forces of its dependence on the shape (:func:`kappa_target`,
:func:`holonomy_stencil`, :func:`twist_gradients`, :func:`first_frame_gradient`, with their
sequential forms over a tube, :func:`curvature_targets` and :func:`frame_forces`). The other
terms are in :mod:`.springs`, whose conventions (precision, arrays, units) these follow.
"""

import warp as wp

from .frames import carry_normal, rotate_minimal, twist_terms, twisted
from .springs import EPS, Vec, node_delta


# -- bending --------------------------------------------------------------------------------------


@wp.func(inline=True)
def curvature_binormal_terms(a: Vec, b: Vec):
    """Curvature binormal ``kb = 2 a x b / D`` of edges ``a``, ``b`` [m], ``D = |a||b| + a.b``
    floored at ``1e-6 |a||b| + EPS`` so that a fold stays finite; its length is ``2 tan(phi / 2)``
    for the turning angle ``phi``. Returns ``(kb, 1/D, |a|, |b|)``. (:func:`curvature_binormal_unit`
    is the same from unit tangents; this form's divisions do not wait on one another, which the
    CPU's per-tube loop runs faster.)"""
    la = wp.length(a)
    lb = wp.length(b)
    den = wp.max(la * lb + wp.dot(a, b), type(la)(1.0e-6) * la * lb + type(la)(EPS))
    inv = type(la)(1.0) / den
    return wp.cross(a, b) * (type(la)(2.0) * inv), inv, la, lb


@wp.func(inline=True)
def edge_tangent(d: Vec):
    """Unit tangent of edge ``d`` [m] and its reciprocal length [1/m], the length floored at
    ``EPS`` (a zero edge: a zero tangent)."""
    length = wp.length(d)
    inv = type(length)(1.0) / wp.max(length, type(length)(EPS))
    return d * inv, inv


@wp.func(inline=True)
def curvature_binormal_unit(ta: Vec, tb: Vec, ila: wp.Float, ilb: wp.Float):
    """Curvature binormal ``kb = 2 a x b / D`` [1] of edges ``a``, ``b`` given by their unit
    tangents ``ta``, ``tb`` and reciprocal lengths ``ila``, ``ilb`` [1/m] (:func:`edge_tangent`),
    ``D = |a||b| + a . b`` floored at ``1e-6 |a||b| + EPS`` so that a fold stays finite: with the
    lengths taken out, ``kb = 2 ta x tb q``, ``q = 1 / max(1 + ta . tb, 1e-6 + EPS / (|a||b|))``.
    Its length is ``2 tan(phi / 2)`` for the turning angle ``phi``. Returns ``(kb, q)``."""
    c = wp.dot(ta, tb)
    q = type(c)(1.0) / wp.max(type(c)(1.0) + c, type(c)(1.0e-6) + type(c)(EPS) * ila * ilb)
    return wp.cross(ta, tb) * (type(c)(2.0) * q), q


@wp.func(inline=True)
def curvature_binormal(a: Vec, b: Vec):
    """Discrete curvature binormal of edges ``a``, ``b`` [m] (:func:`curvature_binormal_terms`; the
    same as :func:`curvature_binormal_unit`)."""
    kb, inv, la, lb = curvature_binormal_terms(a, b)
    return kb


@wp.func(inline=True)
def bend_gradients_unit(ta: Vec, tb: Vec, ila: wp.Float, ilb: wp.Float, kb: Vec, q: wp.Float, kb_target: Vec, k: wp.Float):
    """:func:`bend_gradients` from the edges' unit tangents ``ta``, ``tb`` and reciprocal lengths
    ``ila``, ``ilb`` [1/m] (:func:`edge_tangent`) and their :func:`curvature_binormal_unit`
    ``(kb, q)``: with ``D = |a||b| (1 + ta . tb)``, ``ga = (2 tb x g - (ta + tb) kb . g) q / |a|``
    and ``gb = -(2 ta x g + (ta + tb) kb . g) q / |b|``."""
    g = (kb - kb_target) * k
    s = (ta + tb) * wp.dot(kb, g)
    two = type(k)(2.0)
    ga = (wp.cross(tb, g) * two - s) * (q * ila)
    gb = (wp.cross(ta, g) * (-two) - s) * (q * ilb)
    return ga, gb


@wp.func(inline=True)
def bend_gradients(a: Vec, b: Vec, kb_target: Vec, k: wp.Float):
    """Bending forces of edges ``a``, ``b`` [m] for energy ``k/2 |kb - kb_target|^2``.

    With ``g = k (kb - kb_target)`` returns ``ga = (dkb/da)^T g``, ``gb = (dkb/db)^T g`` and
    ``kb``; the stencil nodes (prev, mid, next) get ``(+ga, gb - ga, -gb)``. The per-tube kernel's
    form; :func:`bend_gradients_unit` is the same from unit tangents, which the on-chip kernel has
    at hand (``tests/test_forces.py`` checks both against the energy's gradient).
    """
    kb, inv, wa, wb = bend_geometry(a, b)
    g = (kb - kb_target) * k
    kg = wp.dot(kb, g)
    two = type(k)(2.0)
    ga = (wp.cross(b, g) * two - wa * kg) * inv
    gb = (wp.cross(a, g) * (-two) - wb * kg) * inv
    return ga, gb, kb


@wp.func(inline=True)
def bend_geometry(a: Vec, b: Vec):
    """The curvature binormal of edges ``a``, ``b`` [m] and what its derivatives are made of:
    returns ``(kb, 1/D, wa, wb)`` with ``D`` of :func:`curvature_binormal_terms`,
    ``wa = |b|/|a| a + b`` and ``wb = |a|/|b| b + a``, so that
    ``dkb/da = -(2 [b]x + kb wa^T) / D`` and ``dkb/db = (2 [a]x - kb wb^T) / D``."""
    kb, inv, la, lb = curvature_binormal_terms(a, b)
    eps = type(la)(EPS)
    return kb, inv, a * (lb / wp.max(la, eps)) + b, b * (la / wp.max(lb, eps)) + a


@wp.func(inline=True)
def bend_jacobians(a: Vec, b: Vec):
    """``(kb, dkb/da, dkb/db)`` of edges ``a``, ``b`` [m] (:func:`bend_geometry`): the
    Gauss-Newton stiffness of a stencil is ``k J_m^T J_n`` for nodes m, n with ``J`` =
    ``(-Ja, Ja - Jb, Jb)`` on (prev, mid, next)."""
    kb, inv, wa, wb = bend_geometry(a, b)
    two = type(inv)(2.0)
    ja = (wp.skew(b) * (-two) - wp.outer(kb, wa)) * inv
    jb = (wp.skew(a) * two - wp.outer(kb, wb)) * inv
    return kb, ja, jb


@wp.func(inline=True)
def bend_energy(a: Vec, b: Vec, kb_target: Vec, k: wp.Float):
    """Bending energy ``k/2 |kb - kb_target|^2`` [J] of edges ``a``, ``b``."""
    return type(k)(0.5) * k * wp.length_sq(curvature_binormal(a, b) - kb_target)


# -- curved rest shapes: the Bishop frame and its holonomy -----------------------------------


@wp.func(inline=True)
def first_edge_normal(t: wp.vec3) -> wp.vec3:
    """The fixed perpendicular of a tube's first rest edge (unit ``t``) that its rest frame
    starts from (``warp_tube.model.tube`` stores the rest curvature in the same frames)."""
    u = wp.vec3(1.0, 0.0, 0.0)
    if wp.abs(t[0]) > 0.6:
        u = wp.vec3(0.0, 1.0, 0.0)
    return wp.normalize(u - t * wp.dot(u, t))


@wp.func(inline=True)
def kappa_target(t: wp.vec3, u: wp.vec3, v: wp.vec3, kappa_rest: wp.vec3) -> wp.vec3:
    """Bending target [1] of a stencil: its rest curvature binormal, stored as (tangent, u, v)
    components in the rest Bishop frame of the stencil's first edge, rebuilt in that edge's
    current frame (unit tangent ``t``, Bishop normal ``u``, ``v = t x u``)."""
    return t * kappa_rest[0] + u * kappa_rest[1] + v * kappa_rest[2]


@wp.func(inline=True)
def holonomy_stencil(ta: wp.vec3, ila: float, kb: wp.vec3, target: wp.vec3, k: float):
    """The force of a bending target's dependence on the shape, for the stencil of edges ``a``
    (unit tangent ``ta``, reciprocal length ``ila`` [1/m]), ``b`` (curvature binormal ``kb``,
    target ``T`` in the Bishop frame of ``a``, coefficient ``k``).

    The frame follows its edge with angular velocity ``t x dt + dpsi t``. With ``g = k (kb - T)``
    and ``h = T x g`` the energy changes by ``(t x h) . da / |a|`` and by ``mu dpsi``,
    ``mu = -t . h``. Returns ``(t x h / |a|, mu)``: the first is the gradient with respect to ``a``;
    ``mu`` weights the twist that every earlier transport puts into this frame (see
    :func:`twist_gradients`).
    """
    h = wp.cross(target, (kb - target) * k)
    return wp.cross(ta, h) * ila, -wp.dot(ta, h)


@wp.func(inline=True)
def twist_gradients(kb: wp.vec3, m_after: float, ila: float, ilb: float):
    """Gradient [N] from the twist the transport at a stencil (curvature binormal ``kb``, edges of
    reciprocal lengths ``ila``, ``ilb`` [1/m]) puts into every later frame: the transport adds
    ``-kb / 2 . (da / |a| + db / |b|)`` to their twist (discrete parallel-transport holonomy), and
    ``m_after`` is the sum of the later stencils' ``mu``. Returns the gradients with respect to
    ``a`` and ``b``."""
    tw = kb * (-0.5 * m_after)
    return tw * ila, tw * ilb


@wp.func
def first_frame_gradient(t_rest: wp.vec3, e0: wp.vec3, m_total: float) -> wp.vec3:
    """Gradient [N] with respect to the first edge ``e0`` of the twist its own transport from the
    rest direction ``t_rest`` puts into every frame (``m_total``: the sum of all stencils' ``mu``)."""
    return curvature_binormal(t_rest, e0) * (-0.5 * m_total / wp.length(e0))


@wp.func(inline=True)
def stencil_forces(ga: wp.vec3, gb: wp.vec3, grad_a: wp.vec3, grad_b: wp.vec3):
    """Forces on a stencil's (prev, mid, next) nodes [N] from bending gradients ``ga``, ``gb``
    (:func:`bend_gradients`) and the frames' gradients with respect to its edges ``grad_a``,
    ``grad_b`` (:func:`holonomy_stencil`, :func:`twist_gradients`; zero for a straight tube):
    ``ga + grad_a``, ``gb - ga - grad_a + grad_b``, ``-gb - grad_b``, the middle one formed as
    minus the sum of the others (the three sum to zero to the last bit)."""
    f_prev = ga + grad_a
    f_next = -(gb + grad_b)
    return f_prev, -(f_prev + f_next), f_next


@wp.func
def first_edge_free(node_inv_mass: wp.array2d[float], pw: int, start: int) -> bool:
    """Whether a tube's first edge may turn (not both of its nodes pinned): its first frame is
    then twisted to the bending energy's minimum (:func:`twist_terms`) instead of fixed by a clamp."""
    return node_inv_mass[pw, start] > 0.0 or node_inv_mass[pw, start + 1] > 0.0


@wp.func
def curvature_targets(
    w: int,
    pw: int,
    start: int,
    end: int,
    node_q: wp.array2d[wp.vec3],
    node_q_lo: wp.array2d[wp.vec3],
    node_rest_q: wp.array2d[wp.vec3],
    node_kappa_rest: wp.array2d[wp.vec3],
    node_bend_k: wp.array2d[float],
    node_inv_mass: wp.array2d[float],
    node_kappa_target_out: wp.array2d[wp.vec3],
):
    """Bending targets of one tube's interior nodes (:func:`kappa_target`), its Bishop normal
    carried edge to edge in order (the sequential form of the on-chip kernel's scan of turns,
    :func:`~.frames.carried_twist`), each step's round-off taken out by keeping ``u`` unit and normal
    to ``t``.
    A tube whose first edge may turn (:func:`first_edge_free`) has no clamp to fix its first
    frame's twist: the frame is twisted to the energy's minimum (:func:`twist_terms`), so a rigid
    turn of the whole tube changes nothing; there the stencils' ``mu`` sum to zero, so
    :func:`first_frame_gradient` vanishes and the forces stay the energy's exact gradient."""
    t_rest = wp.normalize(node_rest_q[pw, start + 1] - node_rest_q[pw, start])
    t = wp.normalize(node_delta(node_q, node_q_lo, w, start, start + 1))
    u = rotate_minimal(t_rest, t, first_edge_normal(t_rest))
    node_kappa_target_out[w, start] = wp.vec3(0.0)
    node_kappa_target_out[w, end - 1] = wp.vec3(0.0)
    free = first_edge_free(node_inv_mass, pw, start)
    ab = wp.vec2(0.0)
    for j in range(start + 1, end - 1):
        target = kappa_target(t, u, wp.cross(t, u), node_kappa_rest[pw, j])
        node_kappa_target_out[w, j] = target
        t_next = wp.normalize(node_delta(node_q, node_q_lo, w, j, j + 1))
        if free:
            ab += twist_terms(t, target, curvature_binormal(node_delta(node_q, node_q_lo, w, j - 1, j), node_delta(node_q, node_q_lo, w, j, j + 1)), node_bend_k[pw, j])
        u = carry_normal(t, t_next, u)
        u = wp.normalize(u - t_next * wp.dot(u, t_next))
        t = t_next
    if free and (ab[0] != 0.0 or ab[1] != 0.0):
        cs = ab / wp.length(ab)  # (cos, sin) of psi = atan2(B, A)
        for j in range(start + 1, end - 1):
            t_j = wp.normalize(node_delta(node_q, node_q_lo, w, j - 1, j))
            node_kappa_target_out[w, j] = twisted(t_j, node_kappa_target_out[w, j], cs[0], cs[1])


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
    """Add to ``node_f_out`` [N] the forces of the targets' dependence on the shape, one backward
    pass over the tube (the sequential form of the on-chip kernel's suffix scan): each stencil's
    :func:`holonomy_stencil`, the twist of the transports weighted by the sum of the later
    stencils' ``mu`` (:func:`twist_gradients`) and of the first frame
    (:func:`first_frame_gradient`). With these the bending force is the exact gradient of the
    energy."""
    m_sum = float(0.0)
    t_b, ilb = edge_tangent(node_delta(node_q, node_q_lo, w, end - 2, end - 1))  # (each edge's once)
    for jj in range(end - start - 2):
        j = end - 2 - jj
        t_a, ila = edge_tangent(node_delta(node_q, node_q_lo, w, j - 1, j))
        kb, q = curvature_binormal_unit(t_a, t_b, ila, ilb)
        grad, mu = holonomy_stencil(t_a, ila, kb, node_kappa_target[w, j], node_bend_k[pw, j])
        ta, tb = twist_gradients(kb, m_sum, ila, ilb)
        f_prev, f_mid, f_next = stencil_forces(wp.vec3(0.0), wp.vec3(0.0), grad + ta, tb)
        node_f_out[w, j - 1] = node_f_out[w, j - 1] + f_prev
        node_f_out[w, j] = node_f_out[w, j] + f_mid
        node_f_out[w, j + 1] = node_f_out[w, j + 1] + f_next
        m_sum += mu
        t_b = t_a
        ilb = ila
    g0 = first_frame_gradient(wp.normalize(node_rest_q[pw, start + 1] - node_rest_q[pw, start]), node_delta(node_q, node_q_lo, w, start, start + 1), m_sum)
    node_f_out[w, start + 1] = node_f_out[w, start + 1] - g0
    node_f_out[w, start] = node_f_out[w, start] + g0
