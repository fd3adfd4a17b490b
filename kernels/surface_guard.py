"""Inner-bend guard of the hubs-and-spokes surface (Warp): spoke lengths limited so that rings
do not cross where the tube bends tightly or folds back on itself.

Spoke ``j`` of a ring points along ``d_j`` from its hub ``x`` (:mod:`warp_tube.kernels.surface_spokes`);
``L`` is its given length.

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

Work split. :func:`hub_guard` (per hub) does everything that depends on the hub only: the
curvature vector, the chord lengths, the three guard planes (neighbours' or virtual rings', and the
centre of curvature's, each relative to the hub), the range of hubs whose cell planes may shorten
one of its spokes (found by walking the centerline ``pi`` radii each way, from
:data:`CELL_MIN_GAP` hubs on; on a straight or gently bent tube no hub is close enough, the range
stays empty and the walk is the only cost) and two *free lengths*: bounds below which no plane
(cell planes included) can shorten a spoke of the hub's body ring or of any ring. A spoke no
longer than its ring's free length keeps its given length (exactly: the guard only takes minima
with larger values), so only the others are guarded: :func:`ring_guard` (per ring) returns at once
where the ring's largest spoke is within its free length and otherwise writes the guarded length
of each longer spoke (:func:`spoke_guard`: five plane tests plus one per hub of the cell range
whose ring can reach, the hub's range re-tested with ``|x_k - x| < R + R_k``; hubs in it that
:func:`hub_guard` passed over cannot limit a spoke of the hub, so the result is the same as with
those it picked), leaving the rest unwritten. The points and normals
(:func:`~warp_tube.kernels.surface_spokes.ring_vertices`) take each spoke's length from there or,
by the same test (:func:`ring_free_length`), as given.
"""

import warp as wp

from .frames import rotate_minimal, safe_normalize
from .surface_arrays import RING_BODY, RING_POLE, SurfaceArrays

VIRTUAL_BLEND = wp.constant(0.9)
"""Reach (fraction of the distance to the centre of curvature) where an end ring starts to feel the
virtual ring beyond the tube's end."""
FREE_MARGIN = wp.constant(1.0e-5)
"""Relative margin of a hub's free lengths (:func:`hub_guard`) against float32 round-off of the
plane distances they bound (each within a few 1e-7)."""
DIRECTION_SLACK = wp.constant(1.0e-6)
"""Slack, relative to a plane normal's length, added to the bound of ``|d . n|`` for a body spoke:
covers ``d`` (built from float32 ``r``, ``s``) being orthogonal to ``t`` only to a few 1e-7."""
CELL_MIN_GAP = wp.constant(6)
"""Fewest hubs between two hubs whose cell plane limits their spokes: nearer hubs are separated by
the neighbour-ring and centre-of-curvature planes alone."""
CELL_WINDOW = wp.constant(3.14159265)
"""Reach of the cell guard along the centerline, in multiples of the tube's radius (mean spoke
length): ``pi``, that of the no-local-self-intersection requirement."""
PLANE_PREV = wp.constant(0)
"""Index of the previous ring's (or the virtual ring's) plane in ``hub_plane``."""
PLANE_NEXT = wp.constant(1)
"""Index of the next ring's (or the virtual ring's) plane in ``hub_plane``."""
PLANE_CENTRE = wp.constant(2)
"""Index of the centre of curvature's plane in ``hub_plane``."""


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
    w: int,
    h: int,
    length: float,
    d: wp.vec3,
    x: wp.vec3,
    cell: wp.vec2i,
    arrays: SurfaceArrays,
    node_q: wp.array2d[wp.vec3],
) -> float:
    """Spoke length [length unit] after the cell planes of the hubs in ``cell[0] .. h - CELL_MIN_GAP``
    and ``h + CELL_MIN_GAP .. cell[1]`` whose rings can reach the ring of hub ``h`` at ``x``
    (``|x_k - x| < R + R_k``); ``d`` the spoke's unit direction."""
    node_offset = arrays.node_offset
    hub_reach = arrays.hub_reach
    pw = w % hub_reach.shape[0]
    reach = hub_reach[pw, h]
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
                    out = wp.min(out, arrays.guard_reach * l_k)
    return out


@wp.func
def hub_guard(w: int, h: int, arrays: SurfaceArrays, node_q: wp.array2d[wp.vec3]):
    """Per-hub data of the spokes of hub ``h`` of world ``w``: curvature, chords, guard planes,
    cell range and free lengths, from the hub positions ``node_q`` and the tangents
    ``arrays.hub_t``.

    Writes, at ``[w, h]`` of the arrays of :class:`~warp_tube.kernels.surface_arrays.SurfaceArrays`:

    - ``hub_kappa``: curvature vector [1/length unit] (an end hub's is its interior neighbour's;
      zero for a tube of 2 hubs);
    - ``hub_chord``: sum of the lengths of the hub's edges [length unit] (one at a tube's end);
    - ``hub_plane``: guard planes relative to the hub (see :func:`plane_reach`) at
      :data:`PLANE_PREV`, :data:`PLANE_NEXT` (the neighbour rings', or at a tube's end of 3+ hubs
      the virtual ring's, read by body rings only) and :data:`PLANE_CENTRE`; zero where none;
    - ``hub_cell`` (guard on only): cell range ``(first, last)``, the farthest hubs before and
      after, at least :data:`CELL_MIN_GAP` hubs away, whose cell planes may shorten a spoke of the
      hub (the hub itself on a side with none);
    - ``hub_free``: free lengths [length unit] (see :func:`plane_free_length`) of a body ring's
      spokes (all three planes and the cell planes) and of any ring's (real neighbours, the centre
      and the cell planes).
    """
    node_offset = arrays.node_offset
    guard_reach = arrays.guard_reach
    hub_reach = arrays.hub_reach
    hub_t = arrays.hub_t
    tube = arrays.node_tube[h]
    first = arrays.tube_node_start[tube]
    last = arrays.tube_node_start[tube + 1] - 1
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
    arrays.hub_chord[w, h] = wp.length(x - x_prev) + wp.length(x_next - x)

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
    arrays.hub_kappa[w, h] = kappa

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
    arrays.hub_plane[w, h, PLANE_PREV] = plane_prev
    arrays.hub_plane[w, h, PLANE_NEXT] = plane_next
    arrays.hub_plane[w, h, PLANE_CENTRE] = plane_centre

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
        window = CELL_WINDOW * arrays.tube_cell_radius[w % arrays.tube_cell_radius.shape[0], tube]
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
        arrays.hub_cell[w, h] = cell
    arrays.hub_free[w, h] = wp.vec2(free_body, free_any)


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
def ring_free_length(free: wp.vec2, kind: int) -> float:
    """Free length [length unit] of a ring of ``kind`` from its hub's free lengths ``free`` (of
    its body ring, of any ring; see :func:`hub_guard`): spokes no longer than it keep their given
    length."""
    if kind == RING_BODY:
        return free[0]
    return free[1]


@wp.func
def spoke_guard(w: int, ring: int, j: int, arrays: SurfaceArrays, node_q: wp.array2d[wp.vec3]):
    """Guarded length [length unit] of spoke ``j`` of ``ring`` in world ``w``, written to
    ``arrays.surface_length`` where the spoke is longer than its ring's free length (nothing
    otherwise, nor for a pole ring's ``j > 0``); reads the per-hub data of :func:`hub_guard`."""
    spoke_length = arrays.spoke_length
    hub_plane = arrays.hub_plane
    kind = arrays.ring_kind[ring]
    if kind == RING_POLE and j > 0:
        return
    h = arrays.ring_hub[ring]
    pw = w % spoke_length.shape[0]
    free = arrays.hub_free[w, h]
    t = arrays.hub_t[w, h]
    c = arrays.ring_cos[ring]
    sn = arrays.ring_sin[ring]
    length = float(0.0)
    d = c * t
    if kind == RING_POLE:
        length = pole_length(spoke_length, pw, h)
        if length <= free[1]:
            return
    else:
        length = spoke_length[pw, h, j]
        if length <= ring_free_length(free, kind):
            return
        r = arrays.hub_r[w, h]
        d = c * t + sn * (arrays.spoke_cos[j] * r + arrays.spoke_sin[j] * wp.cross(t, r))
    tube = arrays.node_tube[h]
    kinds = ring_guard_kinds(h, kind, arrays.tube_node_start[tube], arrays.tube_node_start[tube + 1] - 1)
    out = guarded_length(
        length, d, kinds[0], hub_plane[w, h, PLANE_PREV], kinds[1], hub_plane[w, h, PLANE_NEXT],
        hub_plane[w, h, PLANE_CENTRE], arrays.guard_reach,
    )  # fmt: skip
    cell = arrays.hub_cell[w, h]
    if cell[0] <= h - CELL_MIN_GAP or cell[1] >= h + CELL_MIN_GAP:
        out = cell_limit(w, h, out, d, node_q[w, arrays.node_offset + h], cell, arrays, node_q)
    arrays.surface_length[w, arrays.ring_vertex[ring] + j] = out


@wp.func
def ring_guard(w: int, ring: int, arrays: SurfaceArrays, node_q: wp.array2d[wp.vec3]):
    """Guarded lengths of one ring's spokes (:func:`spoke_guard`), none where the hub's largest
    spoke is within the ring's free length (all but the rings of sharp bends and folds)."""
    h = arrays.ring_hub[ring]
    hub_reach = arrays.hub_reach
    if hub_reach[w % hub_reach.shape[0], h] > ring_free_length(arrays.hub_free[w, h], arrays.ring_kind[ring]):
        for j in range(arrays.spoke_count):
            spoke_guard(w, ring, j, arrays, node_q)
