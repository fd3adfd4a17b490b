"""Triangle topology of the hubs-and-spokes surface, built once in NumPy.

Vertices (for one tube prim with ``S`` spokes per hub and ``N`` hubs over all its curves):

- Ring vertices first, hub-major: hub ``i`` (its index in the prim's points, across curves),
  spoke ``j`` is vertex ``i * S + j``. Spoke ``j`` sits at angle ``phi_j = 2 pi j / S`` from the
  hub's normal ``r`` towards ``s = t x r``.
- With caps, the cap vertices of all tubes after all rings, in curve order; per tube: the start
  cap's rings (``K - 1`` rings of ``S``, from the body outwards) and its pole vertex, then the end
  cap's rings and its pole. A cap is a rounded dome on the end hub: ring ``k`` of ``K`` is at polar
  angle ``(pi / 2)(1 - k / K)`` from the outward axis (``-t`` at the start, ``+t`` at the end);
  ``K = max(2, ceil(S / 4))`` keeps the cap's meridian steps about as long as the ring's chords.

Faces are triangles, counter-clockwise seen from outside (USD's default ``rightHanded``
orientation): each pair of consecutive rings of a tube is joined by a strip of ``2 S`` triangles
(``(hubs - 1) * S * 2`` per tube body), a cap adds ``2 S`` per ring step and a fan of ``S`` to the
pole.

Texture coordinates ``st`` are face-varying (one value per face corner), so the ring's seam gets
``u = 1`` on one side and ``u = 0`` on the other and the texture does not wrap backwards; ``u = j / S``
around, ``v`` along: the rest arc length from the tube's first hub over the tube's rest length
(0 .. 1 over the body; a cap continues below 0 / above 1 by its meridian arc length).

The ring table (:class:`SurfaceTopology` ``ring_*`` arrays) tells the surface kernels, for every
ring, its hub, the cosine and sine of its spokes' angle to the hub tangent, its kind (body, cap,
pole) and its first vertex.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..kernels.surface_arrays import RING_BODY, RING_CAP, RING_POLE

__all__ = ["RING_BODY", "RING_CAP", "RING_POLE", "SurfaceTopology", "cap_ring_count", "build_topology", "tube_topology", "split_topology", "TopologyView"]


def cap_ring_count(spokes: int) -> int:
    """Ring steps ``K`` of one cap (``K - 1`` rings and a pole) for ``spokes`` spokes per hub."""
    return max(2, int(math.ceil(spokes / 4)))


@dataclass(frozen=True)
class SurfaceTopology:
    """Static topology of one tube prim's surface.

    Attributes:
        spokes: spokes per hub, S.
        caps: whether the tube ends are closed by caps.
        hub_count: hubs of all tubes, N.
        vertex_count: vertices, V = N S (+ per tube 2 ((K - 1) S + 1) with caps).
        face_vertex_counts: int32 (F,), all 3 (read-only).
        face_vertex_indices: int32 (3 F,).
        st: float32 (3 F, 2), face-varying texture coordinates (u around, v along).
        st_interpolation: "faceVarying".
        ring_hub: int32 (R,), hub of each ring (index into the prim's hubs).
        ring_kind: int32 (R,), :data:`RING_BODY`, :data:`RING_CAP` or :data:`RING_POLE`.
        ring_cos, ring_sin: float32 (R,), cosine and sine of the spokes' angle to the tangent.
        ring_vertex: int32 (R,), first vertex of each ring.
    """

    spokes: int
    caps: bool
    hub_count: int
    vertex_count: int
    face_vertex_counts: np.ndarray
    face_vertex_indices: np.ndarray
    st: np.ndarray
    st_interpolation: str
    ring_hub: np.ndarray
    ring_kind: np.ndarray
    ring_cos: np.ndarray
    ring_sin: np.ndarray
    ring_vertex: np.ndarray

    @property
    def face_count(self) -> int:
        return len(self.face_vertex_counts)

    @property
    def faces(self) -> np.ndarray:
        """Triangles as vertex indices, int32 (F, 3)."""
        return self.face_vertex_indices.reshape(-1, 3)


class TopologyView:
    """A surface's counts, faces and texture coordinates, read from its ``topology``
    (:class:`SurfaceTopology`): what the output writer reads of a surface."""

    topology: SurfaceTopology

    @property
    def vertex_count(self) -> int:
        return self.topology.vertex_count

    @property
    def face_vertex_counts(self) -> np.ndarray:
        """int32 (F,), all 3."""
        return self.topology.face_vertex_counts

    @property
    def face_vertex_indices(self) -> np.ndarray:
        """int32 (3 F,), counter-clockwise seen from outside."""
        return self.topology.face_vertex_indices

    @property
    def st(self) -> np.ndarray:
        """float32 (3 F,) x 2 face-varying texture coordinates (u around, v along)."""
        return self.topology.st

    @property
    def st_interpolation(self) -> str:
        return self.topology.st_interpolation


def _strip_pattern(spokes: int, forward: bool):
    """One strip of ``2 S`` triangles joining ring ``a`` to ring ``b`` (``b`` further along), per
    corner: whether it is on ring ``b``, its spoke, and its ``u`` around; each shaped (2 S, 3).
    Triangles ``2 j`` and ``2 j + 1`` join spokes ``j`` and ``j + 1`` (mod S), counter-clockwise
    seen from outside when ``forward``."""
    j = np.arange(spokes)[:, None, None]
    # corners a = (ring a, j), b = (ring a, j + 1), c = (ring b, j), d = (ring b, j + 1)
    on_b = np.array([[0, 0, 1], [0, 1, 1]] if forward else [[0, 1, 0], [0, 1, 1]], dtype=bool)
    next_spoke = np.array([[0, 1, 1], [0, 1, 0]] if forward else [[0, 1, 1], [0, 0, 1]], dtype=bool)
    spoke = np.where(next_spoke, (j + 1) % spokes, j)
    u = np.where(next_spoke, (j + 1) / spokes, j / spokes)
    shape = (2 * spokes, 3)
    return np.broadcast_to(on_b, (spokes, 2, 3)).reshape(shape), spoke.reshape(shape), u.reshape(shape)


def _strips_into(tri_out, st_out, ring_a, ring_b, va, vb, spokes: int, forward: bool):
    """Write M strips: triangles into ``tri_out`` (M, 2 S, 3) int32 and face-varying st into
    ``st_out`` (M, 2 S, 3, 2) float32; strip ``m`` joins the ring whose first vertex is
    ``ring_a[m]`` (``v = va[m]``) to ``ring_b[m]`` (``v = vb[m]``)."""
    on_b, spoke, u = _strip_pattern(spokes, forward)
    ring_a = np.asarray(ring_a, dtype=np.int64)
    step = np.asarray(ring_b, dtype=np.int64) - ring_a
    if len(step) and np.all(step == step[0]):  # one pass: ring b is a fixed number of vertices on
        np.add(ring_a.astype(np.int32)[:, None, None], (spoke + on_b * step[0]).astype(np.int32)[None], out=tri_out)
    else:
        np.add(ring_a.astype(np.int32)[:, None, None], spoke.astype(np.int32)[None], out=tri_out)
        np.add(tri_out, step.astype(np.int32)[:, None, None], out=tri_out, where=on_b[None])
    # st of a strip is [1, va, vb] times a fixed (3, 2 S * 3 * 2) pattern: its u, and 0/1 picking
    # va or vb for each corner's v. Every corner gets one term and exact zeros, so the product is
    # exactly (u, va or vb) in float32; one matrix product writes it all.
    pattern = np.zeros((3, 2 * spokes, 3, 2), dtype=np.float32)
    pattern[0, ..., 0] = u
    pattern[1, ..., 1] = ~on_b
    pattern[2, ..., 1] = on_b
    coef = np.empty((len(ring_a), 3), dtype=np.float32)
    coef[:, 0] = 1.0
    coef[:, 1] = np.asarray(va, dtype=np.float64)
    coef[:, 2] = np.asarray(vb, dtype=np.float64)
    np.matmul(coef, pattern.reshape(3, -1), out=st_out.reshape(len(ring_a), -1))


def _fans_into(tri_out, st_out, ring_a, pole, va, vp, spokes: int, forward: bool):
    """Write M fans: triangles into ``tri_out`` (M, S, 3) int32 and st into ``st_out``
    (M, S, 3, 2) float32; fan ``m`` joins ring ``ring_a[m]`` (``v = va[m]``) to the pole vertex
    ``pole[m]`` (``v = vp[m]``), triangle ``j`` joining spokes ``j`` and ``j + 1`` (mod S)."""
    j = np.arange(spokes)
    # corners: a = spoke j, b = spoke j + 1, p = the pole; st u of p is (j + 0.5) / S
    order = (0, 1, 2) if forward else (0, 2, 1)
    spoke = np.stack([j, (j + 1) % spokes, np.zeros_like(j)], -1)[:, order]
    u = np.stack([j / spokes, (j + 1) / spokes, (j + 0.5) / spokes], -1)[:, order]
    is_pole = np.broadcast_to(np.array([False, False, True])[list(order)], (spokes, 3))
    np.add(np.asarray(ring_a, dtype=np.int32)[:, None, None], spoke.astype(np.int32)[None], out=tri_out)
    np.copyto(tri_out, np.asarray(pole, dtype=np.int32)[:, None, None], where=is_pole[None])
    pattern = np.zeros((3, spokes, 3, 2), dtype=np.float32)  # as in _strips_into: [1, va, vp] x pattern
    pattern[0, ..., 0] = u
    pattern[1, ..., 1] = ~is_pole
    pattern[2, ..., 1] = is_pole
    coef = np.empty((len(tri_out), 3), dtype=np.float32)
    coef[:, 0] = 1.0
    coef[:, 1] = np.asarray(va, dtype=np.float64)
    coef[:, 2] = np.asarray(vp, dtype=np.float64)
    out = np.matmul(coef, pattern.reshape(3, -1))
    st_out[...] = out.reshape(st_out.shape)


def _arc_fractions(rest_q, starts: np.ndarray):
    """Per hub, the rest arc length from its tube's first hub over the tube's rest length, (N,),
    and the tubes' rest lengths (T,) (1 where a tube has none); uniform in the hub index without
    ``rest_q``. Each tube's arc is its own running sum, as one tube alone would have it."""
    n_hubs = int(starts[-1])
    counts = np.diff(starts)
    if rest_q is not None:
        seg = np.linalg.norm(np.diff(np.asarray(rest_q, dtype=np.float64), axis=0), axis=1)
    else:
        seg = np.ones(max(n_hubs - 1, 0))
    v_hub = np.empty(n_hubs)
    tube_len = np.empty(len(counts))
    for n in np.unique(counts):  # tubes of one length at a time: a (tubes, n - 1) running sum
        tubes = np.flatnonzero(counts == n)
        hubs = starts[tubes][:, None] + np.arange(n)[None]
        arc = np.zeros((len(tubes), n))
        np.cumsum(seg[hubs[:, :-1]], axis=1, out=arc[:, 1:])
        total = arc[:, -1]
        total = np.where(total > 0, total, 1.0)
        tube_len[tubes] = total
        v_hub[hubs] = arc / total[:, None]
    return v_hub, tube_len


def build_topology(
    tube_node_start: np.ndarray,
    spokes: int,
    *,
    caps: bool = False,
    rest_q: np.ndarray | None = None,
    cap_radius: np.ndarray | None = None,
) -> SurfaceTopology:
    """Build the topology and ring table of one tube prim, with array operations over all hubs.

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
    v_hub, tube_len = _arc_fractions(rest_q, starts)

    # Body: a strip from every hub but a tube's last to the next hub, tubes and hubs in order;
    # with caps, after all the strips, every end's K - 1 strips and fan (ends in order: tube 0
    # start, tube 0 end, tube 1 start, ...), each growing outwards from its end hub. Written
    # straight into the final arrays.
    last = np.zeros(n_hubs, dtype=bool)
    last[starts[1:] - 1] = True
    seg_hub = np.flatnonzero(~last)
    n_body = len(seg_hub) * 2 * S
    per_end_tris = (2 * K - 1) * S if caps else 0
    n_faces = n_body + 2 * n_tubes * per_end_tris
    tri = np.empty((n_faces, 3), dtype=np.int32)
    st = np.empty((n_faces, 3, 2), dtype=np.float32)
    M = len(seg_hub)
    _strips_into(tri[:n_body].reshape(M, 2 * S, 3), st[:n_body].reshape(M, 2 * S, 3, 2), seg_hub * S,
                 (seg_hub + 1) * S, v_hub[seg_hub], v_hub[seg_hub + 1], S, True)  # fmt: skip
    ring_hub = [np.arange(n_hubs)]
    ring_kind = [np.full(n_hubs, RING_BODY)]
    ring_cos = [np.zeros(n_hubs)]
    ring_sin = [np.ones(n_hubs)]
    ring_vertex = [np.arange(n_hubs) * S]
    vertex_count = n_hubs * S

    if caps:
        # Each end adds K - 1 rings of S vertices and a pole.
        hub = np.stack([starts[:-1], starts[1:] - 1], axis=1)  # (T, 2)
        sign = np.array([-1.0, 1.0])
        radius = np.asarray(cap_radius, dtype=np.float64) if cap_radius is not None else 0.1 * tube_len[:, None] * np.ones(2)
        dv = 0.5 * math.pi * radius / tube_len[:, None] / K  # (T, 2)
        k = np.arange(1, K + 1)
        beta = [0.5 * math.pi * (1.0 - kk / K) for kk in k]
        cos_b = np.array([math.cos(b) for b in beta])
        sin_b = np.array([math.sin(b) if kk < K else 0.0 for kk, b in zip(k, beta)])
        per_end = (K - 1) * S + 1
        base = vertex_count + per_end * np.arange(2 * n_tubes).reshape(n_tubes, 2)  # first cap vertex
        ring_first = base[:, :, None] + (k[None, None] - 1) * S  # (T, 2, K); k = K: the pole
        v = v_hub[hub][:, :, None] + (sign[None, :, None] * k[None, None]) * dv[:, :, None]  # (T, 2, K)
        prev_ring = np.concatenate([(hub * S)[:, :, None], ring_first[:, :, :-1]], axis=2)
        prev_v = np.concatenate([v_hub[hub][:, :, None], v[:, :, :-1]], axis=2)
        ring_hub.append(np.broadcast_to(hub[:, :, None], (n_tubes, 2, K)).reshape(-1))
        ring_cos.append((sign[None, :, None] * cos_b[None, None]).repeat(n_tubes, axis=0).reshape(-1))
        ring_sin.append(np.broadcast_to(sin_b, (n_tubes, 2, K)).reshape(-1))
        ring_vertex.append(ring_first.reshape(-1))
        ring_kind.append(np.broadcast_to(np.where(k < K, RING_CAP, RING_POLE), (n_tubes, 2, K)).reshape(-1))
        cap_tri = tri[n_body:].reshape(n_tubes, 2, per_end_tris, 3)
        cap_st = st[n_body:].reshape(n_tubes, 2, per_end_tris, 3, 2)
        n_strip = 2 * (K - 1) * S
        for end in (0, 1):
            forward = end == 1
            flat = lambda a: a[:, end, : K - 1].reshape(-1)  # noqa: E731
            strip_tri = np.empty((n_tubes * (K - 1), 2 * S, 3), dtype=np.int32)
            strip_st = np.empty((n_tubes * (K - 1), 2 * S, 3, 2), dtype=np.float32)
            _strips_into(strip_tri, strip_st, flat(prev_ring), flat(ring_first), flat(prev_v), flat(v), S, forward)
            cap_tri[:, end, :n_strip] = strip_tri.reshape(n_tubes, n_strip, 3)
            cap_st[:, end, :n_strip] = strip_st.reshape(n_tubes, n_strip, 3, 2)
            _fans_into(cap_tri[:, end, n_strip:], cap_st[:, end, n_strip:], prev_ring[:, end, -1], ring_first[:, end, -1],
                       prev_v[:, end, -1], v[:, end, -1], S, forward)  # fmt: skip
        vertex_count += 2 * n_tubes * per_end

    faces = tri
    st = st.reshape(-1, 2)
    return SurfaceTopology(
        spokes=S,
        caps=bool(caps),
        hub_count=n_hubs,
        vertex_count=vertex_count,
        face_vertex_counts=np.broadcast_to(np.int32(3), (len(faces),)),  # all 3: a read-only view, no memory
        face_vertex_indices=faces.reshape(-1),
        st=st,
        st_interpolation="faceVarying",
        ring_hub=np.concatenate(ring_hub).astype(np.int32),
        ring_kind=np.concatenate(ring_kind).astype(np.int32),
        ring_cos=np.concatenate(ring_cos).astype(np.float32),
        ring_sin=np.concatenate(ring_sin).astype(np.float32),
        ring_vertex=np.concatenate(ring_vertex).astype(np.int32),
    )


def tube_topology(tube_node_start, spokes: int, spoke_lengths: np.ndarray, caps: bool, rest_q) -> SurfaceTopology:
    """The topology of one tube prim as its surface builder makes it: :func:`build_topology` with
    the caps' radii (with ``caps``) the mean spoke length [m] at each tube's end hubs.

    Args:
        tube_node_start: first hub of each tube, (T + 1,), from 0.
        spokes: spokes per hub, S.
        spoke_lengths: spoke lengths [m], (N, S).
        caps: close both ends of every tube.
        rest_q: rest hub positions [m], (N, 3).
    """
    starts = np.asarray(tube_node_start, dtype=np.int64)
    cap_radius = None
    if caps:
        mean = np.asarray(spoke_lengths).mean(axis=1)
        cap_radius = np.stack([mean[starts[:-1]], mean[starts[1:] - 1]], axis=1)
    return build_topology(starts, spokes, caps=caps, rest_q=rest_q, cap_radius=cap_radius)


def split_topology(topo: SurfaceTopology, tube_node_start, prim_tube_start) -> list[tuple[SurfaceTopology, slice, slice]]:
    """The topologies of consecutive prims whose tubes ``topo`` (built by :func:`build_topology`)
    holds together, each as :func:`build_topology` makes it for the prim alone (given the same
    tubes, rest positions and cap radii; checked in the tests), with where the prim's vertices lie
    in ``topo``'s: a slice of its body vertices and one of its cap vertices.

    Args:
        topo: the topology of all the prims' tubes.
        tube_node_start: first hub of each tube, (T + 1,), as ``topo`` was built with.
        prim_tube_start: first tube of each prim, (P + 1,), from 0 to T.
    """
    S = topo.spokes
    starts = np.asarray(tube_node_start, dtype=np.int64)
    tubes = np.asarray(prim_tube_start, dtype=np.int64)
    n_hubs = int(starts[-1])
    K = cap_ring_count(S) if topo.caps else 0
    per_end = (K - 1) * S + 1 if topo.caps else 0
    per_end_tris = (2 * K - 1) * S if topo.caps else 0
    hub0 = starts[tubes]  # first hub of each prim, (P + 1,)
    body_v = hub0 * S
    cap_v = n_hubs * S + 2 * per_end * tubes
    body_f = np.concatenate([[0], np.cumsum(np.diff(hub0) - np.diff(tubes))]) * 2 * S  # a strip per segment
    cap_f = int(body_f[-1]) + 2 * per_end_tris * tubes
    cap_r = n_hubs + 2 * K * tubes
    # each vertex's index in its prim's own numbering: body vertices first, then its caps'
    local = np.arange(topo.vertex_count, dtype=np.int64)
    prim_of_hub = np.repeat(np.arange(len(tubes) - 1), np.diff(hub0))
    local[: n_hubs * S] -= body_v[prim_of_hub].repeat(S)
    if topo.caps:
        prim_of_cap = np.repeat(np.arange(len(tubes) - 1), np.diff(cap_v))
        local[n_hubs * S :] += (np.diff(hub0) * S)[prim_of_cap] - cap_v[prim_of_cap]
    faces = topo.faces
    st = topo.st.reshape(-1, 3, 2)
    out = []
    for p in range(len(tubes) - 1):
        fb, fc = slice(body_f[p], body_f[p + 1]), slice(cap_f[p], cap_f[p + 1])
        rb, rc = slice(hub0[p], hub0[p + 1]), slice(cap_r[p], cap_r[p + 1])
        tri = local[np.concatenate([faces[fb], faces[fc]])].astype(np.int32)

        def rings(a):
            return np.concatenate([a[rb], a[rc]])

        n = int(hub0[p + 1] - hub0[p])
        sub = SurfaceTopology(
            spokes=S, caps=topo.caps, hub_count=n, vertex_count=int(n * S + (cap_v[p + 1] - cap_v[p])),
            face_vertex_counts=np.broadcast_to(np.int32(3), (len(tri),)), face_vertex_indices=tri.reshape(-1),
            st=np.concatenate([st[fb], st[fc]]).reshape(-1, 2), st_interpolation=topo.st_interpolation,
            ring_hub=(rings(topo.ring_hub) - hub0[p]).astype(np.int32), ring_kind=rings(topo.ring_kind),
            ring_cos=rings(topo.ring_cos), ring_sin=rings(topo.ring_sin),
            ring_vertex=local[rings(topo.ring_vertex)].astype(np.int32),
        )  # fmt: skip
        out.append((sub, slice(int(body_v[p]), int(body_v[p + 1])), slice(int(cap_v[p]), int(cap_v[p + 1]))))
    return out
