"""Hubs-and-spokes surface: exact geometry, normals, topology, volume and the inner-bend guard."""

import numpy as np
import pytest
import warp as wp

from warp_tube.model import frames as ref
from warp_tube.surface import spans
from warp_tube.surface.builder import SurfaceBuilder
from warp_tube.surface.topology import RING_BODY, RING_POLE, build_topology

DEVICE = "cpu"


def arc(n, rho, angle):
    """n hubs on a circular arc of radius rho [m] and angle [rad] in the xy-plane, from the origin
    along +x, bending towards +y (axis of the bend: +z through (0, rho, 0))."""
    phi = np.linspace(0.0, angle, n)
    return np.stack([rho * np.sin(phi), rho * (1.0 - np.cos(phi)), np.zeros(n)], 1)


def straight(n, length):
    x = np.zeros((n, 3))
    x[:, 0] = np.linspace(0.0, length, n)
    return x


def build(x, spokes, lengths, *, caps=False, guard=0.95, frames="rotationMinimizing", normal=(0.0, 0.0, 1.0)):
    n = len(x)
    b = SurfaceBuilder(
        [0, n], x, spokes, lengths, np.array(normal), frames=frames, caps=caps, device=DEVICE, guard_reach=guard
    )
    b.compute(wp.array(x[None].astype(np.float32), dtype=wp.vec3, device=DEVICE))
    return b


def volume(points, faces):
    """Signed volume [m^3] enclosed by a closed, outward-oriented triangle mesh (divergence theorem)."""
    a, b, c = (points[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def closed_mesh(b, x):
    """Points and faces of a builder's surface; an open tube is closed by a fan to each end hub."""
    P = b.points_numpy().astype(np.float64)
    F = b.topology.faces.astype(np.int64)
    if b.caps:
        return P, F
    S, n = b.spokes, len(x)
    j = np.arange(S)
    j1 = (j + 1) % S
    c0, c1 = len(P), len(P) + 1
    P = np.vstack([P, x[0], x[-1]])
    fans = [np.stack([j, np.full(S, c0), j1], 1), np.stack([(n - 1) * S + j, (n - 1) * S + j1, np.full(S, c1)], 1)]
    return P, np.vstack([F] + fans)


# -- exact geometry ----------------------------------------------------------------------------


@pytest.mark.parametrize("frames", ["rotationMinimizing", "local"])
def test_spokes_at_length_and_angle_on_a_gentle_curve(frames):
    """Away from the guard (radius x curvature < 0.3 here), every spoke end is at its length from
    its hub, at its ring's angle to the tangent, and spoke j lies at phi_j from the reference r."""
    rng = np.random.default_rng(11)
    n, S = 24, 9
    s = np.linspace(0.0, 1.0, n)
    x = np.stack([s, 0.1 * np.sin(2.0 * s), 0.08 * np.cos(3.0 * s)], 1)
    rest = straight(n, 1.0)
    lengths = rng.uniform(0.02, 0.04, size=(n, S))
    b = SurfaceBuilder([0, n], rest, S, lengths, frames=frames, caps=True, device=DEVICE)
    b.compute(wp.array(x[None].astype(np.float32), dtype=wp.vec3, device=DEVICE))
    P = b.points_numpy().astype(np.float64)
    t, r, sv = b.frames_numpy()
    topo = b.topology
    xq = x.astype(np.float32).astype(np.float64)
    for ring in range(len(topo.ring_hub)):
        h, v0 = topo.ring_hub[ring], topo.ring_vertex[ring]
        count = 1 if topo.ring_kind[ring] == RING_POLE else S
        spoke = P[v0 : v0 + count] - xq[h]
        expected_len = lengths[h].mean() if count == 1 else lengths[h]
        # float32: points of O(1) coordinates carry ~1e-7 absolute error, i.e. ~5e-6 of a 0.02 spoke.
        np.testing.assert_allclose(np.linalg.norm(spoke, axis=1), expected_len, rtol=2e-5)
        cos_theta = spoke @ t[h] / np.linalg.norm(spoke, axis=1)
        np.testing.assert_allclose(cos_theta, topo.ring_cos[ring], atol=2e-5)
        if count == S:
            phi = 2 * np.pi * np.arange(S) / S
            u = np.cos(phi)[:, None] * r[h] + np.sin(phi)[:, None] * sv[h]
            d = topo.ring_cos[ring] * t[h] + topo.ring_sin[ring] * u
            np.testing.assert_allclose(spoke / expected_len[:, None], d, atol=2e-5)
    # body vertex order: hub i, spoke j at i * S + j
    assert np.all(topo.ring_vertex[topo.ring_kind == RING_BODY] == np.arange(n) * S)


def test_straight_tube_is_the_exact_polygonal_cylinder():
    n, S, radius = 10, 12, 0.05
    x = straight(n, 0.5)
    b = build(x, S, np.full(n, radius), normal=(0.0, 1.0, 0.0))
    phi = 2 * np.pi * np.arange(S) / S
    # t = +x, r = +y (the reference normal), s = t x r = +z
    u = np.stack([np.zeros(S), np.cos(phi), np.sin(phi)], 1)
    expected = x[:, None, :] + radius * u[None]
    # float32 round-off of coordinates <= 0.55: 1e-7 absolute; 1e-6 leaves 10x.
    np.testing.assert_allclose(b.points_numpy().reshape(n, S, 3), expected, atol=1e-6)
    np.testing.assert_allclose(b.normals_numpy().reshape(n, S, 3), np.broadcast_to(u, (n, S, 3)), atol=1e-6)


def test_normals_of_a_bent_circular_tube_are_the_spoke_directions():
    """A canal surface of constant radius has the spoke direction as its normal, bent or not."""
    n, S, radius = 20, 10, 0.1
    x = arc(n, 0.3, 1.5)  # radius x curvature = 1/3: guard inactive
    b = build(x, S, np.full(n, radius))
    P = b.points_numpy().astype(np.float64).reshape(n, S, 3)
    u = (P - x.astype(np.float32)[:, None, :]) / radius
    np.testing.assert_allclose(b.normals_numpy().reshape(n, S, 3), u, atol=2e-5)  # float32, as above


def elliptic_normal_error(S, a=0.06, bb=0.04, n=6):
    phi = 2 * np.pi * np.arange(S) / S
    L = a * bb / np.sqrt((bb * np.cos(phi)) ** 2 + (a * np.sin(phi)) ** 2)
    b = build(straight(n, 0.3), S, np.tile(L, (n, 1)), normal=(0.0, 1.0, 0.0))
    exact = np.stack([np.zeros(S), L * np.cos(phi) / a**2, L * np.sin(phi) / bb**2], 1)
    exact /= np.linalg.norm(exact, axis=1, keepdims=True)
    u = np.stack([np.zeros(S), np.cos(phi), np.sin(phi)], 1)
    got = b.normals_numpy().reshape(n, S, 3)
    return np.max(np.linalg.norm(got - exact[None], axis=2)), np.max(np.linalg.norm(u - exact, axis=1))


def test_normals_of_an_elliptic_tube():
    """Straight tube with an elliptic cross-section (semi-axes 0.06, 0.04): normals against the exact
    ellipse normal. The kernel differentiates the spoke lengths around the ring by central
    differences, second order in the spoke spacing: measured 0.018 at S = 32."""
    err32, spoke_dir_err = elliptic_normal_error(32)
    err64, _ = elliptic_normal_error(64)
    assert err32 < 0.03
    assert err64 < err32 / 3  # second order: 4x per halving
    assert spoke_dir_err > 0.1  # the plain spoke direction is 10x worse: the correction matters


# -- topology ----------------------------------------------------------------------------------


def test_topology_counts_orientation_and_seam():
    starts, S = np.array([0, 5, 12]), 8
    open_t = build_topology(starts, S)
    assert open_t.face_count == ((5 - 1) + (7 - 1)) * S * 2  # tubes of 5 and 7 hubs
    assert open_t.vertex_count == 12 * S
    capped = build_topology(starts, S, caps=True)
    K = 2  # ceil(8 / 4)
    assert capped.vertex_count == 12 * S + 2 * 2 * ((K - 1) * S + 1)
    assert capped.face_count == open_t.face_count + 2 * 2 * ((K - 1) * 2 * S + S)
    # every edge of a closed (capped) surface is shared by exactly two faces, once each way
    f = capped.faces
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    fwd = {tuple(e) for e in edges.tolist()}
    assert len(fwd) == len(edges)
    assert all((b, a) in fwd for a, b in fwd)
    # face-varying st: within a face u spans one spoke step (no backwards wrap at the seam)
    st = capped.st.reshape(-1, 3, 2)
    assert np.all(np.ptp(st[:, :, 0], axis=1) <= 1.0 / S + 1e-6)
    assert st[:, :, 0].min() == 0.0 and st[:, :, 0].max() == 1.0


def test_two_tubes_after_another_prims_nodes_and_batch_worlds():
    """A prim with two curves whose nodes start at column 4 of node_q, in 3 worlds with per-world
    spoke lengths: each world and each tube equals that tube built alone."""
    rng = np.random.default_rng(5)
    counts, S, W, offset = (7, 9), 6, 3, 4
    starts = offset + np.concatenate([[0], np.cumsum(counts)])
    rest = np.concatenate([arc(counts[0], 1.0, 0.5), straight(counts[1], 0.4) + [0, 1, 0]])
    lengths = rng.uniform(0.02, 0.05, size=(W, 16, S))
    node_q = np.zeros((W, offset + 16, 3))
    node_q[:, offset:] = rest[None] + rng.normal(scale=0.01, size=(W, 16, 3))
    b = SurfaceBuilder(starts, rest, S, lengths, caps=True, world_count=W, device=DEVICE)
    b.compute(wp.array(node_q.astype(np.float32), dtype=wp.vec3, device=DEVICE))
    P = b.points.numpy()
    local = np.concatenate([[0], np.cumsum(counts)])
    for tube in range(2):
        a, e = local[tube], local[tube + 1]
        idx = b.tube_vertex_indices(tube)
        assert np.all(idx[: (e - a) * S] == np.arange(a * S, e * S))  # rings first, hub-major
        for w in range(W):
            alone = SurfaceBuilder([0, e - a], rest[a:e], S, lengths[w, a:e], caps=True, device=DEVICE)
            alone.compute(wp.array(node_q[w : w + 1, offset + a : offset + e].astype(np.float32), dtype=wp.vec3, device=DEVICE))
            np.testing.assert_array_equal(P[w, idx], alone.points_numpy())


# -- volume ------------------------------------------------------------------------------------


@pytest.mark.parametrize("caps", [False, True])
def test_volume_of_bends(caps):
    """Half-circle bends with radius x curvature up to 0.9, hubs r/4 apart: the closed surface's
    volume within 1% of the straight tube with the same hubs (Pappus: a bend keeps A * length).
    The straight open tube itself is the polygonal prism: pi r^2 l (S / 2 pi) sin(2 pi / S)."""
    r, S = 0.1, 16
    poly = S / (2 * np.pi) * np.sin(2 * np.pi / S)
    for rk in (0.3, 0.6, 0.9):
        rho = r / rk
        n = int(np.ceil(np.pi * rho / (r / 4))) + 1
        x = arc(n, rho, np.pi)
        chord_length = np.linalg.norm(np.diff(x, axis=0), axis=1).sum()
        xs = straight(n, chord_length)
        vb = volume(*closed_mesh(build(x, S, np.full(n, r), caps=caps), x))
        vs = volume(*closed_mesh(build(xs, S, np.full(n, r), caps=caps), xs))
        if not caps:
            # float32 points: 1e-6 relative
            assert abs(vs / (np.pi * r * r * chord_length * poly) - 1.0) < 1e-5
        print(f"volume, caps={caps}, radius x curvature {rk}: bent / straight - 1 = {vb / vs - 1:+.4%}")
        assert abs(vb / vs - 1.0) < 0.01


# -- inner-bend guard ---------------------------------------------------------------------------


def _orient(a, b, c, d):
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a))


def _segment_crosses(p, q, a, b, c, eps):
    """Segment pq passes strictly through the interior of triangle abc (signed volumes)."""
    d1, d2 = _orient(a, b, c, p), _orient(a, b, c, q)
    s1, s2, s3 = _orient(p, q, a, b), _orient(p, q, b, c), _orient(p, q, c, a)
    inside = ((s1 > eps) & (s2 > eps) & (s3 > eps)) | ((s1 < -eps) & (s2 < -eps) & (s3 < -eps))
    return (d1 * d2 < -eps * eps) & inside


def intersecting_pairs(points, faces, max_apart, arc_of_vertex, eps=1e-10):
    """Pairs of triangles (i < j) that cross each other, among all pairs whose mean arc positions
    are less than max_apart apart: an edge of one through the other's interior. Touching at shared
    vertices or edges does not count (strict signed-volume tests, eps ~ 1e-10 m^3 for r = 1 m, far
    below the 1e-3 m^3 of the thinnest triangles here and far above float64 round-off)."""
    T = points[faces]
    s = arc_of_vertex[faces].mean(axis=1)
    i, j = np.triu_indices(len(faces), 1)
    keep = np.abs(s[i] - s[j]) < max_apart
    i, j = i[keep], j[keep]
    A, B = T[i], T[j]
    hit = np.zeros(len(i), bool)
    for k in range(3):
        hit |= _segment_crosses(A[:, k], A[:, (k + 1) % 3], B[:, 0], B[:, 1], B[:, 2], eps)
        hit |= _segment_crosses(B[:, k], B[:, (k + 1) % 3], A[:, 0], A[:, 1], A[:, 2], eps)
    return i[hit], j[hit]


@pytest.mark.parametrize("n, angle, caps", [(16, 1.5 * np.pi, False), (24, 1.8 * np.pi, False), (16, np.pi, True)])
def test_no_local_self_intersection_at_radius_times_curvature_2(n, angle, caps):
    """Arc of curvature 2/r (bend radius r/2): every pair of triangles whose rings are less than
    pi r apart along the centerline (here: the whole tube) is checked. Without the guard the inner
    spokes pass the centre of curvature and the rings cross, which the same check finds."""
    r, S = 1.0, 12
    x = arc(n, r / 2, angle)
    arc_len = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(x, axis=0), axis=1))])
    for guard in (0.95, 0.0):
        b = build(x, S, np.full(n, r), caps=caps, guard=guard)
        hub_of_vertex = np.empty(b.vertex_count, dtype=int)
        topo = b.topology
        for ring in range(len(topo.ring_hub)):
            count = 1 if topo.ring_kind[ring] == RING_POLE else S
            hub_of_vertex[topo.ring_vertex[ring] : topo.ring_vertex[ring] + count] = topo.ring_hub[ring]
        i, _ = intersecting_pairs(b.points_numpy().astype(np.float64), topo.faces, np.pi * r, arc_len[hub_of_vertex])
        if guard > 0:
            assert len(i) == 0, f"{len(i)} crossing triangle pairs with the guard on"
        else:
            assert len(i) > 0  # the check does detect the unguarded fold


def test_guard_is_inactive_below_its_reach():
    """radius x curvature 0.85 < 0.9: the guard changes nothing, every spoke keeps its length."""
    n, S, r = 20, 12, 0.085
    x = arc(n, 0.1, 2.0)
    on = build(x, S, np.full(n, r)).points_numpy()
    off = build(x, S, np.full(n, r), guard=0.0).points_numpy()
    np.testing.assert_array_equal(on, off)


def test_guard_cuts_inner_side_at_its_reach():
    """Interior rings of an arc at radius x curvature 2: inner spoke ends stop at g rho from the hub
    towards the centre (the flat chord), outer spokes keep the radius."""
    n, S, r, g = 12, 16, 1.0, 0.95
    rho = r / 2
    x = arc(n, rho, np.pi)
    b = build(x, S, np.full(n, r), guard=g)
    P = b.points_numpy().astype(np.float64).reshape(n, S, 3)
    centre = np.array([0.0, rho, 0.0])
    for i in range(1, n - 1):
        toward = (centre - x[i]) / rho
        reach = (P[i] - x[i]) @ toward
        assert reach.max() <= g * rho * (1 + 1e-5)  # float32 round-off
        spoke = np.linalg.norm(P[i] - x[i], axis=1)
        outer = reach < 0
        np.testing.assert_allclose(spoke[outer], r, rtol=1e-5)


def guarded_lengths_reference(x, t, r, lengths, topo, g):
    """Spoke lengths after the inner-bend guard, per ring vertex, evaluated directly in float64 from
    the module docstring of kernels.surface_guard (neighbour planes, virtual end rings blended in from
    0.9 to 1 of the reach to the centre of curvature's plane, that plane itself), for one tube."""
    n = len(x)
    S = topo.spokes
    out = np.empty(topo.vertex_count)

    def reach(d, p, normal, xh):
        num, den = np.dot(p - xh, normal), np.dot(d, normal)
        return num / den if num * den > 0 else -1.0

    def unit(v):
        return v / np.linalg.norm(v)

    for ring in range(len(topo.ring_hub)):
        h, kind, c, sn, v0 = (topo.ring_hub[ring], topo.ring_kind[ring], topo.ring_cos[ring], topo.ring_sin[ring], topo.ring_vertex[ring])
        planes = []  # (kind, point, normal)
        if h > 0:
            planes.append((1, x[h - 1], t[h - 1]))
        elif kind == RING_BODY:  # virtual ring before the start, continuing the first segment's bend
            e = unit(x[1] - x[0])
            t_star = 2 * np.dot(t[1], e) * e - t[1]  # the neighbour's tangent mirrored in the edge
            R = ref.minimal_rotation(t[1], t_star)
            planes.append((2, x[0] - R @ (x[1] - x[0]), R @ t_star))
        if h < n - 1:
            planes.append((1, x[h + 1], t[h + 1]))
        elif kind == RING_BODY:
            e = unit(x[-1] - x[-2])
            t_star = 2 * np.dot(t[-2], e) * e - t[-2]
            R = ref.minimal_rotation(t[-2], t_star)
            planes.append((2, x[-1] + R @ (x[-1] - x[-2]), R @ t_star))
        hc = min(max(h, 1), n - 2)
        lv = 0.5 * (np.linalg.norm(x[hc] - x[hc - 1]) + np.linalg.norm(x[hc + 1] - x[hc]))
        kappa = (unit(x[hc + 1] - x[hc]) - unit(x[hc] - x[hc - 1])) / lv
        centre = x[hc] + kappa / np.dot(kappa, kappa)
        k_perp = kappa - np.dot(kappa, t[h]) * t[h]
        s = np.cross(t[h], r[h])
        count = 1 if kind == RING_POLE else S
        for j in range(count):
            phi = 2 * np.pi * j / S
            d = c * t[h] + sn * (np.cos(phi) * r[h] + np.sin(phi) * s)
            length = lengths[h].mean() if count == 1 else lengths[h, j]
            l_c = reach(d, centre, k_perp, x[h])
            limited = length
            for pk, p, normal in planes:
                l_k = reach(d, p, normal, x[h])
                if l_k <= 0:
                    continue
                if pk == 1:
                    limited = min(limited, g * l_k)
                elif l_c > 0:
                    blend = np.clip((length / l_c - 0.9) / 0.1, 0.0, 1.0)
                    limited = min(limited, length + blend * (min(length, g * l_k) - length))
            if l_c > 0:
                limited = min(limited, g * l_c)
            out[v0 + j] = limited
    return out


@pytest.mark.parametrize("rk", [0.8, 0.95, 1.1, 1.5])
def test_guarded_lengths_match_a_direct_evaluation_near_the_guards_onset(rk):
    """Perturbed arcs with caps and uneven spokes around the guard's onset (radius x curvature
    0.8 .. 1.5; hubs about 0.6 radii apart, so neighbour planes and virtual end rings act too): every
    spoke end lies at the guarded length from a float64 evaluation of the guard. Checks that the
    kernels' shortcut for spokes no plane can reach (per-hub free lengths) never skips a limit."""
    rng = np.random.default_rng(int(rk * 100))
    n, S, r, g = 14, 16, 0.1, 0.95
    rho = r / rk
    x = arc(n, rho, 0.6 * r * (n - 1) / rho) + rng.normal(scale=0.05 * r, size=(n, 3))
    lengths = r * rng.uniform(0.85, 1.15, size=(n, S))
    b = SurfaceBuilder([0, n], x, S, lengths, caps=True, device=DEVICE, guard_reach=g)
    xq = x.astype(np.float32)
    b.compute(wp.array(xq[None], dtype=wp.vec3, device=DEVICE))
    t, rr, _ = b.frames_numpy()
    xq = xq.astype(np.float64)
    expected = guarded_lengths_reference(xq, t, rr, lengths, b.topology, g)
    topo = b.topology
    hub_of_vertex = np.empty(b.vertex_count, dtype=int)
    for ring in range(len(topo.ring_hub)):
        count = 1 if topo.ring_kind[ring] == RING_POLE else S
        hub_of_vertex[topo.ring_vertex[ring] : topo.ring_vertex[ring] + count] = topo.ring_hub[ring]
    got = np.linalg.norm(b.points_numpy().astype(np.float64) - xq[hub_of_vertex], axis=1)
    # float32 frames and points (~1e-7 relative), amplified where a spoke meets a plane obliquely.
    np.testing.assert_allclose(got, expected, rtol=2e-5)
    if rk > 1.0:
        given = np.concatenate([lengths.reshape(-1), np.full(b.vertex_count - n * S, np.nan)])
        assert np.sum(expected[: n * S] < 0.99 * given[: n * S]) > S  # the guard does act here


# -- cells of folded-back parts ----------------------------------------------------------------


def hairpin(rho, leg, h):
    """Centerline of a U: a straight leg along +x ending at the origin, a half circle of radius rho
    around (0, rho, 0), and a straight leg back along -x at y = 2 rho; hubs about h apart, all on the
    centerline (the legs' facing sides are 2 rho apart, i.e. within reach of each other for
    2 rho < 2 r)."""
    n_leg = int(np.ceil(leg / h))
    n_arc = int(np.ceil(np.pi * rho / h))
    a = np.linspace(-leg, 0.0, n_leg, endpoint=False)
    phi = np.pi * np.arange(n_arc) / n_arc
    first = np.stack([a, 0 * a, 0 * a], 1)
    bend = np.stack([rho * np.sin(phi), rho * (1.0 - np.cos(phi)), 0 * phi], 1)
    back = np.stack([-np.linspace(0.0, leg, n_leg + 1), np.full(n_leg + 1, 2 * rho), np.zeros(n_leg + 1)], 1)
    return np.concatenate([first, bend, back])


def crossing_pairs_within(b, x, max_apart):
    """Crossing triangle pairs of a builder's surface whose rings are less than max_apart apart
    along the centerline (arc length of the hubs, sum of chords)."""
    arc_len = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(x, axis=0), axis=1))])
    topo = b.topology
    hub_of_vertex = np.empty(b.vertex_count, dtype=int)
    for ring in range(len(topo.ring_hub)):
        count = 1 if topo.ring_kind[ring] == RING_POLE else b.spokes
        hub_of_vertex[topo.ring_vertex[ring] : topo.ring_vertex[ring] + count] = topo.ring_hub[ring]
    i, _ = intersecting_pairs(b.points_numpy().astype(np.float64), topo.faces, max_apart, arc_len[hub_of_vertex])
    return len(i)


@pytest.mark.parametrize("rho, caps", [(0.6, True), (0.7, False)])
def test_no_local_self_intersection_of_a_hairpin(rho, caps):
    """A U folded back with bend radius rho = 0.6 r or 0.7 r (radius x curvature 1.7 or 1.4) and
    parallel legs 2 rho = 1.2 r or 1.4 r apart, hubs r/4 apart: the legs' facing sides, within
    pi r of each other along the tube, overlap by 2 r - 2 rho unless the cell planes between the
    legs' hubs stop them. Checked as the r x curvature 2 arcs are; without the guard the same
    check finds the crossings."""
    r, S, g = 1.0, 16, 0.95
    x = hairpin(rho * r, 3.0 * r, r / 4)
    on = build(x, S, np.full(len(x), r), caps=caps, guard=g)
    off = build(x, S, np.full(len(x), r), caps=caps, guard=0.0)
    assert crossing_pairs_within(on, x, np.pi * r) == 0
    assert crossing_pairs_within(off, x, np.pi * r) > 0  # the check does detect the overlap

    # The legs' hubs r/4 before the bend: straight there (no centre plane, parallel neighbour
    # planes), and their arc distance 0.5 r + pi rho is within pi r. A spoke facing the other leg
    # stops at g times the way to the mid-plane y = rho between the legs (equal radii: the cell
    # plane of two facing hubs is their bisector; the other hubs' planes are oblique and farther
    # along it); a spoke facing away keeps the radius. float32 round-off: 1e-5.
    P = on.points_numpy().astype(np.float64)[: len(x) * S].reshape(len(x), S, 3)
    xq = x.astype(np.float32).astype(np.float64)
    legs = np.abs(xq[:, 0] + 0.25 * r) < 1e-6
    assert legs.sum() == 2
    towards = np.where(xq[:, 1] < rho * r, 1.0, -1.0)  # the other leg lies in +y from the first
    reach = (P[legs] - xq[legs, None, :])[:, :, 1] * towards[legs, None]
    assert reach.max() <= g * rho * r * (1 + 1e-5)
    assert reach.max() >= g * rho * r * (1 - 1e-5)  # the facing spoke is cut exactly there
    spoke = np.linalg.norm(P[legs] - xq[legs, None, :], axis=2)
    np.testing.assert_allclose(spoke[reach < 0], r, rtol=1e-5)


@pytest.mark.parametrize("n, angle, caps", [(16, 1.5 * np.pi, False), (24, 1.8 * np.pi, False), (16, np.pi, True)])
def test_cell_planes_leave_circular_arcs_as_the_centre_plane_cuts_them(n, angle, caps):
    """On the radius x curvature 2 arcs of the self-intersection test, hubs 6 or more apart are
    within pi r along the tube and close enough to be in each other's cell range, but their cell
    planes contain the arc's axis, as the ring planes do: every spoke keeps the length the
    neighbour, virtual and centre planes give it (the float64 reference of those alone)."""
    r, S, g = 1.0, 12, 0.95
    x = arc(n, r / 2, angle)
    b = build(x, S, np.full(n, r), caps=caps, guard=g)
    cell = b._hub_cell.numpy()[0]
    hubs = np.arange(n)
    assert np.any((cell[:, 0] <= hubs - 6) | (cell[:, 1] >= hubs + 6))  # the cell guard is consulted
    xq = x.astype(np.float32).astype(np.float64)
    t, rr, _ = b.frames_numpy()
    expected = guarded_lengths_reference(xq, t, rr, np.full((n, S), r), b.topology, g)
    topo = b.topology
    hub_of_vertex = np.empty(b.vertex_count, dtype=int)
    for ring in range(len(topo.ring_hub)):
        count = 1 if topo.ring_kind[ring] == RING_POLE else S
        hub_of_vertex[topo.ring_vertex[ring] : topo.ring_vertex[ring] + count] = topo.ring_hub[ring]
    got = np.linalg.norm(b.points_numpy().astype(np.float64) - xq[hub_of_vertex], axis=1)
    # float32, as in the direct evaluation test; the axis is where a cell plane and the centre
    # plane meet, so their limits agree to round-off.
    np.testing.assert_allclose(got, expected, rtol=2e-5)


def _rebuilds_of_a_hard_case(frames, caps, measured, device, variants):
    """Points, normals and extent of each rebuild variant ``(kernel, block shape)`` on
    an arc at radius x curvature 1.5 and a hairpin with legs 1.3 radii apart (guard and cell planes
    acting), two curves, three worlds. ``measured``: False for circular tubes, True for spoke
    lengths varying around each ring, ``"per world"`` for such lengths differing per world."""
    rng = np.random.default_rng(5)
    n, S, W = 30, 7, 3
    u = hairpin(0.0065, 0.05, 0.004)[:n]
    rest = np.concatenate([straight(n, 0.3), straight(n, 0.3) + [0.0, 0.1, 0.0]])
    lengths = 0.01 * (1.0 + 0.2 * rng.random((2 * n, S)))
    if not measured:
        lengths = np.full(2 * n, 0.01)
    elif measured == "per world":
        lengths = 0.01 * (1.0 + 0.2 * rng.random((W, 2 * n, S)))
    q = np.concatenate([arc(n, 0.01 / 1.5, 1.5 * np.pi), u + [0.0, 0.2, 0.0]])
    qw = np.repeat(q[None], W, axis=0)
    qw[1] += rng.normal(scale=1e-3, size=qw[1].shape)
    out = []
    for kernel, shape in variants:
        spans.MIN_SPAN_HUBS, min_hubs = (1 if kernel == "spans" else spans.MIN_SPAN_HUBS), spans.MIN_SPAN_HUBS
        try:  # "spans": the block kernel with a tube a span (as a world of many tubes run alone)
            b = SurfaceBuilder([0, n, 2 * n], rest, S, lengths, frames=frames, caps=caps, world_count=W, device=device,
                               kernel="block" if kernel == "spans" else kernel)  # fmt: skip
        finally:
            spans.MIN_SPAN_HUBS = min_hubs
        assert b.spans.count == (2 if kernel == "spans" else 1)
        b.block_shape = shape or b.block_shape
        p, nrm = b.compute(wp.array(qw.astype(np.float32), dtype=wp.vec3, device=device))
        guarded = b._surface_length.numpy()
        assert np.any(guarded > 0.0), f"{kernel}: the guard did not act: the comparison would not cover it"
        out.append((p.numpy().copy(), nrm.numpy().copy(), b.extent().numpy().copy()))
    return out


@pytest.mark.parametrize("frames", ["rotationMinimizing", "local"])
@pytest.mark.parametrize("caps", [False, True])
@pytest.mark.parametrize("measured", [True, False, "per world"])
def test_world_and_block_kernels_agree(frames, caps, measured):
    """The two ways a rebuild runs (a thread per world, the CPU's; a warp per world, the GPU's)
    give the same points and normals bit for bit (same arithmetic in the same order), guard and
    cell planes acting, with measured spoke lengths or circular ones (where the kernels read a
    ring's length once unless the guard acts); the world kernel's extent is the exact bounds of
    its points, and the block kernel finds the same. A curve of 60 hubs takes the block kernel's
    frames two chunks of 32, the second tube starting inside the first."""
    # The block kernel with one, two and four worlds per block (W = 3: idle warps), and with each
    # tube a span of its own (six warps, each world's bounds reduced over its two spans).
    variants = [("world", None), ("block", (1, 0)), ("block", (2, 4)), ("block", (4, 0)), ("spans", (2, 4)), ("spans", (4, 0))]
    out = _rebuilds_of_a_hard_case(frames, caps, measured, DEVICE, variants)
    p0, n0, _ = out[0]
    exact = np.stack([p0.min(axis=1), p0.max(axis=1)], axis=1)
    for p1, n1, e1 in out:
        assert np.array_equal(p0, p1) and np.array_equal(n0, n1)
        assert np.array_equal(e1, exact)


@pytest.mark.gpu
@pytest.mark.skipif(wp.get_cuda_device_count() == 0, reason="no CUDA device")
@pytest.mark.parametrize("frames", ["rotationMinimizing", "local"])
@pytest.mark.parametrize("measured", [True, False, "per world"])
def test_world_and_block_kernels_agree_on_cuda(frames, measured):
    """On a GPU the block rebuild (the default there, in three block shapes) and the world kernel
    run on the GPU as its reference, both compiled with the same fast-math options, give the same
    points and normals bit for bit, and the block kernel's extent is the exact bounds of its
    points."""
    variants = [("world", None), ("block", (1, 0)), ("block", (2, 4)), ("block", (4, 0)), ("spans", (2, 4)), ("spans", (1, 0))]
    out = _rebuilds_of_a_hard_case(frames, True, measured, "cuda:0", variants)
    p0, n0, _ = out[0]
    exact = np.stack([p0.min(axis=1), p0.max(axis=1)], axis=1)
    for p1, n1, e1 in out:
        assert np.array_equal(p0, p1) and np.array_equal(n0, n1)
        assert np.array_equal(e1, exact)


@pytest.mark.parametrize("name", ["default", "cantilever", "intestine"])
def test_no_local_self_intersection_in_the_example_scenes(name):
    """Each scene of scenes/ simulated to its end: at a quarter, half, three quarters and the end,
    no two triangles of one tube whose rings lie less than pi r apart along its centerline cross
    (exhaustive, as for the arcs above; r the curve's mean radius, curves of one prim never paired)."""
    from warp_tube import Simulation
    from warp_tube.scene.usd import load_scene

    from .conftest import SCENES

    scene = load_scene(str(SCENES / f"{name}.usda"))
    sim = Simulation(scene, device=DEVICE)
    frames = scene.stage.frame_count - 1
    checks = {frames // 4, frames // 2, 3 * frames // 4, frames}
    checked = 0
    for frame in range(1, frames + 1):
        sim.step()
        if frame not in checks:
            continue
        for tube, builder in zip(scene.tubes, sim.surfaces):
            builder.compute(sim.state.node_q)
            points = builder.points.numpy()[0].astype(np.float64)
            r = float(np.mean(tube.radius))
            # Arc position of each hub along its own curve; curves of one prim far apart in it.
            arc, start = np.empty(len(tube.points)), 0
            for k, count in enumerate(tube.curve_counts):
                seg = np.linalg.norm(np.diff(tube.points[start : start + count], axis=0), axis=1)
                arc[start : start + count] = 1e6 * r * k + np.concatenate([[0.0], np.cumsum(seg)])
                start += count
            topo = builder.topology
            hub_of_vertex = np.empty(builder.vertex_count, dtype=int)
            for ring in range(len(topo.ring_hub)):
                count = 1 if topo.ring_kind[ring] == RING_POLE else builder.spokes
                hub_of_vertex[topo.ring_vertex[ring] : topo.ring_vertex[ring] + count] = topo.ring_hub[ring]
            # eps: the arcs' 1e-10 m^3 at r = 1 m, scaled by r^3.
            i, _ = intersecting_pairs(points, topo.faces, np.pi * r, arc[hub_of_vertex], eps=1e-10 * r**3)
            assert len(i) == 0, f"{name}, frame {frame}, {tube.path}: {len(i)} crossing triangle pairs"
            checked += 1
    assert checked == len(checks) * len(scene.tubes)
