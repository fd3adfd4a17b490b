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

__all__ = ["RING_BODY", "RING_CAP", "RING_POLE", "SurfaceTopology", "cap_ring_count", "build_topology"]


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
        face_vertex_counts: int32 (F,), all 3.
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


def build_topology(
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
