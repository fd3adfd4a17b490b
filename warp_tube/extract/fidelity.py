"""How well extracted hubs and spokes rebuild the mesh they came from.

The rest surface is rebuilt the way the simulator rebuilds it (rings ``hub + spoke_length *
direction``, frames.py convention, consecutive rings joined by triangle strips, ends left open),
and each input vertex's distance to it is measured with a ``wp.Mesh`` closest-point query.
Vertices within one local radius of either end (along the centerline) and vertices nearer to a
side branch's path than to the centerline are left out: the rebuilt tube has neither caps nor
branches.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from ..model.frames import rotation_minimizing_frames, spoke_directions
from ..kernels import raycast
from .polyline import arclength, nearest_on_polyline

if TYPE_CHECKING:
    import trimesh

    from .pipeline import ExtractedTube

__all__ = ["ring_surface", "rebuild_surface", "Fidelity", "fidelity_of", "surface_fidelity"]


def ring_surface(points: np.ndarray, spoke_lengths: np.ndarray, reference_normal: np.ndarray):
    """Rest surface of hubs and spokes.

    Args:
        points: hubs, shape (n, 3); spoke_lengths: shape (n, S); reference_normal: shape (3,).

    Returns:
        ``(vertices (n * S, 3), faces (2 * (n - 1) * S, 3))``; vertex ``i * S + j`` is spoke j of
        hub i (the output contract's order).
    """
    n, m = spoke_lengths.shape
    _, r, s = rotation_minimizing_frames(points, None, reference_normal)
    v = (points[:, None, :] + spoke_lengths[..., None] * spoke_directions(r, s, m)).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(m), indexing="ij")
    a = i * m + j
    b = i * m + (j + 1) % m
    faces = np.concatenate(
        [np.stack([a, b, b + m], -1).reshape(-1, 3), np.stack([a, b + m, a + m], -1).reshape(-1, 3)]
    )
    return v, faces


def rebuild_surface(tube: ExtractedTube):
    """:func:`ring_surface` of an extracted tube."""
    return ring_surface(tube.points, tube.spoke_lengths, tube.reference_normal)


@dataclass(frozen=True)
class Fidelity:
    """Distances from input vertices to the rebuilt surface, as fractions of the mean radius.

    Attributes:
        mean: mean distance / mean radius.
        p95: 95th percentile distance / mean radius.
        max: largest distance / mean radius.
        mean_radius: mean spoke length [mesh units].
        counted: vertices measured.
        left_out: vertices near the ends or on side branches.
    """

    mean: float
    p95: float
    max: float
    mean_radius: float
    counted: int
    left_out: int


def fidelity_of(points, spoke_lengths, reference_normal, vertices, branch_paths=(), device=None) -> Fidelity:
    """Fidelity of hubs and spokes to mesh ``vertices`` (same units), shape (V, 3)."""
    device = wp.get_device(device)
    points = np.asarray(points, dtype=np.float64)
    spoke_lengths = np.asarray(spoke_lengths, dtype=np.float64)
    verts = np.asarray(vertices, dtype=np.float64)
    radius = spoke_lengths.mean(axis=1)
    step = 0.125 * float(radius.min())
    dist_line, arc = nearest_on_polyline(verts, points, step)
    s = arclength(points)
    keep = (arc > radius[0]) & (arc < s[-1] - radius[-1])
    for path in branch_paths:
        path = np.asarray(path, dtype=np.float64).reshape(-1, 3)
        if len(path):
            d_b = nearest_on_polyline(verts, path, step)[0] if len(path) > 1 else np.linalg.norm(verts - path[0], axis=1)
            keep &= ~(d_b < dist_line)
    shift = points.mean(axis=0)
    v, f = ring_surface(points, spoke_lengths, reference_normal)
    pts = wp.array((v - shift).astype(np.float32), dtype=wp.vec3, device=device)
    idx = wp.array(f.astype(np.int32).reshape(-1), dtype=wp.int32, device=device)
    wmesh = wp.Mesh(points=pts, indices=idx)
    query = wp.array((verts[keep] - shift).astype(np.float32), dtype=wp.vec3, device=device)
    out = wp.empty(query.shape[0], dtype=float, device=device)
    big = 4.0 * float(np.ptp(verts, axis=0).max()) + 1.0
    wp.launch(raycast.closest_distance, dim=query.shape[0], inputs=[wmesh.id, query, big], outputs=[out],
              device=device)
    d = out.numpy().astype(np.float64)
    r = float(radius.mean())
    if len(d) == 0:
        return Fidelity(float("nan"), float("nan"), float("nan"), r, 0, len(verts))
    return Fidelity(float(d.mean() / r), float(np.percentile(d, 95) / r), float(d.max() / r), r,
                    int(keep.sum()), int((~keep).sum()))


def surface_fidelity(tube: ExtractedTube, mesh: trimesh.Trimesh, device=None) -> Fidelity:
    """Fidelity of ``tube`` to ``mesh`` (the mesh it was extracted from, after the same scale)."""
    return fidelity_of(tube.points, tube.spoke_lengths, tube.reference_normal, mesh.vertices,
                       [b.path for b in tube.branch_details], device)
