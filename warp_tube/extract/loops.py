"""Boundary loops of a triangle mesh (its open ends and holes) and the mesh with them closed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

__all__ = ["BoundaryLoop", "boundary_loops", "cap_loops"]


@dataclass(frozen=True)
class BoundaryLoop:
    """One closed loop of boundary edges (an open end or a hole).

    Attributes:
        vertices: vertex indices in loop order, shape (k,).
        centroid: mean of the loop's vertices [mesh units], shape (3,).
        radius: mean distance of the loop's vertices from the centroid [mesh units].
        normal: unit normal of the loop's best-fit plane, shape (3,) (sign arbitrary).
        extent: largest distance of the loop's vertices from the centroid [mesh units].
    """

    vertices: np.ndarray
    centroid: np.ndarray
    radius: float
    normal: np.ndarray
    extent: float


def boundary_loops(mesh: trimesh.Trimesh) -> list[BoundaryLoop]:
    """Closed loops of the edges that belong to one face only, largest radius first."""
    f = np.asarray(mesh.faces, dtype=np.int64)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = np.sort(directed, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    bnd = directed[cnt[inv.reshape(-1)] == 1]
    if len(bnd) == 0:
        return []
    nxt: dict[int, list[int]] = {}
    for a, b in bnd.tolist():
        nxt.setdefault(a, []).append(b)
    used: set[tuple[int, int]] = set()
    v = np.asarray(mesh.vertices, dtype=np.float64)
    loops = []
    chains: list[list[int]] = []
    for a0, b0 in bnd.tolist():
        if (a0, b0) in used:
            continue
        chain = [a0]
        a, b = a0, b0
        while (a, b) not in used:
            used.add((a, b))
            if b == a0:
                break
            chain.append(b)
            cands = [c for c in nxt.get(b, []) if (b, c) not in used]
            if not cands:
                break
            a, b = b, cands[0]
        chains.append(chain)
    # A loop that touches itself at a vertex (a pinch) is traced as several closed walks: splice
    # walks that share a vertex into one (Hierholzer), so that one opening is one loop.
    merged = True
    while merged:
        merged = False
        for i in range(len(chains)):
            for j in range(i + 1, len(chains)):
                common = set(chains[i]) & set(chains[j])
                if common:
                    x = next(iter(common))
                    a, b = chains[i], chains[j]
                    k, m = a.index(x), b.index(x)
                    chains[i] = a[: k + 1] + b[m + 1 :] + b[: m + 1] + a[k + 1 :]
                    del chains[j]
                    merged = True
                    break
            if merged:
                break
    for chain in chains:
        if len(set(chain)) < 3:
            continue
        pts = v[chain]
        c = pts.mean(axis=0)
        _, _, vt = np.linalg.svd(pts - c, full_matrices=False)
        dist = np.linalg.norm(pts - c, axis=1)
        loops.append(BoundaryLoop(np.asarray(chain, dtype=np.int64), c, float(dist.mean()), vt[2], float(dist.max())))
    loops.sort(key=lambda lp: -lp.radius)
    return loops


def cap_loops(mesh: trimesh.Trimesh, loops: list[BoundaryLoop]) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of ``mesh`` with every loop closed by a fan around its centroid.

    Returns:
        ``(vertices (V + L, 3), faces (F + sum k, 3))``; the fans' orientation is arbitrary, which
        is fine for ray parity and distances.
    """
    v = [np.asarray(mesh.vertices, dtype=np.float64)]
    f = [np.asarray(mesh.faces, dtype=np.int64)]
    n = len(v[0])
    for lp in loops:
        ring = lp.vertices
        fan = np.stack([np.full(len(ring), n), ring, np.roll(ring, -1)], axis=1)
        v.append(lp.centroid[None, :])
        f.append(fan)
        n += 1
    return np.concatenate(v), np.concatenate(f)
