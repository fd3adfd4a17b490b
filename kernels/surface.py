"""Boundary points and normals of the hubs-and-spokes surface (Warp), one thread per spoke.

A ring is a set of ``S`` spokes leaving one hub at the same angle ``theta`` to the hub tangent
(see :mod:`warp_tube.topology` for the ring table): body rings at 90 degrees, cap rings at smaller
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

Inner-bend guard. Where ``radius x curvature`` approaches 1, inner spokes reach the centre of
curvature, where the neighbouring rings' planes cross their own: past it, rings would cross and the
surface would fold through itself. With ``guard_reach = g`` in (0, 1) (0: off), a spoke's length is
limited so that its end stays at most the fraction ``g`` of the way, along the spoke, to

- the plane of either neighbouring ring (through the neighbour hub, normal to its tangent), where
  the spoke heads into it: ``L <= g ((x_k - x) . t_k) / (d . t_k)``;
- the plane through the local centre of curvature ``x + kappa / |kappa|^2`` normal to ``kappa``'s
  part in the ring plane (an end hub uses its interior neighbour's ``kappa``);
- for a body ring at a tube's end, a virtual ring one hub beyond the end that continues the last
  segment's bend. An end ring is normal to its edge, not radial to the bend, so near the centre of
  curvature it would reach behind its hub (into the place of the other end of a tube bent into a
  nearly closed loop). This limit is blended in as the spoke's unguarded reach goes from 0.9 to 1
  times the distance to the centre's plane, so the shape stays continuous and tubes with
  ``radius x curvature <= 0.9`` are not affected by it.

On a circular arc all interior ring planes meet in the arc's axis (through the centre of
curvature), so every ring stays in its own wedge: rings never touch and the strips between them lie
in disjoint wedges; an open tube has no self-intersection at any curvature as long as its arc angle
leaves a gap of more than two hub spacings (the virtual rings) before closing into a loop. Caps are
not limited by the virtual rings: a cap's dome of radius ``r`` is real geometry, and on a loop it can
reach the tube's other end (contact, not modelled).

Cost in shape: where the guard acts the inner side of a ring is cut flat along a straight chord at
distance ``g rho`` from the hub (``rho`` the bend radius; about ``2/3 g rho`` at an end ring), parallel
to the bend axis: the cross-section loses the circular segment beyond that chord and the inner wall
becomes a thin surface of revolution of radius ``(1 - g) rho`` around the bend axis. On a circular
tube it acts only where ``radius x curvature > g`` for the innermost spoke; below that the surface is
exact. It costs five plane tests per spoke (three spokes are evaluated per thread, for normals).
"""

import warp as wp

from .frames import rotate_minimal, safe_normalize

RING_BODY = wp.constant(0)
RING_CAP = wp.constant(1)
RING_POLE = wp.constant(2)
MIN_STRETCH = wp.constant(1.0e-2)
"""Floor of ``1 - L kappa . u`` (the surface's stretch along the tube at a spoke end) in normals."""
VIRTUAL_BLEND = wp.constant(0.9)
"""Reach (fraction of the distance to the centre of curvature) where an end ring starts to feel the
virtual ring beyond the tube's end."""


@wp.func
def plane_distance(d: wp.vec3, x: wp.vec3, x_k: wp.vec3, t_k: wp.vec3) -> float:
    """Distance [length unit] along unit ``d`` from ``x`` to the plane through ``x_k`` normal to
    ``t_k``, where the ray from ``x`` heads into that plane; -1 where it does not."""
    num = wp.dot(x_k - x, t_k)
    den = wp.dot(d, t_k)
    if num * den > 0.0:
        return num / den
    return -1.0


@wp.func
def neighbour_limit(length: float, kind: int, l_k: float, l_c: float, guard_reach: float) -> float:
    """Limit of a spoke of given ``length`` from one neighbour ring's plane at distance ``l_k``.

    ``kind`` 1: a real neighbour, limit ``guard_reach l_k``. ``kind`` 2: the virtual ring beyond a
    tube's end, blended in as the spoke's reach goes from :data:`VIRTUAL_BLEND` to 1 times ``l_c``,
    the distance to the centre of curvature's plane, so that the shape changes continuously.
    """
    out = length
    if l_k > 0.0:
        if kind == 1:
            out = wp.min(length, guard_reach * l_k)
        elif kind == 2 and l_c > 0.0:
            blend = wp.clamp((length / l_c - VIRTUAL_BLEND) / (1.0 - VIRTUAL_BLEND), 0.0, 1.0)
            out = length + blend * (wp.min(length, guard_reach * l_k) - length)
    return out


@wp.func
def spoke_length_at(
    length: float,
    d: wp.vec3,
    x: wp.vec3,
    prev_kind: int,
    x_prev: wp.vec3,
    t_prev: wp.vec3,
    next_kind: int,
    x_next: wp.vec3,
    t_next: wp.vec3,
    has_centre: int,
    centre: wp.vec3,
    k_perp: wp.vec3,
    guard_reach: float,
) -> float:
    """Spoke length [length unit] after the inner-bend guard.

    Limited against the previous and next rings' planes (kind 0: none, 1: real, 2: virtual, see
    :func:`neighbour_limit`) and against the plane through the local centre of curvature
    ``centre`` normal to ``k_perp`` (the curvature direction in the ring's plane).
    """
    out = length
    if guard_reach > 0.0:
        l_c = float(-1.0)
        if has_centre != 0:
            l_c = plane_distance(d, x, centre, k_perp)
        if prev_kind != 0:
            out = wp.min(out, neighbour_limit(length, prev_kind, plane_distance(d, x, x_prev, t_prev), l_c, guard_reach))
        if next_kind != 0:
            out = wp.min(out, neighbour_limit(length, next_kind, plane_distance(d, x, x_next, t_next), l_c, guard_reach))
        if l_c > 0.0:
            out = wp.min(out, guard_reach * l_c)
    return out


@wp.kernel(enable_backward=False)
def spoke_points_kernel(
    # model:
    node_offset: int,
    spoke_count: int,
    guard_reach: float,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    ring_hub: wp.array[wp.int32],
    ring_kind: wp.array[wp.int32],
    ring_cos: wp.array[float],
    ring_sin: wp.array[float],
    ring_vertex: wp.array[wp.int32],
    spoke_length: wp.array3d[float],
    # state in:
    node_q: wp.array2d[wp.vec3],
    hub_t: wp.array2d[wp.vec3],
    hub_r: wp.array2d[wp.vec3],
    # out:
    surface_q_out: wp.array2d[wp.vec3],
    surface_n_out: wp.array2d[wp.vec3],
):
    """Write one spoke's boundary point and unit normal; one thread per (world, ring, spoke).

    Args:
        node_offset: column of ``node_q`` holding hub 0.
        spoke_count: spokes per ring, S.
        guard_reach: inner-bend guard fraction in (0, 1); 0 turns the guard off.
        tube_node_start: first hub of each tube, (tube_count + 1,).
        node_tube: tube of each hub, (node_count,).
        ring_hub, ring_kind, ring_cos, ring_sin, ring_vertex: the ring table, (ring_count,) each.
        spoke_length: spoke lengths [length unit], shape (1 or world_count, node_count, S).
        node_q: hub positions [length unit], shape (world_count, >= node_offset + node_count).
        hub_t, hub_r: hub unit tangents and normals [1], shape (world_count, node_count).
        surface_q_out: boundary points [length unit], shape (world_count, vertex_count).
        surface_n_out: unit outward normals [1], shape (world_count, vertex_count).
    """
    w, ring, j = wp.tid()
    kind = ring_kind[ring]
    if kind == RING_POLE and j > 0:
        return
    h = ring_hub[ring]
    pw = w % spoke_length.shape[0]
    tube = node_tube[h]
    has_prev = int(h > tube_node_start[tube])
    has_next = int(h < tube_node_start[tube + 1] - 1)

    x = node_q[w, node_offset + h]
    t = hub_t[w, h]
    r = hub_r[w, h]
    s = wp.cross(t, r)
    x_prev = x
    t_prev = t
    x_next = x
    t_next = t
    if has_prev != 0:
        x_prev = node_q[w, node_offset + h - 1]
        t_prev = hub_t[w, h - 1]
    if has_next != 0:
        x_next = node_q[w, node_offset + h + 1]
        t_next = hub_t[w, h + 1]
    c = ring_cos[ring]
    sn = ring_sin[ring]

    # Curvature vector at the hub (an end hub borrows its interior neighbour's) and the local
    # centre of curvature, for the guard and the normals.
    first = tube_node_start[tube]
    last = tube_node_start[tube + 1] - 1
    hc = wp.clamp(h, first + 1, last - 1)
    kappa = wp.vec3(0.0)
    has_centre = int(0)
    centre = x
    k_perp = wp.vec3(0.0)
    if last - first >= 2:
        xc = node_q[w, node_offset + hc]
        xa = node_q[w, node_offset + hc - 1]
        xb = node_q[w, node_offset + hc + 1]
        lv = 0.5 * (wp.length(xc - xa) + wp.length(xb - xc))
        if lv > 0.0:
            kappa = (safe_normalize(xb - xc) - safe_normalize(xc - xa)) / lv
        k2 = wp.dot(kappa, kappa)
        if k2 > 0.0:
            centre = xc + kappa / k2
            k_perp = kappa - wp.dot(kappa, t) * t
            has_centre = 1

    # Guard planes: the neighbouring rings', and for a body ring at a tube's end (3+ hubs) a
    # virtual ring one hub beyond it, continuing the last segment's bend (the end ring is normal to
    # its edge, not to the bend, and would otherwise reach behind its hub near the centre of
    # curvature). Cap rings, which lie beyond the end ring, are not limited by the virtual ring.
    g_prev = has_prev
    xg_prev = x_prev
    tg_prev = t_prev
    g_next = has_next
    xg_next = x_next
    tg_next = t_next
    if last - first >= 2 and kind == RING_BODY:
        if has_prev == 0:
            e = safe_normalize(x_next - x)
            t_star = 2.0 * wp.dot(t_next, e) * e - t_next
            xg_prev = x - rotate_minimal(t_next, t_star, x_next - x)
            tg_prev = rotate_minimal(t_next, t_star, t_star)
            g_prev = 2
        if has_next == 0:
            e = safe_normalize(x - x_prev)
            t_star = 2.0 * wp.dot(t_prev, e) * e - t_prev
            xg_next = x + rotate_minimal(t_prev, t_star, x - x_prev)
            tg_next = rotate_minimal(t_prev, t_star, t_star)
            g_next = 2

    if kind == RING_POLE:
        mean = float(0.0)
        for k in range(spoke_count):
            mean += spoke_length[pw, h, k]
        d = c * t
        length = spoke_length_at(
            mean / float(spoke_count), d, x, g_prev, xg_prev, tg_prev, g_next, xg_next, tg_next, has_centre, centre, k_perp, guard_reach
        )
        v = ring_vertex[ring]
        surface_q_out[w, v] = x + length * d
        surface_n_out[w, v] = d
        return

    dphi = 2.0 * wp.pi / float(spoke_count)
    phi = float(j) * dphi
    u = wp.cos(phi) * r + wp.sin(phi) * s
    u_perp = wp.cross(t, u)
    d = c * t + sn * u
    length = spoke_length_at(
        spoke_length[pw, h, j], d, x, g_prev, xg_prev, tg_prev, g_next, xg_next, tg_next, has_centre, centre, k_perp, guard_reach
    )

    # Around the ring: central difference of the neighbouring spokes' (guarded) lengths.
    jm = (j + spoke_count - 1) % spoke_count
    jp = (j + 1) % spoke_count
    d_m = c * t + sn * (wp.cos(phi - dphi) * r + wp.sin(phi - dphi) * s)
    d_p = c * t + sn * (wp.cos(phi + dphi) * r + wp.sin(phi + dphi) * s)
    length_m = spoke_length_at(
        spoke_length[pw, h, jm], d_m, x, g_prev, xg_prev, tg_prev, g_next, xg_next, tg_next, has_centre, centre, k_perp, guard_reach
    )
    length_p = spoke_length_at(
        spoke_length[pw, h, jp], d_p, x, g_prev, xg_prev, tg_prev, g_next, xg_next, tg_next, has_centre, centre, k_perp, guard_reach
    )
    n = d - ((length_p - length_m) / (2.0 * dphi * length * sn)) * u_perp

    if kind == RING_BODY:
        # Along the tube: the given lengths of the neighbouring hubs over their chords.
        l_prev = wp.length(x - x_prev)
        l_next = wp.length(x_next - x)
        dl = float(0.0)
        ds = l_prev + l_next
        if has_prev != 0 and has_next != 0:
            dl = spoke_length[pw, h + 1, j] - spoke_length[pw, h - 1, j]
        elif has_next != 0:
            dl = spoke_length[pw, h + 1, j] - spoke_length[pw, h, j]
        elif has_prev != 0:
            dl = spoke_length[pw, h, j] - spoke_length[pw, h - 1, j]
        stretch = wp.max(1.0 - length * wp.dot(kappa, u), MIN_STRETCH)
        if ds > 0.0:
            n = n - (dl / (ds * stretch)) * t

    v = ring_vertex[ring] + j
    surface_q_out[w, v] = x + length * d
    surface_n_out[w, v] = wp.normalize(n)


@wp.kernel(enable_backward=False)
def shade_orthographic_kernel(
    # model:
    mesh: wp.uint64,
    origin: wp.vec3,
    right: wp.vec3,
    up: wp.vec3,
    view_dir: wp.vec3,
    pixel_size: float,
    max_dist: float,
    # out:
    image_out: wp.array2d[float],
):
    """Lambert shading of a surface seen by an orthographic camera; one thread per pixel.

    Args:
        mesh: ``wp.Mesh`` id of the surface.
        origin: centre of the image plane [length unit], behind the surface along ``view_dir``.
        right, up: unit image axes; ``view_dir``: unit viewing direction.
        pixel_size: pixel pitch on the image plane [length unit].
        max_dist: longest ray [length unit].
        image_out: brightness in [0, 1] of each (row, column) pixel, -1 where no surface is hit;
            row 0 at the top. Two-sided: ``0.2 + 0.8 |n . view_dir|`` (light from the camera).
    """
    row, col = wp.tid()
    rows = image_out.shape[0]
    cols = image_out.shape[1]
    p = (
        origin
        + (float(col) + 0.5 - 0.5 * float(cols)) * pixel_size * right
        + (0.5 * float(rows) - float(row) - 0.5) * pixel_size * up
    )
    q = wp.mesh_query_ray(mesh, p, view_dir, max_dist)
    if q.result:
        n = wp.normalize(q.normal)
        image_out[row, col] = 0.2 + 0.8 * wp.abs(wp.dot(n, view_dir))
    else:
        image_out[row, col] = -1.0
