"""Boundary points and normals of the hubs-and-spokes surface (Warp): per-hub data, then one thread per spoke.

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

Cells of folded-back parts. The planes above only separate rings that fan around a common axis
(neighbours, and rings of one bend). Where the tube folds back on itself within a few radii (a
hairpin, radius x curvature > 1 at its bend, legs closer than two radii) the facing rings of the
two legs lie side by side in nearly parallel planes, and nothing above stops their spokes: the legs
overlap. So each spoke is also limited, at the same fraction ``g``, by the *cell plane* between its
hub ``x`` and every hub ``x_k`` of the same tube that

- is at least :data:`CELL_MIN_GAP` hubs away (closer hubs are left to the planes above, so tubes
  with fewer hubs than that per ``pi`` radii keep exactly the guard above),
- lies less than ``pi r`` away along the centerline (sum of chords; ``r`` the mean spoke length
  of the prim: the radius of a circular tube), and
- is close enough for the two rings to meet: ``|x_k - x| < R + R_k`` (``R``, ``R_k`` the hubs'
  largest spoke lengths).

The cell plane is normal to ``e = x_k - x`` through ``x + e R / (R + R_k)``, splitting the
distance between the hubs in the ratio of their radii (the bisector plane for equal radii), so
``L <= g (|e|^2 R / (R + R_k)) / (d . e)`` where ``d . e > 0``. Both hubs of a pair use the same
plane, so the spoke ends of the two rings stay on opposite sides of it, each at least ``(1 - g)``
of its way short of it. On a circular arc every cell plane contains the arc's axis, as the ring
planes do, so it limits no spoke further than the centre of curvature's plane already does.

Cost in shape: where the guard acts the inner side of a ring is cut flat along a straight chord at
distance ``g rho`` from the hub (``rho`` the bend radius; about ``2/3 g rho`` at an end ring), parallel
to the bend axis: the cross-section loses the circular segment beyond that chord and the inner wall
becomes a thin surface of revolution of radius ``(1 - g) rho`` around the bend axis. On a circular
tube it acts only where ``radius x curvature > g`` for the innermost spoke; below that the surface is
exact. Where two legs of a fold lie side by side ``D`` apart (``D < 2 r``, circular tube), each
leg's facing side is cut flat at ``g D / 2`` from its hub, parallel to the other leg: the legs keep a
gap of ``(1 - g) D`` between them instead of passing through each other.

Work split. :func:`hub_guard_kernel` (one thread per (world, hub)) does everything that depends on
the hub only: the curvature vector, the chord lengths, the three guard planes (neighbours' or
virtual rings', and the centre of curvature's, each relative to the hub), the range of hubs whose
cell planes may shorten one of its spokes (found by walking the centerline ``pi`` radii each way,
from :data:`CELL_MIN_GAP` hubs on; on a straight or gently bent tube no hub is close enough, the
range stays empty and the walk is the only cost) and two *free lengths*: bounds below which no
plane (cell planes included) can shorten a spoke of the hub's body ring or of any ring.
A spoke no longer than its ring's free length keeps its given length (exactly: the guard only
takes minima with larger values), so only the others are guarded: :func:`ring_guard_kernel` (one
thread per (world, ring, spoke)) writes their guarded lengths, five plane tests each plus one per
hub of the cell range whose ring can reach (the hub kernel's range, re-tested with
``|x_k - x| < R + R_k``; hubs in it that the hub kernel passed over cannot limit a spoke of the
hub, so the result is the same as with those it picked), and leaves the rest unwritten; it runs
a thread per (world, ring) that returns at once where the ring's largest spoke is within its free
length.
:func:`spoke_points_kernel` (one thread per (world, ring, spoke), spokes fastest, so consecutive
threads write consecutive vertices) takes each of its spoke's and its two neighbours' lengths (for
the normal) from there or, by the same test, as given. The points kernel
holds no guard code, which keeps its register count (and so the GPU's occupancy) at that of the
plain spoke geometry.
"""

import functools

import warp as wp

from .frames import (
    hub_local_frame,
    hub_tangent,
    reflect_frame,
    reflection_pair_a,
    reflection_pair_b,
    rotate_minimal,
    safe_normalize,
    tube_rotation_minimizing_frames,
    tube_start_normal,
)

RING_BODY = wp.constant(0)
RING_CAP = wp.constant(1)
RING_POLE = wp.constant(2)
MIN_STRETCH = wp.constant(1.0e-2)
"""Floor of ``1 - L kappa . u`` (the surface's stretch along the tube at a spoke end) in normals."""
VIRTUAL_BLEND = wp.constant(0.9)
"""Reach (fraction of the distance to the centre of curvature) where an end ring starts to feel the
virtual ring beyond the tube's end."""
FREE_MARGIN = wp.constant(1.0e-5)
"""Relative margin of a hub's free lengths (:func:`hub_guard_kernel`) against float32 round-off of
the plane distances they bound (each within a few 1e-7)."""
DIRECTION_SLACK = wp.constant(1.0e-6)
"""Slack, relative to a plane normal's length, added to the bound of ``|d . n|`` for a body spoke:
covers ``d`` (built from float32 ``r``, ``s``) being orthogonal to ``t`` only to a few 1e-7."""
CELL_MIN_GAP = wp.constant(6)
"""Fewest hubs between two hubs whose cell plane limits their spokes: nearer hubs are separated by
the neighbour-ring and centre-of-curvature planes alone, as before the cell guard."""
CELL_WINDOW = wp.constant(3.14159265)
"""Reach of the cell guard along the centerline, in multiples of the tube's radius (mean spoke
length): ``pi``, that of the no-local-self-intersection requirement."""
PLANE_PREV = wp.constant(0)
PLANE_NEXT = wp.constant(1)
PLANE_CENTRE = wp.constant(2)

#: Options of the surface kernels' modules: fast approximate division and square root on CUDA
#: (Warp's CPU compiler ignores the option, so CPU results are unchanged by it).
CUDA_OPTIONS = {"fast_math": True}


@wp.func
def plane_reach(d: wp.vec3, plane: wp.vec4) -> float:
    """Distance [length unit] along unit ``d`` from a hub to a plane given relative to that hub,
    where the ray heads into it; -1 where it does not.

    ``plane``: normal ``n`` (not necessarily unit) in ``xyz`` and ``n . (p - x)`` in ``w``, for any
    point ``p`` of the plane and the hub ``x``; all zero for no plane (never reached).
    """
    num = plane[3]
    den = wp.dot(d, wp.vec3(plane[0], plane[1], plane[2]))
    if num * den > 0.0:
        return num / den
    return -1.0


@wp.func
def hub_plane(x: wp.vec3, p: wp.vec3, n: wp.vec3) -> wp.vec4:
    """The plane through ``p`` normal to ``n`` relative to hub ``x``, as :func:`plane_reach` reads it."""
    return wp.vec4(n[0], n[1], n[2], wp.dot(p - x, n))


@wp.func
def plane_free_length(plane: wp.vec4, t: wp.vec3, reach: float, body: int) -> float:
    """Spoke length [length unit] below which ``plane`` cannot limit a spoke of the hub (frame
    tangent ``t``) under the guard ``reach``; a large value for no plane.

    A spoke ``d`` reaches the plane at ``|n . (p - x)| / |d . n|`` or never. ``|d . n| <= |n|`` for
    any ring; on a body ring (``d`` normal to ``t``) ``|d . n| <= |n - (n . t) t|``, usually far
    less. Scaled by ``reach (1 - FREE_MARGIN)`` so a spoke no longer than this keeps its length
    exactly through :func:`guarded_length`.
    """
    n = wp.vec3(plane[0], plane[1], plane[2])
    n_len = wp.length(n)
    bound = n_len
    if body != 0:
        bound = wp.length(n - wp.dot(n, t) * t) + DIRECTION_SLACK * n_len
    num = wp.abs(plane[3])
    if num * bound > 0.0:
        return reach * (1.0 - FREE_MARGIN) * num / bound
    return 1.0e30


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
def guarded_length(
    length: float,
    d: wp.vec3,
    prev_kind: int,
    plane_prev: wp.vec4,
    next_kind: int,
    plane_next: wp.vec4,
    plane_centre: wp.vec4,
    guard_reach: float,
) -> float:
    """Spoke length [length unit] after the inner-bend guard.

    Limited against the previous and next rings' planes (kind 0: none, 1: real, 2: virtual, see
    :func:`neighbour_limit`) and against the plane through the local centre of curvature normal to
    the curvature's part in the ring's plane (all zero where the hub has no centre), each given
    relative to the hub (:func:`plane_reach`).
    """
    out = length
    l_c = plane_reach(d, plane_centre)
    if prev_kind != 0:
        out = wp.min(out, neighbour_limit(length, prev_kind, plane_reach(d, plane_prev), l_c, guard_reach))
    if next_kind != 0:
        out = wp.min(out, neighbour_limit(length, next_kind, plane_reach(d, plane_next), l_c, guard_reach))
    if l_c > 0.0:
        out = wp.min(out, guard_reach * l_c)
    return out


@wp.func
def cell_plane(e: wp.vec3, reach: float, reach_k: float) -> wp.vec4:
    """The cell plane between a hub and hub ``x + e`` relative to the hub (see :func:`plane_reach`):
    normal to ``e``, through ``x + e reach / (reach + reach_k)``; ``reach``, ``reach_k`` the hubs'
    largest spoke lengths [length unit]."""
    return wp.vec4(e[0], e[1], e[2], wp.dot(e, e) * reach / (reach + reach_k))


@wp.func
def cell_limit(
    length: float,
    d: wp.vec3,
    x: wp.vec3,
    reach: float,
    h: int,
    cell: wp.vec2i,
    w: int,
    pw: int,
    node_offset: int,
    node_q: wp.array2d[wp.vec3],
    hub_reach: wp.array2d[float],
    guard_reach: float,
) -> float:
    """Spoke length [length unit] after the cell planes of the hubs in ``cell[0] .. h - CELL_MIN_GAP``
    and ``h + CELL_MIN_GAP .. cell[1]`` whose rings can reach the hub's (``|x_k - x| < R + R_k``)."""
    out = length
    for side in range(2):
        k0 = cell[0]
        k1 = h - CELL_MIN_GAP
        if side == 1:
            k0 = h + CELL_MIN_GAP
            k1 = cell[1]
        for k in range(k0, k1 + 1):
            e = node_q[w, node_offset + k] - x
            reach_k = hub_reach[pw, k]
            if wp.dot(e, e) < (reach + reach_k) * (reach + reach_k):
                l_k = plane_reach(d, cell_plane(e, reach, reach_k))
                if l_k > 0.0:
                    out = wp.min(out, guard_reach * l_k)
    return out


@wp.func
def hub_guard(
    w: int,
    h: int,
    # model:
    node_offset: int,
    guard_reach: float,
    cell_radius: float,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    hub_reach: wp.array2d[float],
    # state in:
    node_q: wp.array2d[wp.vec3],
    hub_t: wp.array2d[wp.vec3],
    # out:
    hub_kappa_out: wp.array2d[wp.vec3],
    hub_chord_out: wp.array2d[float],
    hub_plane_out: wp.array3d[wp.vec4],
    hub_cell_out: wp.array2d[wp.vec2i],
    hub_free_out: wp.array2d[wp.vec2],
):
    """The work of one thread of :func:`hub_guard_kernel`."""
    tube = node_tube[h]
    first = tube_node_start[tube]
    last = tube_node_start[tube + 1] - 1
    x = node_q[w, node_offset + h]
    t = hub_t[w, h]
    x_prev = x
    t_prev = t
    x_next = x
    t_next = t
    if h > first:
        x_prev = node_q[w, node_offset + h - 1]
        t_prev = hub_t[w, h - 1]
    if h < last:
        x_next = node_q[w, node_offset + h + 1]
        t_next = hub_t[w, h + 1]
    hub_chord_out[w, h] = wp.length(x - x_prev) + wp.length(x_next - x)

    # Curvature vector at the hub (an end hub borrows its interior neighbour's) and the local
    # centre of curvature.
    hc = wp.clamp(h, first + 1, last - 1)
    kappa = wp.vec3(0.0)
    plane_centre = wp.vec4(0.0)
    if last - first >= 2:
        xc = node_q[w, node_offset + hc]
        xa = node_q[w, node_offset + hc - 1]
        xb = node_q[w, node_offset + hc + 1]
        lv = 0.5 * (wp.length(xc - xa) + wp.length(xb - xc))
        if lv > 0.0:
            kappa = (safe_normalize(xb - xc) - safe_normalize(xc - xa)) / lv
        k2 = wp.dot(kappa, kappa)
        if k2 > 0.0:
            plane_centre = hub_plane(x, xc + kappa / k2, kappa - wp.dot(kappa, t) * t)
    hub_kappa_out[w, h] = kappa

    # Guard planes: the neighbouring rings', and at a tube's end (3+ hubs) a virtual ring one hub
    # beyond it, continuing the last segment's bend (for body rings: the end ring is normal to its
    # edge, not to the bend, and would otherwise reach behind its hub near the centre of
    # curvature). Cap rings, which lie beyond the end ring, are not limited by the virtual ring.
    plane_prev = wp.vec4(0.0)
    plane_next = wp.vec4(0.0)
    if h > first:
        plane_prev = hub_plane(x, x_prev, t_prev)
    elif last - first >= 2:
        e = safe_normalize(x_next - x)
        t_star = 2.0 * wp.dot(t_next, e) * e - t_next
        plane_prev = hub_plane(x, x - rotate_minimal(t_next, t_star, x_next - x), rotate_minimal(t_next, t_star, t_star))
    if h < last:
        plane_next = hub_plane(x, x_next, t_next)
    elif last - first >= 2:
        e = safe_normalize(x - x_prev)
        t_star = 2.0 * wp.dot(t_prev, e) * e - t_prev
        plane_next = hub_plane(x, x + rotate_minimal(t_prev, t_star, x - x_prev), rotate_minimal(t_prev, t_star, t_star))
    hub_plane_out[w, h, PLANE_PREV] = plane_prev
    hub_plane_out[w, h, PLANE_NEXT] = plane_next
    hub_plane_out[w, h, PLANE_CENTRE] = plane_centre

    free_body = wp.min(
        plane_free_length(plane_centre, t, guard_reach, 1),
        wp.min(plane_free_length(plane_prev, t, guard_reach, 1), plane_free_length(plane_next, t, guard_reach, 1)),
    )
    free_any = plane_free_length(plane_centre, t, guard_reach, 0)
    if h > first:
        free_any = wp.min(free_any, plane_free_length(plane_prev, t, guard_reach, 0))
    if h < last:
        free_any = wp.min(free_any, plane_free_length(plane_next, t, guard_reach, 0))

    # Cell planes: walk the centerline both ways, less than pi radii, and keep the farthest hubs,
    # CELL_MIN_GAP or more away, whose cell plane can shorten one of this hub's spokes (free length
    # below the hub's largest spoke). Every hub between them and the hub lies in the window too.
    if guard_reach > 0.0:
        pw = w % hub_reach.shape[0]
        reach = hub_reach[pw, h]
        window = CELL_WINDOW * cell_radius
        cell = wp.vec2i(h, h)
        for side in range(2):
            step = 2 * side - 1
            k = h + step
            arc = float(0.0)
            x_k = x
            while k >= first and k <= last and arc < window:
                x_prev_k = x_k
                x_k = node_q[w, node_offset + k]
                arc += wp.length(x_k - x_prev_k)
                reach_k = hub_reach[pw, k]
                e = x_k - x
                near = wp.dot(e, e) < (reach + reach_k) * (reach + reach_k)
                if (k - h) * step >= CELL_MIN_GAP and arc < window and near:
                    plane = cell_plane(e, reach, reach_k)
                    body_free = plane_free_length(plane, t, guard_reach, 1)
                    any_free = plane_free_length(plane, t, guard_reach, 0)
                    # Cap rings (any direction) only at a tube's ends.
                    if body_free < reach or (any_free < reach and (h == first or h == last)):
                        cell[side] = k
                        free_body = wp.min(free_body, body_free)
                        free_any = wp.min(free_any, any_free)
                k += step
        hub_cell_out[w, h] = cell
    hub_free_out[w, h] = wp.vec2(free_body, free_any)


@wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
def hub_guard_kernel(
    # model:
    node_offset: int,
    guard_reach: float,
    cell_radius: float,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    hub_reach: wp.array2d[float],
    # state in:
    node_q: wp.array2d[wp.vec3],
    hub_t: wp.array2d[wp.vec3],
    # out:
    hub_kappa_out: wp.array2d[wp.vec3],
    hub_chord_out: wp.array2d[float],
    hub_plane_out: wp.array3d[wp.vec4],
    hub_cell_out: wp.array2d[wp.vec2i],
    hub_free_out: wp.array2d[wp.vec2],
):
    """Per-hub data of the spokes: curvature, chords, guard planes; one thread per (world, hub).

    Args:
        node_offset: column of ``node_q`` holding hub 0.
        guard_reach: inner-bend guard fraction in (0, 1); 0 turns the guard off.
        cell_radius: the tube's radius for the cell guard's window [length unit]: hubs less than
            ``CELL_WINDOW cell_radius`` apart along the centerline (the prim's mean spoke length).
        tube_node_start: first hub of each tube, (tube_count + 1,).
        node_tube: tube of each hub, (node_count,).
        hub_reach: largest spoke length of each hub [length unit], shape (1 or world_count,
            node_count).
        node_q: hub positions [length unit], shape (world_count, >= node_offset + node_count).
        hub_t: hub unit tangents [1], shape (world_count, node_count).
        hub_kappa_out: curvature vector [1/length unit] (an end hub's is its interior neighbour's;
            zero for a tube of 2 hubs), shape (world_count, node_count).
        hub_chord_out: sum of the lengths of the hub's edges [length unit] (one at a tube's end),
            shape (world_count, node_count).
        hub_plane_out: guard planes relative to the hub (see :func:`plane_reach`), shape
            (world_count, node_count, 3): :data:`PLANE_PREV`, :data:`PLANE_NEXT` (the neighbour
            rings', or at a tube's end of 3+ hubs the virtual ring's, read by body rings only) and
            :data:`PLANE_CENTRE`; zero where none.
        hub_cell_out: cell range ``(first, last)``: the farthest hubs before and after, at least
            :data:`CELL_MIN_GAP` hubs away, whose cell planes may shorten a spoke of the hub
            (``first > h - CELL_MIN_GAP`` and ``last < h + CELL_MIN_GAP`` for none; the hub itself
            when none), shape (world_count, node_count); written with the guard on only.
        hub_free_out: free lengths [length unit] (see :func:`plane_free_length`): of a body ring's
            spokes (all three planes and the cell planes) and of any ring's (real neighbours, the
            centre and the cell planes), shape (world_count, node_count).
    """
    w, h = wp.tid()
    hub_guard(w, h, node_offset, guard_reach, cell_radius, tube_node_start, node_tube, hub_reach, node_q, hub_t, hub_kappa_out, hub_chord_out, hub_plane_out, hub_cell_out, hub_free_out)


@wp.func
def ring_guard_kinds(h: int, kind: int, first: int, last: int) -> wp.vec2i:
    """Kinds of a ring's previous and next guard planes (see :func:`guarded_length`): real
    neighbours, else for a body ring at the end of a tube of 3+ hubs the virtual ring."""
    prev_kind = int(h > first)
    next_kind = int(h < last)
    if kind == RING_BODY and last - first >= 2:
        if prev_kind == 0:
            prev_kind = 2
        if next_kind == 0:
            next_kind = 2
    return wp.vec2i(prev_kind, next_kind)


@wp.func
def pole_length(spoke_length: wp.array3d[float], pw: int, h: int) -> float:
    """Length of a cap's pole spoke [length unit]: the mean of its hub's spoke lengths."""
    spoke_count = spoke_length.shape[2]
    mean = float(0.0)
    for k in range(spoke_count):
        mean += spoke_length[pw, h, k]
    return mean / float(spoke_count)


@wp.func
def spoke_guard(
    w: int,
    ring: int,
    j: int,
    # model:
    node_offset: int,
    guard_reach: float,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    hub_reach: wp.array2d[float],
    ring_hub: wp.array[wp.int32],
    ring_kind: wp.array[wp.int32],
    ring_cos: wp.array[float],
    ring_sin: wp.array[float],
    ring_vertex: wp.array[wp.int32],
    spoke_cos: wp.array[float],
    spoke_sin: wp.array[float],
    spoke_length: wp.array3d[float],
    # state in:
    node_q: wp.array2d[wp.vec3],
    hub_t: wp.array2d[wp.vec3],
    hub_r: wp.array2d[wp.vec3],
    hub_plane: wp.array3d[wp.vec4],
    hub_cell: wp.array2d[wp.vec2i],
    hub_free: wp.array2d[wp.vec2],
    # out:
    surface_length_out: wp.array2d[float],
):
    """The work of one thread of :func:`ring_guard_kernel`."""
    kind = ring_kind[ring]
    if kind == RING_POLE and j > 0:
        return
    h = ring_hub[ring]
    pw = w % spoke_length.shape[0]
    free = hub_free[w, h]
    t = hub_t[w, h]
    c = ring_cos[ring]
    sn = ring_sin[ring]
    length = float(0.0)
    d = c * t
    if kind == RING_POLE:
        length = pole_length(spoke_length, pw, h)
        if length <= free[1]:
            return
    else:
        length = spoke_length[pw, h, j]
        limit = free[1]
        if kind == RING_BODY:
            limit = free[0]
        if length <= limit:
            return
        r = hub_r[w, h]
        d = c * t + sn * (spoke_cos[j] * r + spoke_sin[j] * wp.cross(t, r))
    tube = node_tube[h]
    kinds = ring_guard_kinds(h, kind, tube_node_start[tube], tube_node_start[tube + 1] - 1)
    out = guarded_length(
        length, d, kinds[0], hub_plane[w, h, PLANE_PREV], kinds[1], hub_plane[w, h, PLANE_NEXT],
        hub_plane[w, h, PLANE_CENTRE], guard_reach,
    )  # fmt: skip
    cell = hub_cell[w, h]
    if cell[0] <= h - CELL_MIN_GAP or cell[1] >= h + CELL_MIN_GAP:
        x = node_q[w, node_offset + h]
        out = cell_limit(out, d, x, hub_reach[pw, h], h, cell, w, pw, node_offset, node_q, hub_reach, guard_reach)
    surface_length_out[w, ring_vertex[ring] + j] = out


@wp.func
def ring_guard(
    w: int,
    ring: int,
    node_offset: int,
    guard_reach: float,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    hub_reach: wp.array2d[float],
    ring_hub: wp.array[wp.int32],
    ring_kind: wp.array[wp.int32],
    ring_cos: wp.array[float],
    ring_sin: wp.array[float],
    ring_vertex: wp.array[wp.int32],
    spoke_cos: wp.array[float],
    spoke_sin: wp.array[float],
    spoke_length: wp.array3d[float],
    node_q: wp.array2d[wp.vec3],
    hub_t: wp.array2d[wp.vec3],
    hub_r: wp.array2d[wp.vec3],
    hub_plane: wp.array3d[wp.vec4],
    hub_cell: wp.array2d[wp.vec2i],
    hub_free: wp.array2d[wp.vec2],
    surface_length_out: wp.array2d[float],
):
    """Guarded lengths of one ring's spokes (:func:`spoke_guard`), none where the hub's largest
    spoke is within the ring's free length."""
    h = ring_hub[ring]
    free = hub_free[w, h]
    limit = free[1]
    if ring_kind[ring] == RING_BODY:
        limit = free[0]
    if hub_reach[w % hub_reach.shape[0], h] > limit:
        for j in range(spoke_cos.shape[0]):
            spoke_guard(
                w, ring, j, node_offset, guard_reach, tube_node_start, node_tube, hub_reach, ring_hub, ring_kind,
                ring_cos, ring_sin, ring_vertex, spoke_cos, spoke_sin, spoke_length, node_q, hub_t, hub_r,
                hub_plane, hub_cell, hub_free, surface_length_out,
            )  # fmt: skip


@wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
def ring_guard_kernel(
    # model:
    node_offset: int,
    guard_reach: float,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    hub_reach: wp.array2d[float],
    ring_hub: wp.array[wp.int32],
    ring_kind: wp.array[wp.int32],
    ring_cos: wp.array[float],
    ring_sin: wp.array[float],
    ring_vertex: wp.array[wp.int32],
    spoke_cos: wp.array[float],
    spoke_sin: wp.array[float],
    spoke_length: wp.array3d[float],
    # state in:
    node_q: wp.array2d[wp.vec3],
    hub_t: wp.array2d[wp.vec3],
    hub_r: wp.array2d[wp.vec3],
    hub_plane: wp.array3d[wp.vec4],
    hub_cell: wp.array2d[wp.vec2i],
    hub_free: wp.array2d[wp.vec2],
    # out:
    surface_length_out: wp.array2d[float],
):
    """Guarded length of each spoke longer than its ring's free length; one thread per
    (world, ring), which skips the ring at once where its hub's largest spoke is within the ring's
    free length (all but the rings of sharp bends and folds) and otherwise takes its spokes in
    turn. Other entries are left as they are (and not read).

    Args:
        node_offset: column of ``node_q`` holding hub 0.
        guard_reach: inner-bend guard fraction in (0, 1).
        tube_node_start, node_tube, ring_*, spoke_cos, spoke_sin, spoke_length: as
            :func:`spoke_points_kernel`.
        hub_reach: largest spoke length of each hub [length unit], shape (1 or world_count,
            node_count).
        node_q: hub positions [length unit], shape (world_count, >= node_offset + node_count).
        hub_t, hub_r: hub unit tangents and normals [1], shape (world_count, node_count).
        hub_plane, hub_cell, hub_free: per-hub data from :func:`hub_guard_kernel`.
        surface_length_out: guarded spoke lengths [length unit], shape (world_count, vertex_count).
    """
    w, ring = wp.tid()
    ring_guard(
        w, ring, node_offset, guard_reach, tube_node_start, node_tube, hub_reach, ring_hub, ring_kind, ring_cos,
        ring_sin, ring_vertex, spoke_cos, spoke_sin, spoke_length, node_q, hub_t, hub_r, hub_plane, hub_cell,
        hub_free, surface_length_out,
    )  # fmt: skip


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
    """Lengths [length unit] of spoke ``j`` of a ring (first vertex ``v0``) and of its two
    neighbours in the ring: given, or the guard's where longer than the ring's free length (the
    test of :func:`spoke_guard`)."""
    jm = j - 1
    if j == 0:
        jm = spoke_count - 1
    jp = j + 1
    if jp == spoke_count:
        jp = 0
    length = spoke_length[pw, h, j]
    length_m = spoke_length[pw, h, jm]
    length_p = spoke_length[pw, h, jp]
    if guard:
        limit = free[1]
        if kind == RING_BODY:
            limit = free[0]
        if length > limit:
            length = surface_length[w, v0 + j]
        if length_m > limit:
            length_m = surface_length[w, v0 + jm]
        if length_p > limit:
            length_p = surface_length[w, v0 + jp]
    return length, length_m, length_p


@wp.func
def pole_point(
    x: wp.vec3,
    t: wp.vec3,
    c: float,
    w: int,
    pw: int,
    h: int,
    v0: int,
    guard: bool,
    free: wp.vec2,
    spoke_length: wp.array3d[float],
    surface_length: wp.array2d[float],
) -> wp.vec3:
    """End [length unit] of a cap's pole spoke (vertex ``v0``, along ``c t`` from hub ``x``): the
    mean of the hub's spoke lengths, or the guard's where longer than the ring's free length."""
    length = pole_length(spoke_length, pw, h)
    if guard and length > free[1]:
        length = surface_length[w, v0]
    return x + length * (c * t)


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
    limit = free[1]
    if kind == RING_BODY:
        limit = free[0]
    dl = float(0.0)
    uniform = hub_uniform[pw, h] != 0 and not (guard and length > limit)
    if uniform:
        tube = node_tube[h]
        has_prev = int(h > tube_node_start[tube])
        has_next = int(h < tube_node_start[tube + 1] - 1)
        dl = body_length_step(pw, h, 0, has_prev, has_next, spoke_length)
    return uniform, length, dl


@wp.func
def ring_vertices(
    w: int,
    pw: int,
    ring: int,
    j_first: int,
    j_step: int,
    node_offset: int,
    spoke_count: int,
    guard: bool,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    ring_hub: wp.array[wp.int32],
    ring_kind: wp.array[wp.int32],
    ring_cos: wp.array[float],
    ring_sin: wp.array[float],
    ring_vertex: wp.array[wp.int32],
    spoke_cos: wp.array[float],
    spoke_sin: wp.array[float],
    spoke_length: wp.array3d[float],
    hub_uniform: wp.array2d[wp.int32],
    node_q: wp.array2d[wp.vec3],
    hub_t: wp.array2d[wp.vec3],
    hub_r: wp.array2d[wp.vec3],
    hub_kappa: wp.array2d[wp.vec3],
    hub_chord: wp.array2d[float],
    hub_free: wp.array2d[wp.vec2],
    surface_length: wp.array2d[float],
    surface_q_out: wp.array2d[wp.vec3],
    surface_n_out: wp.array2d[wp.vec3],
    lo: wp.vec3,
    hi: wp.vec3,
):
    """Write spokes ``j_first, j_first + j_step, ...`` of one ring (a pole ring's one vertex when
    ``j_first`` is 0); returns ``lo``, ``hi`` widened by the points written.

    A ring whose hub and neighbours have equal spoke lengths all round (``hub_uniform``, a
    circular tube) and that the guard leaves alone reads its length and its step along the tube
    once: the same values the per-spoke reads give, so the same points and normals.
    """
    kind = ring_kind[ring]
    h = ring_hub[ring]
    x = node_q[w, node_offset + h]
    t = hub_t[w, h]
    c = ring_cos[ring]
    free = hub_free[w, h]
    v0 = ring_vertex[ring]
    out_lo = lo
    out_hi = hi
    if kind == RING_POLE:
        if j_first == 0:
            p = pole_point(x, t, c, w, pw, h, v0, guard, free, spoke_length, surface_length)
            surface_q_out[w, v0] = p
            surface_n_out[w, v0] = c * t
            out_lo = wp.min(out_lo, p)
            out_hi = wp.max(out_hi, p)
        return out_lo, out_hi
    tube = node_tube[h]
    has_prev = int(h > tube_node_start[tube])
    has_next = int(h < tube_node_start[tube + 1] - 1)
    sn = ring_sin[ring]
    r = hub_r[w, h]
    s = wp.cross(t, r)
    kappa = hub_kappa[w, h]
    ds = hub_chord[w, h]
    dphi = 2.0 * wp.pi / float(spoke_count)
    uniform, length, dl = uniform_ring(pw, h, kind, guard, free, tube_node_start, node_tube, spoke_length, hub_uniform)
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
            x, t, r, s, c, sn, kind, spoke_cos[j], spoke_sin[j], length_j, length_m, length_p, dphi, dl_j, kappa, ds
        )  # fmt: skip
        surface_q_out[w, v0 + j] = p
        surface_n_out[w, v0 + j] = n
        out_lo = wp.min(out_lo, p)
        out_hi = wp.max(out_hi, p)
    return out_lo, out_hi


@wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
def ring_info_kernel(
    # model:
    guard_reach: float,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    ring_hub: wp.array[wp.int32],
    ring_kind: wp.array[wp.int32],
    spoke_length: wp.array3d[float],
    hub_uniform: wp.array2d[wp.int32],
    # state in:
    hub_chord: wp.array2d[float],
    hub_free: wp.array2d[wp.vec2],
    # out:
    ring_info_out: wp.array2d[wp.vec4],
):
    """Sort one ring for the spoke kernels; one thread per (world, ring).

    Writes ``(length, dl, ds, 1 + kind)`` for a uniform ring (a circular one the guard leaves alone,
    see :func:`ring_vertices`; ``kind`` :data:`RING_BODY` or :data:`RING_CAP`): its spokes' common
    length, the length's step along the tube and the hub's chord sum [length unit], all that
    :func:`spoke_points_kernel` needs beyond the hub's frame; ``(0, 0, 0, 0)`` for any other ring
    (pole, measured or guarded), left to :func:`spoke_points_general_kernel`.

    Args: as :func:`spoke_points_kernel`; ``ring_info_out`` shaped (world_count, ring_count).
    """
    w, ring = wp.tid()
    pw = w % spoke_length.shape[0]
    h = ring_hub[ring]
    kind = ring_kind[ring]
    out = wp.vec4(0.0)
    if kind != RING_POLE:
        uniform, length, dl = uniform_ring(
            pw, h, kind, guard_reach > 0.0, hub_free[w, h], tube_node_start, node_tube, spoke_length, hub_uniform
        )  # fmt: skip
        if uniform:
            out = wp.vec4(length, dl, hub_chord[w, h], float(1 + kind))
    ring_info_out[w, ring] = out


@wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
def spoke_points_kernel(
    node_offset: int,
    node_row: int,
    hub_count: int,
    spoke_count: int,
    vertex_count: int,
    ring_geom: wp.array[wp.vec4],
    spoke_cs: wp.array[wp.vec2],
    ring_info: wp.array[wp.vec4],
    node_q: wp.array[wp.vec3],
    hub_t: wp.array[wp.vec3],
    hub_r: wp.array[wp.vec3],
    hub_kappa: wp.array[wp.vec3],
    # out:
    surface_q_out: wp.array[wp.vec3],
    surface_n_out: wp.array[wp.vec3],
):
    """Write one spoke's boundary point and unit normal; one thread per (world, ring, spoke), the
    spoke index fastest. Uniform rings only (``ring_info`` from :func:`ring_info_kernel` nonzero
    in its last entry); :func:`spoke_points_general_kernel` writes the others. Kept to the common
    case, with its per-world arrays flattened to one dimension and its tables packed, so that a
    thread needs few registers and little index arithmetic; the arithmetic is
    :func:`ring_vertices`', so the points and normals are the same.

    Args:
        node_offset: column of ``node_q`` holding hub 0; ``node_row``: its row length (vec3).
        hub_count, spoke_count, vertex_count: hubs N, spokes S and vertices V per world.
        ring_geom: per ring ``(cos theta, sin theta, hub, first vertex)`` (indices as exact
            floats), (ring_count,).
        spoke_cs: ``(cos phi_j, sin phi_j)`` of each spoke, (S,).
        ring_info: per (world, ring) ``(length, dl, ds, 1 + kind or 0)``, (world_count * ring_count,).
        node_q: hub positions [length unit], flattened rows of ``node_row``.
        hub_t, hub_r: hub unit tangents and normals [1], (world_count * N,).
        hub_kappa: hub curvature vectors [1/length unit], (world_count * N,).
        surface_q_out: boundary points [length unit], (world_count * V,).
        surface_n_out: unit outward normals [1], (world_count * V,).
    """
    w, ring, j = wp.tid()
    info = ring_info[w * ring_geom.shape[0] + ring]
    if info[3] == 0.0:
        return
    g = ring_geom[ring]
    h = int(g[2])
    wh = w * hub_count + h
    t = hub_t[wh]
    r = hub_r[wh]
    cs = spoke_cs[j]
    length = info[0]
    p, n = spoke_point_normal(
        node_q[w * node_row + node_offset + h], t, r, wp.cross(t, r), g[0], g[1], int(info[3]) - 1, cs[0], cs[1],
        length, length, length, 2.0 * wp.pi / float(spoke_count), info[1], hub_kappa[wh], info[2],
    )  # fmt: skip
    v = w * vertex_count + int(g[3]) + j
    surface_q_out[v] = p
    surface_n_out[v] = n


@wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
def spoke_points_general_kernel(
    # model:
    node_offset: int,
    spoke_count: int,
    lanes: int,
    guard_reach: float,
    tube_node_start: wp.array[wp.int32],
    node_tube: wp.array[wp.int32],
    ring_hub: wp.array[wp.int32],
    ring_kind: wp.array[wp.int32],
    ring_cos: wp.array[float],
    ring_sin: wp.array[float],
    ring_vertex: wp.array[wp.int32],
    spoke_cos: wp.array[float],
    spoke_sin: wp.array[float],
    spoke_length: wp.array3d[float],
    hub_uniform: wp.array2d[wp.int32],
    # state in:
    ring_info: wp.array2d[wp.vec4],
    node_q: wp.array2d[wp.vec3],
    hub_t: wp.array2d[wp.vec3],
    hub_r: wp.array2d[wp.vec3],
    hub_kappa: wp.array2d[wp.vec3],
    hub_chord: wp.array2d[float],
    hub_free: wp.array2d[wp.vec2],
    surface_length: wp.array2d[float],
    # out:
    surface_q_out: wp.array2d[wp.vec3],
    surface_n_out: wp.array2d[wp.vec3],
):
    """Write the spokes' boundary points and unit normals where :func:`spoke_points_kernel` does
    not (pole, measured or guarded rings: ``ring_info[w, ring][3] == 0``), through
    :func:`ring_vertices`; one thread per (world, ring, lane), lane ``k`` writing spokes
    ``k, k + lanes, ...``, returning at once for the other rings. The host launches one lane per
    ring for circular tubes (few rings come here, so the launch costs little) and one per spoke
    for measured shapes (all rings come here).

    Args:
        node_offset: column of ``node_q`` holding hub 0.
        spoke_count: spokes per ring, S.
        lanes: threads per ring (1 or S).
        guard_reach: inner-bend guard fraction in (0, 1); 0 turns the guard off.
        tube_node_start: first hub of each tube, (tube_count + 1,).
        node_tube: tube of each hub, (node_count,).
        ring_hub, ring_kind, ring_cos, ring_sin, ring_vertex: the ring table, (ring_count,) each.
        spoke_cos, spoke_sin: ``cos phi_j``, ``sin phi_j`` of each spoke, (S,).
        spoke_length: spoke lengths [length unit], shape (1 or world_count, node_count, S).
        hub_uniform: 1 where a hub and its neighbours have one spoke length all round, shape
            (1 or world_count, node_count) (see :func:`ring_vertices`).
        ring_info: from :func:`ring_info_kernel`, (world_count, ring_count).
        node_q: hub positions [length unit], shape (world_count, >= node_offset + node_count).
        hub_t, hub_r: hub unit tangents and normals [1], shape (world_count, node_count).
        hub_kappa, hub_chord, hub_free: per-hub data from :func:`hub_guard_kernel`.
        surface_length: guarded spoke lengths from :func:`ring_guard_kernel`, read (only) for
            spokes longer than their ring's free length when the guard is on.
        surface_q_out: boundary points [length unit], shape (world_count, vertex_count).
        surface_n_out: unit outward normals [1], shape (world_count, vertex_count).
    """
    w, ring, lane = wp.tid()
    if ring_info[w, ring][3] != 0.0:
        return
    pw = w % spoke_length.shape[0]
    far = wp.vec3(1.0e30)
    ring_vertices(
        w, pw, ring, lane, lanes, node_offset, spoke_count, guard_reach > 0.0, tube_node_start, node_tube,
        ring_hub, ring_kind, ring_cos, ring_sin, ring_vertex, spoke_cos, spoke_sin, spoke_length, hub_uniform,
        node_q, hub_t, hub_r, hub_kappa, hub_chord, hub_free, surface_length, surface_q_out, surface_n_out, far, -far,
    )  # fmt: skip


@wp.struct
class SurfaceArrays:
    """Everything :func:`surface_world_kernel` reads and writes but the hub positions, in one
    struct: a recorded CPU launch sets each argument on every call (~0.3 us each), so two
    arguments instead of ~30. Fields as the kernel's arguments of the same names."""

    node_offset: int
    spoke_count: int
    guard_reach: float
    cell_radius: float
    local_frames: int
    tube_node_start: wp.array[wp.int32]
    node_tube: wp.array[wp.int32]
    node_rest_t: wp.array2d[wp.vec3]
    node_rest_r: wp.array2d[wp.vec3]
    hub_reach: wp.array2d[float]
    ring_hub: wp.array[wp.int32]
    ring_kind: wp.array[wp.int32]
    ring_cos: wp.array[float]
    ring_sin: wp.array[float]
    ring_vertex: wp.array[wp.int32]
    spoke_cos: wp.array[float]
    spoke_sin: wp.array[float]
    spoke_length: wp.array3d[float]
    hub_uniform: wp.array2d[wp.int32]
    # scratch (per-hub data and guarded lengths, as the split kernels write them):
    hub_t: wp.array2d[wp.vec3]
    hub_r: wp.array2d[wp.vec3]
    hub_kappa: wp.array2d[wp.vec3]
    hub_chord: wp.array2d[float]
    hub_plane: wp.array3d[wp.vec4]
    hub_cell: wp.array2d[wp.vec2i]
    hub_free: wp.array2d[wp.vec2]
    surface_length: wp.array2d[float]
    # out:
    surface_q_out: wp.array2d[wp.vec3]
    surface_n_out: wp.array2d[wp.vec3]
    extent_out: wp.array2d[wp.vec3]


@wp.kernel(enable_backward=False, module="unique")
def surface_world_kernel(arrays: SurfaceArrays, node_q: wp.array2d[wp.vec3]):
    """The whole rebuild of one world's surface in one thread: frames, per-hub data, guarded
    lengths, points and normals, and their bounds; one thread per world (the CPU's path: one
    launch instead of four, each ring's frame read once for its spokes).

    Same arithmetic as the split kernels (frames, :func:`hub_guard_kernel`,
    :func:`ring_guard_kernel`, :func:`spoke_points_kernel`), so both give the same points and
    normals. A ring is guarded only where its hub's largest spoke exceeds the ring's free length.

    Args:
        arrays: the fields below (:class:`SurfaceArrays`).
        node_q: hub positions [length unit], shape (world_count, >= node_offset + node_count).
        local_frames: 1 for the paper's local frames, 0 for rotation-minimizing ones.
        node_rest_t, node_rest_r: rest tangents and spoke-0 normals [1], shape (1 or world_count,
            node_count) (see :mod:`warp_tube.kernels.frames`).
        extent_out: ``[min, max]`` corner of the world's points [length unit], shape (world_count, 2).
        Others: as the split kernels.
    """
    node_offset = arrays.node_offset
    spoke_count = arrays.spoke_count
    guard_reach = arrays.guard_reach
    cell_radius = arrays.cell_radius
    local_frames = arrays.local_frames
    tube_node_start = arrays.tube_node_start
    node_tube = arrays.node_tube
    node_rest_t = arrays.node_rest_t
    node_rest_r = arrays.node_rest_r
    hub_reach = arrays.hub_reach
    ring_hub = arrays.ring_hub
    ring_kind = arrays.ring_kind
    ring_cos = arrays.ring_cos
    ring_sin = arrays.ring_sin
    ring_vertex = arrays.ring_vertex
    spoke_cos = arrays.spoke_cos
    spoke_sin = arrays.spoke_sin
    spoke_length = arrays.spoke_length
    hub_t = arrays.hub_t
    hub_r = arrays.hub_r
    hub_kappa = arrays.hub_kappa
    hub_chord = arrays.hub_chord
    hub_plane = arrays.hub_plane
    hub_cell = arrays.hub_cell
    hub_free = arrays.hub_free
    surface_length = arrays.surface_length
    surface_q_out = arrays.surface_q_out
    surface_n_out = arrays.surface_n_out
    extent_out = arrays.extent_out
    w = wp.tid()
    pw = w % spoke_length.shape[0]
    hub_count = node_tube.shape[0]
    if local_frames != 0:
        for h in range(hub_count):
            hub_local_frame(w, h, node_offset, tube_node_start, node_tube, node_rest_t, node_rest_r, node_q, hub_t, hub_r)
    else:
        for tube in range(tube_node_start.shape[0] - 1):
            tube_rotation_minimizing_frames(w, tube, node_offset, tube_node_start, node_rest_t, node_rest_r, node_q, hub_t, hub_r)
    for h in range(hub_count):
        hub_guard(
            w, h, node_offset, guard_reach, cell_radius, tube_node_start, node_tube, hub_reach, node_q, hub_t,
            hub_kappa, hub_chord, hub_plane, hub_cell, hub_free,
        )  # fmt: skip
    guard = guard_reach > 0.0
    ring_count = ring_hub.shape[0]
    if guard:
        for ring in range(ring_count):
            ring_guard(
                w, ring, node_offset, guard_reach, tube_node_start, node_tube, hub_reach, ring_hub, ring_kind,
                ring_cos, ring_sin, ring_vertex, spoke_cos, spoke_sin, spoke_length, node_q, hub_t, hub_r,
                hub_plane, hub_cell, hub_free, surface_length,
            )  # fmt: skip
    lo = wp.vec3(1.0e30)
    hi = wp.vec3(-1.0e30)
    for ring in range(ring_count):
        lo, hi = ring_vertices(
            w, pw, ring, 0, 1, node_offset, spoke_count, guard, tube_node_start, node_tube, ring_hub, ring_kind,
            ring_cos, ring_sin, ring_vertex, spoke_cos, spoke_sin, spoke_length, arrays.hub_uniform, node_q, hub_t,
            hub_r, hub_kappa, hub_chord, hub_free, surface_length, surface_q_out, surface_n_out, lo, hi,
        )  # fmt: skip
    extent_out[w, 0] = lo
    extent_out[w, 1] = hi


@wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS)
def surface_extent_kernel(
    surface_q: wp.array2d[wp.vec3],
    # out:
    extent_out: wp.array2d[wp.vec3],
):
    """``[min, max]`` corners [length unit] of each world's points, shape (world_count, 2), from
    ``surface_q`` (world_count, vertex_count); one thread per world (the split path's bounds)."""
    w = wp.tid()
    lo = wp.vec3(1.0e30)
    hi = wp.vec3(-1.0e30)
    for v in range(surface_q.shape[1]):
        p = surface_q[w, v]
        lo = wp.min(lo, p)
        hi = wp.max(hi, p)
    extent_out[w, 0] = lo
    extent_out[w, 1] = hi


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


WORLD_LANES = 32
"""Threads of :func:`make_surface_block_kernel`'s kernel per world (one warp)."""

SURFACE_RING_LANES = 8
"""Lanes of a world's warp that share a ring (at most; fewer with fewer spokes)."""


BLOCK_HUBS = 1
"""Phases of :func:`make_surface_block_kernel`'s kernel: frames, per-hub data, guarded lengths."""
BLOCK_VERTICES = 2
"""Phases of :func:`make_surface_block_kernel`'s kernel: points, normals and their bounds."""


@functools.cache
def make_surface_block_kernel(worlds_per_block: int, min_blocks: int, phases: int = BLOCK_HUBS | BLOCK_VERTICES):
    """The GPU rebuild, a warp of :data:`WORLD_LANES` threads per world, ``worlds_per_block``
    worlds per block, compiled for at least ``min_blocks`` resident blocks per multiprocessor (CUDA
    ``__launch_bounds__``; 0: no such bound), doing the ``phases`` (:data:`BLOCK_HUBS`,
    :data:`BLOCK_VERTICES` or both). Cached per arguments.

    One kernel for both keeps the per-hub data in cache between them and is the faster for
    circular tubes; one for each lets each be compiled and launched on its own (block shape,
    registers), which was the faster for measured shapes on an H100 (see
    ``warp_tube.surface.builder.BLOCK_SPLIT``)."""
    B = WORLD_LANES * int(worlds_per_block)
    bounds = (B, int(min_blocks)) if min_blocks else B
    hubs = bool(phases & BLOCK_HUBS)
    vertices = bool(phases & BLOCK_VERTICES)

    @wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS, launch_bounds=bounds)
    def surface_block_kernel(arrays: SurfaceArrays, node_q: wp.array2d[wp.vec3]):
        """A world's surface rebuilt by one warp (``wp.launch_tiled`` over blocks of
        ``worlds_per_block`` worlds): the world kernel's work spread over the warp's lanes phase by
        phase.

        With :data:`BLOCK_HUBS`:

        1. frames: local ones by a lane per hub; rotation-minimizing ones a chunk of hubs at a
           time, each step's reflections by a lane per hub, their product along the tube by the
           world's lane 0 (:func:`reflect_frame`);
        2. per-hub guard data (:func:`hub_guard`), a lane per hub;
        3. guarded lengths (:func:`ring_guard`), a lane per ring (guard on only);

        with :data:`BLOCK_VERTICES`:

        4. points and normals (:func:`ring_vertices`): :data:`SURFACE_RING_LANES` lanes to a ring,
           several rings at a time, so that a ring's reads serve several spokes and runs of
           consecutive lanes write consecutive vertices;
        5. the points' bounds, reduced over the warp (halving, five rounds) into ``extent_out``.

        A phase reads what the previous one wrote (scratch arrays in ``arrays``) after a block
        barrier (the write of one element of a shared tile, which every thread reaches). Same
        functions, so the same points and normals as the world and split kernels.

        Args:
            arrays: as :func:`surface_world_kernel`.
            node_q: hub positions [length unit], shape (world_count, >= node_offset + node_count).
        """
        node_offset = arrays.node_offset
        spoke_count = arrays.spoke_count
        guard_reach = arrays.guard_reach
        tube_node_start = arrays.tube_node_start
        node_tube = arrays.node_tube
        spoke_length = arrays.spoke_length
        hub_t = arrays.hub_t
        hub_r = arrays.hub_r
        hub_free = arrays.hub_free
        block, thread = wp.tid()
        w = block * wp.static(worlds_per_block) + thread // WORLD_LANES
        lane = thread % WORLD_LANES
        active = w < node_q.shape[0]
        pw = w % spoke_length.shape[0]
        hub_count = node_tube.shape[0]
        ring_count = arrays.ring_hub.shape[0]
        guard = guard_reach > 0.0
        if wp.static(hubs):
            barrier = wp.tile_zeros(shape=(wp.static(B),), dtype=int, storage="shared")
            step_a = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec4, storage="shared")
            step_b = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec4, storage="shared")
            step_c = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec4, storage="shared")
            r_carried = wp.vec3(0.0)

            if arrays.local_frames != 0:
                if active:
                    for h in range(lane, hub_count, WORLD_LANES):
                        hub_local_frame(w, h, node_offset, tube_node_start, node_tube, arrays.node_rest_t, arrays.node_rest_r, node_q, hub_t, hub_r)
            else:
                # Rotation-minimizing frames, a chunk of WORLD_LANES hubs at a time: every lane finds
                # its hub's tangent and the two reflections of the step that reaches it (or, at a
                # tube's first hub, its start normal), which depend on positions and tangents only;
                # then the world's lane 0 carries the normal along the chunk through them, one hub
                # after the other, so only that short product is sequential.
                base = thread - lane
                for chunk in range(0, hub_count, WORLD_LANES):
                    h = chunk + lane
                    a = wp.vec4(0.0)
                    b = wp.vec4(0.0)
                    c = wp.vec4(0.0)
                    if active and h < hub_count:
                        tube = node_tube[h]
                        start = tube_node_start[tube]
                        first = node_offset + start
                        last = node_offset + tube_node_start[tube + 1] - 1
                        t = hub_tangent(node_q, w, node_offset + h, first, last)
                        hub_t[w, h] = t
                        if h == start:
                            r = tube_start_normal(arrays.node_rest_t[pw, h], arrays.node_rest_r[pw, h], t)
                            a = wp.vec4(r[0], r[1], r[2], 0.0)
                            c = wp.vec4(t[0], t[1], t[2], 1.0)
                        else:
                            t0 = hub_tangent(node_q, w, node_offset + h - 1, first, last)
                            a = reflection_pair_a(node_q[w, node_offset + h - 1], node_q[w, node_offset + h])
                            b = reflection_pair_b(a, t0, t)
                            c = wp.vec4(t[0], t[1], t[2], 0.0)
                    step_a[thread] = a
                    step_b[thread] = b
                    step_c[thread] = c
                    if active and lane == 0:
                        for k in range(wp.min(WORLD_LANES, hub_count - chunk)):
                            a = step_a[base + k]
                            c = step_c[base + k]
                            if c[3] > 0.0:
                                r_carried = wp.vec3(a[0], a[1], a[2])
                            else:
                                r_carried = reflect_frame(r_carried, a, step_b[base + k], wp.vec3(c[0], c[1], c[2]))
                            hub_r[w, chunk + k] = r_carried
                    barrier[thread] = 4  # the chunk's steps are read before the next chunk's overwrite them
            barrier[thread] = 1
            if active:
                for h in range(lane, hub_count, WORLD_LANES):
                    hub_guard(
                        w, h, node_offset, guard_reach, arrays.cell_radius, tube_node_start, node_tube, arrays.hub_reach,
                        node_q, hub_t, arrays.hub_kappa, arrays.hub_chord, arrays.hub_plane, arrays.hub_cell, hub_free,
                    )  # fmt: skip
            barrier[thread] = 2
            if guard:
                if active:
                    for ring in range(lane, ring_count, WORLD_LANES):
                        ring_guard(
                            w, ring, node_offset, guard_reach, tube_node_start, node_tube, arrays.hub_reach, arrays.ring_hub,
                            arrays.ring_kind, arrays.ring_cos, arrays.ring_sin, arrays.ring_vertex, arrays.spoke_cos,
                            arrays.spoke_sin, spoke_length, node_q, hub_t, hub_r, arrays.hub_plane, arrays.hub_cell, hub_free,
                            arrays.surface_length,
                        )  # fmt: skip
                barrier[thread] = 3
        if wp.static(vertices):
            lows = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec3, storage="shared")
            highs = wp.tile_zeros(shape=(wp.static(B),), dtype=wp.vec3, storage="shared")
            lanes = wp.min(spoke_count, SURFACE_RING_LANES)
            rings_per_pass = WORLD_LANES // lanes
            sub = lane % lanes
            group = lane // lanes
            lo = wp.vec3(1.0e30)
            hi = wp.vec3(-1.0e30)
            if active:
                for first in range(0, ring_count, rings_per_pass):
                    ring = first + group
                    if group < rings_per_pass and ring < ring_count:
                        lo, hi = ring_vertices(
                            w, pw, ring, sub, lanes, node_offset, spoke_count, guard, tube_node_start, node_tube,
                            arrays.ring_hub, arrays.ring_kind, arrays.ring_cos, arrays.ring_sin, arrays.ring_vertex,
                            arrays.spoke_cos, arrays.spoke_sin, spoke_length, arrays.hub_uniform, node_q, hub_t, hub_r,
                            arrays.hub_kappa, arrays.hub_chord, hub_free, arrays.surface_length, arrays.surface_q_out,
                            arrays.surface_n_out, lo, hi,
                        )  # fmt: skip
            # The warp's bounds by halving: in each round the lower half takes in the upper half's
            # (which writes back what it holds, so reading it while it is written is harmless).
            lows[thread] = lo
            highs[thread] = hi
            step = int(wp.static(WORLD_LANES // 2))
            while step > 0:
                if lane < step:
                    lo = wp.min(lo, lows[thread + step])
                    hi = wp.max(hi, highs[thread + step])
                lows[thread] = lo
                highs[thread] = hi
                step = step // 2
            if active and lane == 0:
                arrays.extent_out[w, 0] = lo
                arrays.extent_out[w, 1] = hi

    return surface_block_kernel
