"""Warp meshes of a tube being extracted and the queries run on them: rays, distances, diameters.

Three meshes are kept: the *wall* (the input with its small holes closed: rays and distances see
the real tube, open ends stay open), the *closed* mesh (every boundary loop closed by a fan: inside
tests, and the test whether a ray leaves the tube through an open loop before it meets the wall)
and the input as given (whether a ray leaves through any hole at all).
Lengths are in the mesh's units; the host arrays are float64, the Warp ones float32 (callers work
near the origin, so that float32 keeps the precision of small tubes far from it).
"""

from __future__ import annotations

import numpy as np
import trimesh
import warp as wp

from ..kernels import raycast
from .mesh_io import unit_face_normals

__all__ = ["MeshQueries"]


class MeshQueries:
    """``wp.Mesh`` of the tube's wall and of its closed version, and queries on them.

    Args:
        wall_v, wall_f: the wall (small holes closed): vertices (V, 3), triangles (F, 3).
        closed_v, closed_f: every loop closed.
        device: Warp device.
        raw: the mesh as given, ``(vertices, triangles)`` (default: the wall), for the test whether
            a ray leaves through any hole.
    """

    def __init__(self, wall_v, wall_f, closed_v, closed_f, device, raw=None):
        self.device = device
        self._keep = []
        self.wall = self._mesh(wall_v, wall_f)
        self.closed = self._mesh(closed_v, closed_f)
        self.raw = self._mesh(*raw) if raw is not None else self.wall
        #: whether the tube's sections are flat (:mod:`warp_tube.extract.flat`): ray hits on their long
        #: sides belong to them (:func:`warp_tube.extract.sections.ring_hits`)
        self.flat = False
        #: where long, narrow side branches leave the tube: ``(centres (k, 3), reach (k,))`` [mesh
        #: units], or None; sections within reach of one are not measured but bridged
        #: (:func:`warp_tube.extract.sections.near_junction`)
        self.junctions = None

    def _mesh(self, v, f):
        pts = wp.array(np.asarray(v, dtype=np.float32), dtype=wp.vec3, device=self.device)
        idx = wp.array(np.asarray(f, dtype=np.int32).reshape(-1), dtype=wp.int32, device=self.device)
        m = wp.Mesh(points=pts, indices=idx)
        self._keep.append((pts, idx))
        return m

    def _vec3(self, a) -> wp.array:
        return wp.array(np.asarray(a, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3, device=self.device)

    def rays(self, mesh, origins, dirs, max_t) -> np.ndarray:
        """Nearest hit distance per ray, -1 on a miss; origins, unit dirs shape (..., 3) -> shape (...)."""
        shp = np.shape(origins)[:-1]
        o = self._vec3(origins)
        if o.shape[0] == 0:
            return np.zeros(shp)
        out = wp.empty(o.shape[0], dtype=float, device=self.device)
        wp.launch(raycast.cast_rays, dim=o.shape[0], inputs=[mesh.id, o, self._vec3(dirs), float(max_t)], outputs=[out],
                  device=self.device)  # fmt: skip
        return out.numpy().astype(np.float64).reshape(shp)

    def distance(self, points, max_dist, mesh=None) -> np.ndarray:
        """Distance from each point to the wall (or ``mesh``), shape (n,); ``max_dist`` where farther."""
        p = self._vec3(points)
        if p.shape[0] == 0:
            return np.zeros(0)
        out = wp.empty(p.shape[0], dtype=float, device=self.device)
        mid = (mesh or self.wall).id
        wp.launch(raycast.closest_distance, dim=p.shape[0], inputs=[mid, p, float(max_dist)], outputs=[out],
                  device=self.device)  # fmt: skip
        return out.numpy().astype(np.float64)

    def inner_diameters(self, mesh: trimesh.Trimesh, max_t: float, samples: int = 4000) -> np.ndarray:
        """Distances across the tube from up to ``samples`` face centroids (valid ones only)."""
        step = max(1, len(mesh.faces) // samples)
        c = np.asarray(mesh.triangles_center[::step])
        n = unit_face_normals(mesh)[::step]
        ok = np.isfinite(n).all(axis=1) & (np.linalg.norm(n, axis=1) > 0.5)
        c, n = c[ok], n[ok]
        out = wp.empty(len(c), dtype=float, device=self.device)
        offset = 1e-4 * max_t
        wp.launch(raycast.inner_diameter, dim=len(c), inputs=[self.closed.id, self._vec3(c), self._vec3(n), offset,
                                                             float(max_t)], outputs=[out], device=self.device)  # fmt: skip
        t = out.numpy().astype(np.float64)
        return t[t > 2.0 * offset]
