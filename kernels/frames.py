"""Hub tangents, least rotations and twist-free frames along batched centerlines (Warp).

These functions follow the frame convention of :mod:`warp_tube.model.frames` (the NumPy
reference) exactly, in float32:

- Tangent at a hub: the normalised sum of the unit vectors of its two edges (the bisector), the
  unit edge vector at a tube's two ends.
- A frame is ``(t, r, s)`` with ``r`` the direction of spoke 0 and ``s = t x r``; the functions
  write ``t`` and ``r`` only (``s`` is one cross product away).

Two ways of carrying the spokes along a deformed centerline, both without rotation about the axis:

``rotationMinimizing`` (default), :func:`tube_rotation_minimizing_frames`
    A scan of the tube's hubs in order. The first hub's normal is its rest
    normal carried by the minimal rotation that takes the rest first tangent to the current first
    tangent; every later normal comes from its predecessor by the double reflection of Wang,
    Juttler, Zheng and Liu (ACM TOG 27(1), 2008): reflect ``(r_i, t_i)`` in the bisecting plane of
    ``x_i x_{i+1}``, then in the plane that takes the reflected tangent onto ``t_{i+1}``. The frames
    follow the deformed curve as a whole: the twist they accumulate is the curve's own geometric
    twist (for a helix, ``-torsion`` per unit length), fourth order accurate in the hub spacing
    with exact tangents. Cost: a sequential loop of ``n`` steps per tube (the surface's block kernel
    finds each step's two reflections in parallel, :func:`reflection_pair_a`,
    :func:`reflection_pair_b`, and runs only their product, :func:`reflect_frame`, in order).

``local`` (the paper's section 3.2, eq. 2), :func:`hub_local_frame`
    One hub at a time. Each hub's spoke plane is carried from that hub's *rest* frame by
    the minimal rotation taking its rest tangent to its current tangent, independently of every
    other hub: the translation + in-plane rotation + out-of-plane rotation of the paper's lemma
    compose to exactly this least rotation. (The paper rotates the segment ``AB`` into the spoke;
    here the tangent is the hub's bisector tangent, so that both modes put each ring in the same
    plane and differ only in the spokes' rotation about the tangent.) It is fully parallel and
    exact for the paper's motions (rigid translation, bending in a plane through the rest axis) but,
    being path-independent per hub, it does not follow the twist that a genuinely
    three-dimensional bend puts into a rotation-minimizing frame (see the helix figures in the
    tests), and a hub whose tangent turns near 180 degrees from rest has an ill-defined rotation.

Batch layout: node positions ``node_q`` [any length unit] shaped (world_count, node_count) hold the
nodes of all tubes of one world concatenated; this module's nodes start at column ``node_offset``
(other prims' nodes may come first). ``tube_node_start`` (tube_count + 1) gives each tube's first
node relative to ``node_offset``; ``node_tube`` (node_count) the tube of each node. Parameter arrays
shaped (1, n) or (world_count, n) are read at row ``w % rows``.
"""

import warp as wp

ANTIPARALLEL_EPS = wp.constant(1.0e-6)
"""``1 + a.b`` below which two unit vectors are taken as opposite (a half turn), float32; the NumPy
reference (:func:`warp_tube.model.frames.rotate_minimal`) uses the same threshold."""


@wp.func
def safe_normalize(v: wp.vec3) -> wp.vec3:
    """``v / |v|``, or ``v`` itself when its length is zero (as the NumPy reference)."""
    length = wp.length(v)
    if length > 0.0:
        return v / length
    return v


@wp.func
def hub_tangent(node_q: wp.array2d[wp.vec3], w: int, i: int, first: int, last: int) -> wp.vec3:
    """Unit tangent [1] at column ``i`` of a tube whose nodes are columns ``first..last``.

    The bisector of the two unit edges inside the tube, the unit edge at its ends.
    """
    if i == first:
        return safe_normalize(node_q[w, i + 1] - node_q[w, i])
    if i == last:
        return safe_normalize(node_q[w, i] - node_q[w, i - 1])
    e0 = safe_normalize(node_q[w, i] - node_q[w, i - 1])
    e1 = safe_normalize(node_q[w, i + 1] - node_q[w, i])
    return safe_normalize(e0 + e1)


@wp.func
def least_aligned_normal(t: wp.vec3) -> wp.vec3:
    """Unit normal to ``t`` from the world axis least aligned with it (lowest index on ties)."""
    ax = wp.abs(t[0])
    ay = wp.abs(t[1])
    az = wp.abs(t[2])
    axis = wp.vec3(0.0, 0.0, 1.0)
    if ax <= ay and ax <= az:
        axis = wp.vec3(1.0, 0.0, 0.0)
    elif ay <= az:
        axis = wp.vec3(0.0, 1.0, 0.0)
    return wp.normalize(axis - wp.dot(axis, t) * t)


@wp.func
def rotate_minimal(a: wp.vec3, b: wp.vec3, x: wp.vec3) -> wp.vec3:
    """Apply to ``x`` the least rotation taking unit vector ``a`` to unit vector ``b``.

    ``R x = x + k x x + k x (k x x) / (1 + a.b)`` with ``k = a x b``. For ``1 + a.b`` below
    :data:`ANTIPARALLEL_EPS` (a half turn, where the least rotation is not unique) the half turn
    about :func:`least_aligned_normal` of ``a`` is taken, as the NumPy reference does. The one
    least rotation of the kernels: surface frames, guard planes and the bending springs' Bishop
    frames (:mod:`warp_tube.kernels.springs`, :mod:`warp_tube.kernels.onchip`).
    """
    c = wp.dot(a, b)
    if c < -1.0 + ANTIPARALLEL_EPS:
        k = least_aligned_normal(a)
        return 2.0 * wp.dot(k, x) * k - x
    k = wp.cross(a, b)
    kx = wp.cross(k, x)
    return x + kx + wp.cross(k, kx) / (1.0 + c)


@wp.func(inline=True)
def edge_normal(t: wp.vec3) -> wp.vec3:
    """A unit normal of unit vector ``t``, a smooth function of ``t`` except where ``t[2]`` changes
    sign, without a square root or a branch (Duff et al., "Building an orthonormal basis,
    revisited", JCGT 6(1), 2017): the reference an edge's Bishop normal is measured from by
    :func:`carried_twist`; ``(1, 0, 0)`` for a zero ``t``."""
    sign = wp.sign(t[2])
    a = -1.0 / (sign + t[2])
    return wp.vec3(1.0 + sign * t[0] * t[0] * a, sign * t[0] * t[1] * a, -sign * t[0])


@wp.func(inline=True)
def edge_binormal(t: wp.vec3) -> wp.vec3:
    """``t x edge_normal(t)`` for unit ``t``: the second vector of the same basis (Duff et al.),
    without a cross product; ``(0, 1, 0)`` for a zero ``t``."""
    sign = wp.sign(t[2])
    a = -1.0 / (sign + t[2])
    return wp.vec3(t[0] * t[1] * a, sign + t[1] * t[1] * a, -t[1])


@wp.func(inline=True)
def carry_normal(a: wp.vec3, b: wp.vec3, x: wp.vec3) -> wp.vec3:
    """:func:`rotate_minimal` of a vector ``x`` normal to unit ``a``, taking ``a`` to unit ``b``:
    ``x - (x . b) / (1 + a . b) (a + b)`` (what is normal to both tangents is kept, the rest turned
    in their plane), a half turn (``1 + a . b`` below :data:`ANTIPARALLEL_EPS`) as there. Fewer
    operations than the general form, and none of them waiting on a cross product: the Bishop
    normal carried edge to edge (:func:`carried_twist`, ``bending.curvature_targets``)."""
    c = wp.dot(a, b)
    if c < -1.0 + ANTIPARALLEL_EPS:
        return rotate_minimal(a, b, x)
    return x - (a + b) * (wp.dot(x, b) / (1.0 + c))


@wp.func(inline=True)
def carried_twist(a: wp.vec3, x: wp.vec3, b: wp.vec3, n: wp.vec3, m: wp.vec3) -> wp.vec2:
    """The turn about unit tangent ``b`` from its unit normal ``n`` (``m = b x n``) to ``p``, the
    normal ``x`` of unit tangent ``a`` carried onto ``b`` by the least rotation
    (:func:`carry_normal`), as the unit complex number ``(cos, sin)``: ``p = cos n + sin m``.
    Turns compose by complex product (:func:`turn_product`), so a tube's Bishop normals are its
    edges' :func:`edge_normal` turned by a scan of products: a pair of scalars where the frames'
    rotations would be quaternions.

    ``p`` is not formed: with ``s = (x . b) / (1 + a . b)``, ``n . p = n . x - s n . a`` and
    ``m . p = m . x - s m . a`` (``n . b = m . b = 0``), which the on-chip kernel schedules better
    (1% faster on an H200 than forming ``p``, 2026-11-28)."""
    c = wp.dot(a, b)
    if c < -1.0 + ANTIPARALLEL_EPS:
        p = rotate_minimal(a, b, x)
        return wp.vec2(wp.dot(n, p), wp.dot(m, p))
    s = wp.dot(x, b) / (1.0 + c)
    return wp.vec2(wp.dot(n, x) - s * wp.dot(n, a), wp.dot(m, x) - s * wp.dot(m, a))


@wp.func(inline=True)
def turn_product(a: wp.vec2, b: wp.vec2) -> wp.vec2:
    """The turn ``a`` followed by ``b`` (:func:`carried_twist`; their complex product)."""
    return wp.vec2(a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0])


@wp.func(inline=True)
def unit_turn(z: wp.vec2) -> wp.vec2:
    """Turn ``z`` (:func:`carried_twist`) normalised: a product of many turns drifts from unit
    length by round-off (a zero ``z``, of degenerate edges, stays zero)."""
    return z * (1.0 / wp.sqrt(wp.max(wp.dot(z, z), 1.0e-30)))


@wp.func(inline=True)
def turned_components(k: wp.vec3, c: wp.vec2) -> wp.vec3:
    """Components ``k`` of a vector in the frame ``(t, u, t x u)`` whose normal ``u`` is normal
    ``n`` of unit tangent ``t`` turned about it by unit turn ``c`` (``u = c[0] n + c[1] t x n``),
    as components in ``(t, n, t x n)``: the vector without forming the turned frame."""
    return wp.vec3(k[0], c[0] * k[1] - c[1] * k[2], c[1] * k[1] + c[0] * k[2])


@wp.func
def reflection_pair_a(x0: wp.vec3, x1: wp.vec3) -> wp.vec4:
    """The first reflection of a double-reflection step from hub ``x0`` to hub ``x1`` [1]: its
    plane normal ``v1 = x1 - x0`` and ``2 / |v1|^2``, or ``w = -1`` where the hubs coincide (the
    step then keeps the normal as it is)."""
    v1 = x1 - x0
    c1 = wp.dot(v1, v1)
    if c1 <= 0.0:
        return wp.vec4(0.0, 0.0, 0.0, -1.0)
    return wp.vec4(v1[0], v1[1], v1[2], 2.0 / c1)


@wp.func
def reflection_pair_b(a: wp.vec4, t0: wp.vec3, t1: wp.vec3) -> wp.vec4:
    """The second reflection of the step whose first is ``a`` (:func:`reflection_pair_a`), from
    tangent ``t0`` to ``t1``: normal ``v2 = t1 - R1 t0`` and ``2 / |v2|^2``, or ``w = 0`` where
    ``v2`` vanishes (no second reflection)."""
    v1 = wp.vec3(a[0], a[1], a[2])
    t_l = t0 - a[3] * wp.dot(v1, t0) * v1
    v2 = t1 - t_l
    c2 = wp.dot(v2, v2)
    if c2 > 1.0e-30:
        return wp.vec4(v2[0], v2[1], v2[2], 2.0 / c2)
    return wp.vec4(0.0)


@wp.func
def reflect_frame(r0: wp.vec3, a: wp.vec4, b: wp.vec4, t1: wp.vec3) -> wp.vec3:
    """Normal ``r0`` carried by the double-reflection step ``(a, b)`` to the hub of tangent ``t1``.

    The step's two reflections depend on the hubs and their tangents only, not on the normal they
    carry: they are found for all hubs at once (:func:`reflection_pair_a`, :func:`reflection_pair_b`)
    and only this product runs along the tube, one hub after the other.
    """
    if a[3] < 0.0:
        return r0
    v1 = wp.vec3(a[0], a[1], a[2])
    r_l = r0 - a[3] * wp.dot(v1, r0) * v1
    r_n = r_l
    if b[3] > 0.0:
        v2 = wp.vec3(b[0], b[1], b[2])
        r_n = r_l - b[3] * wp.dot(v2, r_l) * v2
    # Re-orthonormalise against round-off so long tubes keep an orthonormal frame.
    r_n = r_n - wp.dot(r_n, t1) * t1
    return wp.normalize(r_n)


@wp.func
def double_reflection(x0: wp.vec3, x1: wp.vec3, t0: wp.vec3, t1: wp.vec3, r0: wp.vec3) -> wp.vec3:
    """Normal at hub ``x1`` carried from ``(x0, t0, r0)`` by one double-reflection step [1]."""
    a = reflection_pair_a(x0, x1)
    return reflect_frame(r0, a, reflection_pair_b(a, t0, t1), t1)


@wp.func
def tube_start_normal(rest_t: wp.vec3, rest_r: wp.vec3, t: wp.vec3) -> wp.vec3:
    """Normal at a tube's first hub: its rest normal turned by the least rotation of its rest
    tangent onto ``t``, made orthonormal to ``t``."""
    r = rotate_minimal(rest_t, t, rest_r)
    return wp.normalize(r - wp.dot(r, t) * t)


@wp.func
def tube_rotation_minimizing_frames(
    w: int,
    tube: int,
    node_offset: int,
    tube_node_start: wp.array[wp.int32],
    node_rest_t: wp.array2d[wp.vec3],
    node_rest_r: wp.array2d[wp.vec3],
    node_q: wp.array2d[wp.vec3],
    hub_t_out: wp.array2d[wp.vec3],
    hub_r_out: wp.array2d[wp.vec3],
):
    """Double-reflection rotation-minimizing frames of tube ``tube`` of world ``w``.

    Args:
        node_offset: column of ``node_q`` holding this module's node 0.
        tube_node_start: first node of each tube (relative to ``node_offset``), tube_count + 1.
        node_rest_t: rest unit tangents [1], shape (1 or world_count, node_count).
        node_rest_r: rest unit normals (spoke 0) [1], same shape; only each tube's first is read.
        node_q: node positions [any length unit], shape (world_count, >= node_offset + node_count).
        hub_t_out: unit tangents [1], shape (world_count, node_count); the tube's are written.
        hub_r_out: unit normals (spoke 0) [1], shape (world_count, node_count); the tube's are
            written.
    """
    pw = w % node_rest_t.shape[0]
    start = tube_node_start[tube]
    end = tube_node_start[tube + 1]
    first = node_offset + start
    last = node_offset + end - 1

    t = hub_tangent(node_q, w, first, first, last)
    r = tube_start_normal(node_rest_t[pw, start], node_rest_r[pw, start], t)
    hub_t_out[w, start] = t
    hub_r_out[w, start] = r
    x = node_q[w, first]
    for i in range(start + 1, end):
        x_next = node_q[w, node_offset + i]
        t_next = hub_tangent(node_q, w, node_offset + i, first, last)
        r = double_reflection(x, x_next, t, t_next, r)
        hub_t_out[w, i] = t_next
        hub_r_out[w, i] = r
        x = x_next
        t = t_next


@wp.func
def hub_local_frame(
    w: int,
    i: int,
    node_offset: int,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    node_rest_t: wp.array2d[wp.vec3],
    node_rest_r: wp.array2d[wp.vec3],
    node_q: wp.array2d[wp.vec3],
    hub_t_out: wp.array2d[wp.vec3],
    hub_r_out: wp.array2d[wp.vec3],
):
    """The paper's local frame (eq. 2) of hub ``i`` of world ``w``: ``r_i = R(rest t_i -> t_i) rest r_i``
    with ``R`` the least rotation, made orthonormal to ``t_i``. Arguments as
    :func:`tube_rotation_minimizing_frames`, plus ``node_tube`` (the tube of each node); every
    node's rest normal is read."""
    pw = w % node_rest_t.shape[0]
    tube = node_tube[i]
    first = node_offset + tube_node_start[tube]
    last = node_offset + tube_node_start[tube + 1] - 1
    t = hub_tangent(node_q, w, node_offset + i, first, last)
    r = rotate_minimal(node_rest_t[pw, i], t, node_rest_r[pw, i])
    hub_t_out[w, i] = t
    hub_r_out[w, i] = wp.normalize(r - wp.dot(r, t) * t)


@wp.func(inline=True)
def twist_terms(t: wp.vec3, target: wp.vec3, kb: wp.vec3, k: float) -> wp.vec2:
    """A stencil's share ``(A, B)`` of its tube's bending energy as a function of a twist ``psi``
    of the first frame, which turns every target about its edge's tangent ``t``: the energy is
    ``C - A cos psi - B sin psi``, minimal at ``psi = atan2(B, A)`` summed over the tube.
    ``target`` untwisted, ``kb`` the stencil's curvature binormal, ``k`` its stiffness [N m]."""
    perp = target - t * wp.dot(target, t)
    return wp.vec2(k * wp.dot(kb, perp), k * wp.dot(kb, wp.cross(t, perp)))


@wp.func(inline=True)
def twisted(t: wp.vec3, target: wp.vec3, c: float, s: float) -> wp.vec3:
    """``target`` turned about the unit tangent ``t`` by the angle of cosine ``c`` and sine ``s``."""
    along = t * wp.dot(target, t)
    perp = target - along
    return along + perp * c + wp.cross(t, perp) * s
