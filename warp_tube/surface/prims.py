"""The surfaces of a scene's tube prims: consecutive prims of one kind rebuilt by one builder.

A scene of many tube prims (a hose a prim, as DCC tools make them) would otherwise pay a
:class:`~warp_tube.surface.builder.SurfaceBuilder` per prim: its set-up, a launch and two copies
back per frame. Consecutive prims with the same spoke count, frame convention and caps share one
builder over their nodes (each tube keeps its prim's guard window, reference normal and spoke
lengths, so every vertex is what a builder of its own prim gives, bit for bit); each prim is then
a :class:`PrimSurface`, its vertices picked from the shared builder's in its own topology's order
(body rings hub-major, then its tubes' caps), the topology its own builder would have
(:func:`~warp_tube.surface.topology.split_topology`).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .builder import SurfaceBuilder
from .topology import SurfaceTopology, TopologyView, split_topology

__all__ = ["PrimSurface", "SharedPrims", "prim_surfaces"]


class PrimSurface(TopologyView):
    """One tube prim's surface, rebuilt by a builder it shares with neighbouring prims.

    Attributes:
        builder: the shared :class:`~warp_tube.surface.builder.SurfaceBuilder`.
        topology: the prim's own topology (as a builder of this prim alone makes it).
        body, caps_vertices: where the prim's body vertices and its caps' lie among the builder's
            (its own numbering: the body's, then the caps').
    """

    def __init__(self, builder: SurfaceBuilder, topology: SurfaceTopology, body: slice, caps_vertices: slice):
        self.builder = builder
        self.topology = topology
        self.body, self.caps_vertices = body, caps_vertices
        self.spokes, self.frames, self.caps = builder.spokes, builder.frames, builder.caps
        self.world_count = builder.world_count
        self._extent = None

    def take(self, points: np.ndarray) -> np.ndarray:
        """The prim's vertices of a host array of the builder's, shaped (..., V_builder, 3)."""
        if self.caps_vertices.stop == self.caps_vertices.start:
            return points[..., self.body, :]
        return np.concatenate([points[..., self.body, :], points[..., self.caps_vertices, :]], axis=-2)

    def compute(self, node_q: wp.array) -> tuple[wp.array, wp.array]:
        """Rebuild (the shared builder, every prim of it) and return this prim's points [L] and
        normals, new arrays shaped (world_count, V) on the builder's device (``extent`` after)."""
        pts, nrm = self.builder.compute(node_q)
        p, n = self.take(pts.numpy()), self.take(nrm.numpy())
        self._extent = np.stack([p.min(axis=1), p.max(axis=1)], axis=1)
        dev = self.builder.device
        return wp.array(p, dtype=wp.vec3, device=dev), wp.array(n, dtype=wp.vec3, device=dev)

    def extent(self) -> wp.array:
        """``[min, max]`` corners [L] of the points of the last :meth:`compute`, (world_count, 2)."""
        if self._extent is None:
            raise RuntimeError("extent() before compute()")
        return wp.array(self._extent, dtype=wp.vec3, device=self.builder.device)


class SharedPrims:
    """The prims of one shared builder (``views``, all of them, in order), and where their vertices
    lie in it, worked out once: the prims' body vertices follow one another, and so do their caps'."""

    def __init__(self, views: list[PrimSurface]):
        self.builder = views[0].builder
        self.views = views
        self._body = slice(views[0].body.start, views[-1].body.stop)
        self._caps = slice(views[0].caps_vertices.start, views[-1].caps_vertices.stop)
        self._body_at = np.array([v.body.start for v in views]) - self._body.start
        self._caps_at = np.array([v.caps_vertices.start for v in views]) - self._caps.start

    def extents(self, points: np.ndarray) -> np.ndarray:
        """``[min, max]`` corners of each prim's points, (P, 2, 3), from ``points`` (V_builder, 3),
        the host copy of the builder's points: one reduction per axis over all prims (a reduction
        over the rows of a (V, 3) array is several times slower), exact as the builder's own extent."""
        out = np.empty((len(self.views), 2, 3), dtype=points.dtype)
        for c in range(3):
            col = points[:, c]
            for side, ufunc in enumerate((np.minimum, np.maximum)):
                value = ufunc.reduceat(col[self._body], self._body_at)
                if self._caps.stop > self._caps.start:  # (one kind: every prim capped, or none)
                    value = ufunc(value, ufunc.reduceat(col[self._caps], self._caps_at))
                out[:, side, c] = value
        return out


def _kind(t) -> tuple:
    return (t.params.spokes, t.params.frames, bool(t.params.caps))


def _lengths(t) -> np.ndarray:
    return t.spoke_lengths if t.spoke_lengths is not None else np.repeat(t.radius[:, None], t.params.spokes, axis=1)


def prim_surfaces(tubes, prim_start, device) -> tuple[list, list[SurfaceBuilder], list[SharedPrims]]:
    """Per tube prim its surface (a builder of its own, or a :class:`PrimSurface` of one shared
    with the consecutive prims of its kind), the builders, each once, in prim order, and the
    prims of each shared builder (:class:`SharedPrims`).

    Args:
        tubes: the scene's tube prims (:class:`~warp_tube.scene.spec.TubeSpec`), in node order.
        prim_start: first node of each prim in the model, (prims,) or more.
        device: Warp device.
    """
    per_prim, builders, shared = [], [], []
    k = 0
    while k < len(tubes):
        end = k + 1
        while end < len(tubes) and _kind(tubes[end]) == _kind(tubes[k]):
            end += 1
        group = tubes[k:end]
        t0 = group[0]
        lengths = [_lengths(t) for t in group]
        starts = int(prim_start[k]) + np.concatenate([[0], np.cumsum(np.concatenate([t.curve_counts for t in group]))])
        if len(group) == 1:
            b = SurfaceBuilder(tube_node_start=starts, rest_q=t0.points, spokes=t0.params.spokes, spoke_lengths=lengths[0],
                               reference_normal=t0.params.reference_normal, frames=t0.params.frames, caps=t0.params.caps,
                               world_count=1, device=device)  # fmt: skip
            per_prim.append(b)
            builders.append(b)
            k = end
            continue
        curves = [len(t.curve_counts) for t in group]
        normals = np.concatenate([np.tile(np.full(3, np.nan) if t.params.reference_normal is None
                                          else np.asarray(t.params.reference_normal, dtype=np.float64), (c, 1))
                                  for t, c in zip(group, curves)])  # fmt: skip
        cell = np.repeat([float(x.mean()) for x in lengths], curves)  # each prim's guard window, as its own builder's
        b = SurfaceBuilder(tube_node_start=starts, rest_q=np.concatenate([t.points for t in group]), spokes=t0.params.spokes,
                           spoke_lengths=np.concatenate(lengths), reference_normal=normals, frames=t0.params.frames,
                           caps=t0.params.caps, world_count=1, device=device, cell_radius=cell)  # fmt: skip
        builders.append(b)
        views = _views(b, group)
        per_prim += views
        shared.append(SharedPrims(views))
        k = end
    return per_prim, builders, shared


def _views(b: SurfaceBuilder, group) -> list[PrimSurface]:
    """Each prim of ``group``'s surface within the shared builder ``b``."""
    tubes = np.concatenate([[0], np.cumsum([len(t.curve_counts) for t in group])])
    parts = split_topology(b.topology, b._local_starts, tubes)
    return [PrimSurface(b, topo, body, caps) for topo, body, caps in parts]
