"""The per-point and per-tube NumPy loops that the vectorised build replaced, kept as references
for the tests (same results to round-off, see tests/test_build_vectorised.py).

``rest_curvature_coordinates_loop``: one tube's rest curvature binormals in its Bishop frames, the
frame carried point by point with ``rotate_minimal``. ``build_topology_loop``: the surface
topology built tube by tube and strip by strip. ``node_parameters_loop``: the model's per-node
masses, stiffnesses and damping built curve by curve.
"""

from __future__ import annotations

import math

import numpy as np

from warp_tube.model.frames import rotate_minimal
from warp_tube.model.tube import curvature_binormal, first_edge_normal, rest_curvature_of_curves
from warp_tube.surface.topology import RING_BODY, RING_CAP, RING_POLE, SurfaceTopology, cap_ring_count


def rest_curvature_coordinates_loop(points: np.ndarray) -> np.ndarray:
    """Rest curvature binormals of one tube (n, 3) in its rest Bishop frames, (n, 3)."""
    x = np.asarray(points, dtype=np.float64)
    n = len(x)
    out = np.zeros((n, 3))
    if n < 3:
        return out
    t = (x[1] - x[0]) / np.linalg.norm(x[1] - x[0])
    u = first_edge_normal(t)
    for j in range(1, n - 1):
        kb = curvature_binormal(x[j] - x[j - 1], x[j + 1] - x[j])
        v = np.cross(t, u)
        out[j] = [np.dot(kb, t), np.dot(kb, u), np.dot(kb, v)]
        t_next = (x[j + 1] - x[j]) / np.linalg.norm(x[j + 1] - x[j])
        u = rotate_minimal(t, t_next, u)
        u = u - t_next * np.dot(u, t_next)
        u /= np.linalg.norm(u)
        t = t_next
    return out


def _strip(a0: int, b0: int, va: float, vb: float, spokes: int, forward: bool):
    """Triangles and face-varying st joining ring ``a0`` to ring ``b0`` (``b`` further along)."""
    j = np.arange(spokes)
    j1 = (j + 1) % spokes
    a, b, c, d = a0 + j, a0 + j1, b0 + j, b0 + j1
    ua, ub = j / spokes, (j + 1) / spokes
    pa, pb, pc, pd = (np.stack([u, np.full(spokes, v)], -1) for u, v in ((ua, va), (ub, va), (ua, vb), (ub, vb)))
    if forward:
        tri = np.stack([np.stack([a, b, d], -1), np.stack([a, d, c], -1)], 1)
        st = np.stack([np.stack([pa, pb, pd], 1), np.stack([pa, pd, pc], 1)], 1)
    else:
        tri = np.stack([np.stack([a, d, b], -1), np.stack([a, c, d], -1)], 1)
        st = np.stack([np.stack([pa, pd, pb], 1), np.stack([pa, pc, pd], 1)], 1)
    return tri.reshape(-1, 3), st.reshape(-1, 3, 2)


def _fan(a0: int, pole: int, va: float, vp: float, spokes: int, forward: bool):
    """Triangles and face-varying st joining ring ``a0`` to a pole vertex further along."""
    j = np.arange(spokes)
    a, b = a0 + j, a0 + (j + 1) % spokes
    p = np.full(spokes, pole)
    pa = np.stack([j / spokes, np.full(spokes, va)], -1)
    pb = np.stack([(j + 1) / spokes, np.full(spokes, va)], -1)
    pp = np.stack([(j + 0.5) / spokes, np.full(spokes, vp)], -1)
    if forward:
        return np.stack([a, b, p], -1), np.stack([pa, pb, pp], 1)
    return np.stack([a, p, b], -1), np.stack([pa, pp, pb], 1)


def build_topology_loop(
    tube_node_start: np.ndarray,
    spokes: int,
    *,
    caps: bool = False,
    rest_q: np.ndarray | None = None,
    cap_radius: np.ndarray | None = None,
) -> SurfaceTopology:
    """Build the topology and ring table of one tube prim.

    Args:
        tube_node_start: first hub of each tube, int (T + 1,), starting at 0, increasing, each tube
            with at least 2 hubs.
        spokes: spokes per hub, S >= 3.
        caps: close both ends of every tube with a rounded cap.
        rest_q: rest hub positions [m], (N, 3), for ``v`` (arc length); default: uniform in the hub
            index.
        cap_radius: per tube (T, 2), the mean spoke length [m] at its start and end hub, for the
            caps' ``v`` extent; default: a tenth of the tube's rest length.

    Returns:
        The :class:`SurfaceTopology`.
    """
    starts = np.asarray(tube_node_start, dtype=np.int64)
    if starts.ndim != 1 or len(starts) < 2 or starts[0] != 0 or np.any(np.diff(starts) < 2):
        raise ValueError(f"tube_node_start must start at 0 and give every tube >= 2 hubs, got {starts.tolist()}")
    if spokes < 3:
        raise ValueError(f"spokes must be >= 3, got {spokes}")
    S = int(spokes)
    n_hubs = int(starts[-1])
    n_tubes = len(starts) - 1
    K = cap_ring_count(S) if caps else 0

    # v along each tube: rest arc length over the tube's rest length.
    v_hub = np.empty(n_hubs)
    tube_len = np.empty(n_tubes)
    for tube in range(n_tubes):
        a, b = starts[tube], starts[tube + 1]
        if rest_q is not None:
            seg = np.linalg.norm(np.diff(np.asarray(rest_q, dtype=np.float64)[a:b], axis=0), axis=1)
        else:
            seg = np.ones(b - a - 1)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        tube_len[tube] = arc[-1] if arc[-1] > 0 else 1.0
        v_hub[a:b] = arc / tube_len[tube]

    ring_hub = [np.arange(n_hubs)]
    ring_kind = [np.full(n_hubs, RING_BODY)]
    ring_cos = [np.zeros(n_hubs)]
    ring_sin = [np.ones(n_hubs)]
    ring_vertex = [np.arange(n_hubs) * S]
    tris, sts = [], []
    next_vertex = n_hubs * S

    for tube in range(n_tubes):
        a, b = int(starts[tube]), int(starts[tube + 1])
        for i in range(a, b - 1):
            tri, st = _strip(i * S, (i + 1) * S, v_hub[i], v_hub[i + 1], S, True)
            tris.append(tri)
            sts.append(st)
    for tube in range(n_tubes):
        if not caps:
            break
        a, b = int(starts[tube]), int(starts[tube + 1])
        for end, hub, sign in ((0, a, -1.0), (1, b - 1, 1.0)):
            radius = cap_radius[tube, end] if cap_radius is not None else 0.1 * tube_len[tube]
            dv = 0.5 * math.pi * radius / tube_len[tube] / K
            forward = sign > 0
            prev_ring, prev_v = hub * S, v_hub[hub]
            for k in range(1, K + 1):
                beta = 0.5 * math.pi * (1.0 - k / K)
                v = v_hub[hub] + sign * k * dv
                ring_hub.append([hub])
                ring_cos.append([sign * math.cos(beta)])
                ring_sin.append([math.sin(beta) if k < K else 0.0])
                ring_vertex.append([next_vertex])
                if k < K:
                    ring_kind.append([RING_CAP])
                    tri, st = _strip(prev_ring, next_vertex, prev_v, v, S, forward)
                    prev_ring, prev_v = next_vertex, v
                    next_vertex += S
                else:
                    ring_kind.append([RING_POLE])
                    tri, st = _fan(prev_ring, next_vertex, prev_v, v, S, forward)
                    next_vertex += 1
                tris.append(tri)
                sts.append(st)

    faces = np.concatenate(tris).astype(np.int32)
    st = np.concatenate(sts).reshape(-1, 2).astype(np.float32)
    return SurfaceTopology(
        spokes=S,
        caps=bool(caps),
        hub_count=n_hubs,
        vertex_count=next_vertex,
        face_vertex_counts=np.full(len(faces), 3, dtype=np.int32),
        face_vertex_indices=faces.reshape(-1),
        st=st,
        st_interpolation="faceVarying",
        ring_hub=np.concatenate(ring_hub).astype(np.int32),
        ring_kind=np.concatenate(ring_kind).astype(np.int32),
        ring_cos=np.concatenate(ring_cos).astype(np.float32),
        ring_sin=np.concatenate(ring_sin).astype(np.float32),
        ring_vertex=np.concatenate(ring_vertex).astype(np.int32),
    )


def node_parameters_loop(scene):
    """The per-node arrays of :func:`warp_tube.model.tube.node_parameters`, built curve by curve
    (a few dozen NumPy calls per curve): (dict of arrays, curved)."""
    pts, tube_start, node_tube = [], [0], []
    mass, inv_mass, damping, rest_len, ke, kd, bend_k, kappa, anchor_k, anchor_kd, radius = ([] for _ in range(11))
    prim_node_start = []
    curved = False
    t_index = 0
    curve_kappa = iter(rest_curvature_of_curves(
        [spec.points[c0 : c0 + cn] for spec in scene.tubes for c0, cn in zip(spec.curve_starts, spec.curve_counts)]))  # fmt: skip
    for spec in scene.tubes:
        prim_node_start.append(tube_start[-1])
        p = spec.params
        pinned = np.zeros(len(spec.points), dtype=bool)
        pinned[spec.pinned] = True
        anchored = np.zeros(len(spec.points), dtype=bool)
        anchored[spec.anchors] = True
        for c0, cn in zip(spec.curve_starts, spec.curve_counts):
            x = spec.points[c0 : c0 + cn]
            r = spec.radius[c0 : c0 + cn]
            pin = pinned[c0 : c0 + cn]
            seg = np.linalg.norm(x[1:] - x[:-1], axis=1)
            r_seg = 0.5 * (r[1:] + r[:-1])
            m_seg = p.density * np.pi * r_seg**2 * seg
            m = np.zeros(cn)
            m[:-1] += 0.5 * m_seg
            m[1:] += 0.5 * m_seg
            elastic = ~(pin[1:] & pin[:-1])
            l_el = np.where(elastic, seg, 0.0)
            l_v = np.zeros(cn)
            l_v[1:-1] = 0.5 * (l_el[:-1] + l_el[1:])
            ei = p.bending_stiffness(r)
            bk = np.where(l_v > 0.0, ei / np.where(l_v > 0, l_v, 1.0), 0.0)
            bk[0] = bk[-1] = 0.0
            k_ax = p.axial_stiffness(r_seg) / seg
            pts.append(x)
            radius.append(r)
            mass.append(m)
            inv_mass.append(np.where(pin, 0.0, 1.0 / m))
            damping.append(np.full(cn, p.damping))
            rest_len.append(np.append(seg, 0.0))
            ke.append(np.append(k_ax, 0.0))
            kd.append(np.append(k_ax * p.spring_damping, 0.0))
            bend_k.append(bk)
            kap = next(curve_kappa)
            if float(np.abs(kap).max()) > 1e-6:
                curved = True
            kappa.append(kap)
            ka = np.where(anchored[c0 : c0 + cn], p.anchor_stiffness, 0.0)
            anchor_k.append(ka)
            anchor_kd.append(ka * p.spring_damping)
            node_tube.append(np.full(cn, t_index))
            t_index += 1
            tube_start.append(tube_start[-1] + cn)
    cat = lambda a: np.concatenate(a)  # noqa: E731
    per_node = dict(
        node_rest_q=cat(pts), node_mass=cat(mass), node_inv_mass=cat(inv_mass), node_damping=cat(damping),
        seg_rest_length=cat(rest_len), seg_ke=cat(ke), seg_kd=cat(kd), node_bend_k=cat(bend_k),
        node_kappa_rest=cat(kappa), node_anchor_k=cat(anchor_k), node_anchor_kd=cat(anchor_kd), node_radius=cat(radius),
        tube_node_start=np.array(tube_start), node_tube=cat(node_tube), prim_node_start=np.array(prim_node_start),
    )  # fmt: skip
    return per_node, curved
