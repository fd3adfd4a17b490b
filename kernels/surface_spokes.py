"""Boundary points and normals of the hubs-and-spokes surface (Warp), ring by ring.

A ring is a set of ``S`` spokes leaving one hub at the same angle ``theta`` to the hub tangent
(see :mod:`warp_tube.surface.topology` for the ring table): body rings at 90 degrees, cap rings at smaller
angles to the outward axis, and a cap's pole (one vertex, on the axis). Spoke ``j`` of a ring
points along::

    d_j = cos(theta) t + sin(theta) u_j,    u_j = cos(phi_j) r + sin(phi_j) s,    phi_j = 2 pi j / S

with ``(t, r, s = t x r)`` the hub's frame (:mod:`warp_tube.kernels.frames`); its end is
``x + L d_j`` with ``L`` the spoke's length (a pole: the mean of the hub's spoke lengths).

Normals are those of the smooth surface ``p(s, phi) = x(s) + L(s, phi) u(s, phi)`` that the spokes
sample, with the frame carried without twist (so ``du/ds = -(kappa . u) t``)::

    n ~ d - (L_phi / (L sin theta)) (t x u) - [body rings] (L_s / (1 - L kappa . u)) t

where ``L_phi`` is the central difference of the (guarded) lengths of the neighbouring spokes of
the ring, ``L_s`` the difference of the given lengths of the neighbouring hubs over their chord
lengths (one-sided at a tube's ends), ``kappa = (e1/|e1| - e0/|e0|) / l_v`` the hub's curvature
vector (exact, ``1 / rho`` towards the centre, on a circle; an end hub uses its neighbour's) and ``1 - L kappa . u``
is floored at :data:`MIN_STRETCH`. For a circular tube this is exactly the spoke direction ``u``.

A spoke longer than its ring's free length takes the inner-bend guard's length
(:mod:`warp_tube.kernels.surface_guard`), both for its point and in its neighbours' ``L_phi``.
"""

import warp as wp

from .surface_arrays import RING_BODY, RING_POLE, SurfaceArrays
from .surface_guard import pole_length, ring_free_length

MIN_STRETCH = wp.constant(1.0e-2)
"""Floor of ``1 - L kappa . u`` (the surface's stretch along the tube at a spoke end) in normals."""


@wp.func
def drawn_length(given: float, limit: float, guard: bool, surface_length: wp.array2d[float], w: int, v: int) -> float:
    """Length [length unit] that the spoke of vertex ``v`` is drawn with: the guard's
    (``surface_length``, :func:`~warp_tube.kernels.surface_guard.spoke_guard`) where the guard is on
    and the ``given`` length exceeds the ring's free length ``limit``, else the given one."""
    if guard and given > limit:
        return surface_length[w, v]
    return given


@wp.func
def ring_spoke_lengths(
    w: int,
    pw: int,
    h: int,
    j: int,
    kind: int,
    spoke_count: int,
    v0: int,
    guard: bool,
    free: wp.vec2,
    spoke_length: wp.array3d[float],
    surface_length: wp.array2d[float],
):
    """Lengths [length unit] that spoke ``j`` of a ring (first vertex ``v0``) and its two
    neighbours in the ring are drawn with (:func:`drawn_length`)."""
    jm = j - 1
    if j == 0:
        jm = spoke_count - 1
    jp = j + 1
    if jp == spoke_count:
        jp = 0
    limit = ring_free_length(free, kind)
    length = drawn_length(spoke_length[pw, h, j], limit, guard, surface_length, w, v0 + j)
    length_m = drawn_length(spoke_length[pw, h, jm], limit, guard, surface_length, w, v0 + jm)
    length_p = drawn_length(spoke_length[pw, h, jp], limit, guard, surface_length, w, v0 + jp)
    return length, length_m, length_p


@wp.func
def body_length_step(pw: int, h: int, j: int, has_prev: int, has_next: int, spoke_length: wp.array3d[float]) -> float:
    """Difference [length unit] of spoke ``j``'s given lengths at the neighbouring hubs (one-sided
    at a tube's end, 0 for a tube of one hub)."""
    dl = float(0.0)
    if has_prev != 0 and has_next != 0:
        dl = spoke_length[pw, h + 1, j] - spoke_length[pw, h - 1, j]
    elif has_next != 0:
        dl = spoke_length[pw, h + 1, j] - spoke_length[pw, h, j]
    elif has_prev != 0:
        dl = spoke_length[pw, h, j] - spoke_length[pw, h - 1, j]
    return dl


@wp.func
def spoke_point_normal(
    x: wp.vec3,
    t: wp.vec3,
    r: wp.vec3,
    s: wp.vec3,
    c: float,
    sn: float,
    kind: int,
    cos_j: float,
    sin_j: float,
    length: float,
    length_m: float,
    length_p: float,
    dphi: float,
    dl: float,
    kappa: wp.vec3,
    ds: float,
):
    """End point [length unit] and unit normal of a (non-pole) spoke at angle ``phi_j`` of a ring
    at ``theta`` (``c``, ``sn``: its cosine and sine) from hub ``x`` with frame ``(t, r, s)``.

    The normal is the module's formula: the central difference ``length_p - length_m`` over
    ``2 dphi`` around the ring; on body rings ``dl / ds`` along the tube (``ds``: the hub's chord
    sum) over the stretch ``1 - L kappa . u`` floored at :data:`MIN_STRETCH`. Where both terms are
    zero (a circular stretch of constant radius) the normal is the spoke direction, found without
    them.
    """
    u = cos_j * r + sin_j * s
    d = c * t + sn * u
    if length_p == length_m and (dl == 0.0 or kind != RING_BODY or not ds > 0.0):
        # Both correction terms vanish (no change of length round the ring here, none along the
        # tube that enters): the normal is the spoke direction. The same value the general
        # branch gives (it would subtract exact zeros), for a fraction of the work.
        return x + length * d, wp.normalize(d)
    u_perp = wp.cross(t, u)
    n = d - ((length_p - length_m) / (2.0 * dphi * length * sn)) * u_perp
    if kind == RING_BODY:
        stretch = wp.max(1.0 - length * wp.dot(kappa, u), MIN_STRETCH)
        if ds > 0.0:
            n = n - (dl / (ds * stretch)) * t
    return x + length * d, wp.normalize(n)


@wp.func
def uniform_ring(
    pw: int,
    h: int,
    kind: int,
    guard: bool,
    free: wp.vec2,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    spoke_length: wp.array3d[float],
    hub_uniform: wp.array2d[wp.int32],
):
    """Whether a (non-pole) ring of hub ``h`` is uniform: the hub and its neighbours have one spoke
    length all round (``hub_uniform``) and the guard leaves the ring alone (the length is within
    its free length, the test of :func:`ring_spoke_lengths`). Returns ``(uniform, length, dl)``:
    the common length and its step along the tube [length unit] (meaningful when uniform), the
    values every spoke of the ring would read."""
    length = spoke_length[pw, h, 0]
    dl = float(0.0)
    uniform = hub_uniform[pw, h] != 0 and not (guard and length > ring_free_length(free, kind))
    if uniform:
        tube = node_tube[h]
        has_prev = int(h > tube_node_start[tube])
        has_next = int(h < tube_node_start[tube + 1] - 1)
        dl = body_length_step(pw, h, 0, has_prev, has_next, spoke_length)
    return uniform, length, dl


@wp.func
def ring_vertices(
    w: int,
    ring: int,
    j_first: int,
    j_step: int,
    arrays: SurfaceArrays,
    node_q: wp.array2d[wp.vec3],
    lo: wp.vec3,
    hi: wp.vec3,
):
    """Write the points and normals of spokes ``j_first, j_first + j_step, ...`` of one ring of
    world ``w`` (a pole ring's one vertex when ``j_first`` is 0) to ``arrays.surface_q_out`` and
    ``arrays.surface_n_out``; returns ``lo``, ``hi`` widened by the points written.

    Reads the hub frames and the per-hub data of
    :func:`~warp_tube.kernels.surface_guard.hub_guard` (and, with the guard on, the guarded
    lengths of :func:`~warp_tube.kernels.surface_guard.ring_guard`). A ring whose hub and
    neighbours have equal spoke lengths all round (``hub_uniform``, a circular tube) and that the
    guard leaves alone reads its length and its step along the tube once: the same values the
    per-spoke reads give, so the same points and normals.
    """
    node_offset = arrays.node_offset
    spoke_count = arrays.spoke_count
    guard = arrays.guard_reach > 0.0
    tube_node_start = arrays.tube_node_start
    node_tube = arrays.node_tube
    spoke_length = arrays.spoke_length
    surface_length = arrays.surface_length
    surface_q_out = arrays.surface_q_out
    surface_n_out = arrays.surface_n_out
    hub_t = arrays.hub_t
    pw = w % spoke_length.shape[0]
    kind = arrays.ring_kind[ring]
    h = arrays.ring_hub[ring]
    x = node_q[w, node_offset + h]
    t = hub_t[w, h]
    c = arrays.ring_cos[ring]
    free = arrays.hub_free[w, h]
    v0 = arrays.ring_vertex[ring]
    out_lo = lo
    out_hi = hi
    if kind == RING_POLE:
        if j_first == 0:
            # The pole spoke: along c t, the mean of the hub's spoke lengths (or the guard's).
            pole = drawn_length(pole_length(spoke_length, pw, h), ring_free_length(free, kind), guard, surface_length, w, v0)
            p = x + pole * (c * t)
            surface_q_out[w, v0] = p
            surface_n_out[w, v0] = c * t
            out_lo = wp.min(out_lo, p)
            out_hi = wp.max(out_hi, p)
        return out_lo, out_hi
    tube = node_tube[h]
    has_prev = int(h > tube_node_start[tube])
    has_next = int(h < tube_node_start[tube + 1] - 1)
    sn = arrays.ring_sin[ring]
    r = arrays.hub_r[w, h]
    s = wp.cross(t, r)
    kappa = arrays.hub_kappa[w, h]
    ds = arrays.hub_chord[w, h]
    dphi = 2.0 * wp.pi / float(spoke_count)
    uniform, length, dl = uniform_ring(pw, h, kind, guard, free, tube_node_start, node_tube, spoke_length, arrays.hub_uniform)
    for j in range(j_first, spoke_count, j_step):
        length_j = length
        length_m = length
        length_p = length
        dl_j = dl
        if not uniform:
            length_j, length_m, length_p = ring_spoke_lengths(
                w, pw, h, j, kind, spoke_count, v0, guard, free, spoke_length, surface_length
            )  # fmt: skip
            dl_j = body_length_step(pw, h, j, has_prev, has_next, spoke_length)
        p, n = spoke_point_normal(
            x, t, r, s, c, sn, kind, arrays.spoke_cos[j], arrays.spoke_sin[j], length_j, length_m, length_p, dphi, dl_j, kappa, ds
        )  # fmt: skip
        surface_q_out[w, v0 + j] = p
        surface_n_out[w, v0 + j] = n
        out_lo = wp.min(out_lo, p)
        out_hi = wp.max(out_hi, p)
    return out_lo, out_hi
