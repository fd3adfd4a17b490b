"""The tube's radius before its axis is known: chords across it from its wall, checked from inside.

The voxel size of the distance map, which open loops may be ends, the least area of a flat cut, the
first hub count and the least hub spacing all scale with the tube's radius, which is needed before
the axis is found. Two measures:

- *chords from the wall*: from up to 4000 face centroids along the face normal, through the solid,
  to the opposite wall (:meth:`~warp_tube.extract.queries.MeshQueries.inner_diameters`). On a
  smooth wall these are the tube's diameters: half their median is the median radius, half their
  10th percentile the radius of the narrow parts.
- *widths from inside*: at :data:`WIDTH_POINTS` points spread through the inside (centres of the
  inside voxels of a coarse grid, :func:`warp_tube.extract.distance_map.inside_voxels`), the chords
  through the point along :data:`WIDTH_DIRECTIONS` directions spread over a hemisphere; the point's
  width is half the lower quartile of its chords (on a tube's axis, about a radius; nearer the
  wall, less). On the synthetic and real test meshes (``benchmarks/bench_extract.py``) the median
  width is 0.75 to 0.98 of the chords' median radius, and their narrow radius 0.65 of it or more.

On a rough wall (the noise of a scan or a segmentation, of an edge length or more) the face
normals point anywhere, and most chords from
the wall cross a fold of it: their 10th percentile (and with more noise their median) drops to the
size of the folds, a tenth of the radius or less, which would make the distance map's voxels tiny
(minutes instead of seconds), every triangle a candidate flat end and the hub count many times too
large. The widths from inside do not see folds: a point's chords pass between them. Where the
chords' narrow radius is less than :data:`ROUGH` times the median width, the wall is taken as rough:
chords shorter than the median width are left out (noise of a tenth of the radius puts the
narrow radius at a twentieth of the width, of a fifth in any direction at a fiftieth), and where
too few are left (at least :data:`MIN_KEPT` of them), the median width stands for the radius and
half of it for the narrow one. Measuring the widths takes about 3 ms on one CPU core.

With more noise (spikes of half a radius: a fifth of the radius and more along the normals) the
widths from inside are cut short by the inward spikes too (a capsule of radius 5 read as 1.8-2.1 at
noise of 0.2 radii, 0.7-1.0 at 0.25), and the distance map's voxels, which follow the radius,
became 2.5 to 6 times too fine (seconds to tens of seconds). So on a rough wall the radii are
measured again, the same two ways, on a copy of the mesh smoothed by :data:`SMOOTHING_PASSES`
passes of Taubin's filter (a low-pass that does not shrink: noise of an edge length or two goes,
a tube's cross-section of tens of edges stays): 4.3-4.4 and 4.2-4.3 there, 4.5-4.9 for straight
tubes (:func:`rough_scale`). The wall is still rough: what follows measures it past the noise.

Lengths are in the mesh's units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import distance_map as dmap
from .queries import MeshQueries

__all__ = ["TubeScale", "tube_scale", "rough_scale", "inside_widths", "ROUGH", "MIN_KEPT", "WIDTH_POINTS", "WIDTH_DIRECTIONS",
           "SMOOTHING_PASSES"]  # fmt: skip

ROUGH = 0.25
"""The wall is rough when the chords' narrow radius is less than this times the median width."""
MIN_KEPT = 0.05
"""On a rough wall, the least fraction of the chords (and at least 8) that must be as long as the
median width for the chords to give the radii."""
WIDTH_POINTS = 96
"""Points of the inside whose width is measured."""
WIDTH_DIRECTIONS = 8
"""Chords through each of them (directions spread over a hemisphere)."""
SMOOTHING_PASSES = 10
"""Passes of Taubin's filter (lambda 0.5, mu -0.53) over a rough wall before its radii are measured
again (:func:`rough_scale`)."""
_GRID_CELLS = 3.0e4  # cells of the first grid over the bounding box, for the inside points
_MAX_CELLS = 6.0e6  # finest grid tried, in cells over the bounding box


@dataclass(frozen=True)
class TubeScale:
    """The tube's radius as known before its axis.

    Attributes:
        median: median radius [mesh units].
        narrow: radius of the narrow parts (10th percentile) [mesh units].
        width: median width from inside [mesh units] (0 where the inside had no grid point).
        rough: whether the wall was taken as rough (the chords from it crossed folds).
        kept: the chords from the wall that gave the radii (all on a smooth wall; 0 where the
            width stands for them).
        chords: chords measured.
    """

    median: float
    narrow: float
    width: float
    rough: bool
    kept: int
    chords: int


def _hemisphere(k: int) -> np.ndarray:
    """``k`` unit directions spread evenly over the hemisphere z > 0 (Fibonacci), shape (k, 3)."""
    i = np.arange(k) + 0.5
    z = i / k
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def _inside_points(q: MeshQueries, lo: np.ndarray, hi: np.ndarray, count: int) -> np.ndarray:
    """About ``count`` or more points spread evenly through the inside of the closed mesh: the
    centres of the inside voxels of the coarsest grid (from :data:`_GRID_CELLS` cells over the box,
    halving the voxel up to :data:`_MAX_CELLS`) that has at least twice ``count`` of them, strided
    down to ``count``. Shape (k, 3); fewer (or none) for a mesh whose inside no grid resolves."""
    ext = np.asarray(hi, dtype=np.float64) - np.asarray(lo, dtype=np.float64)
    ext = np.maximum(ext, 1e-3 * max(float(ext.max()), 1e-300))  # a flat box still has cells
    h = float(np.cbrt(np.prod(ext) / _GRID_CELLS))
    h_min = float(np.cbrt(np.prod(ext) / _MAX_CELLS))
    pts = np.zeros((0, 3))
    while True:
        origin, shape, flat = dmap.inside_voxels(q.closed, lo, hi, h, q.device)
        if len(flat) >= len(pts):
            pts = origin + h * np.stack(np.unravel_index(flat, shape), axis=1)
        if len(flat) >= 2 * count or h <= h_min:
            break
        h = max(0.5 * h, h_min)
    if len(pts) > count:
        pts = pts[np.linspace(0, len(pts) - 1, count).round().astype(np.int64)]
    return pts


def inside_widths(q: MeshQueries, points: np.ndarray, diag: float, directions: int = WIDTH_DIRECTIONS) -> np.ndarray:
    """Width at each point of the inside: half the lower quartile of the chords through it along
    ``directions`` directions spread over a hemisphere (distance to the closed mesh's first hit one
    way plus the other; a ray that meets nothing counts ``diag``). Shape (n,) [mesh units]."""
    u = _hemisphere(directions)
    dirs = np.concatenate([u, -u])
    origins = np.repeat(np.asarray(points, dtype=np.float64)[:, None, :], len(dirs), axis=1)
    t = q.rays(q.closed, origins, np.broadcast_to(dirs, origins.shape), 2.0 * diag)
    t = np.where(t > 0.0, np.minimum(t, diag), diag)
    chords = t[:, :directions] + t[:, directions:]
    return 0.5 * np.percentile(chords, 25, axis=1)


def tube_scale(q: MeshQueries, diameters: np.ndarray, lo: np.ndarray, hi: np.ndarray, diag: float) -> TubeScale:
    """The tube's median and narrow radius from the chords ``diameters`` across it from its wall
    (:meth:`~warp_tube.extract.queries.MeshQueries.inner_diameters`, at least one), checked
    against the widths from inside (see the module).

    Args:
        q: the tube's meshes (the closed one: inside points and widths).
        diameters: chords from the wall [mesh units], shape (k,).
        lo, hi: bounding box corners [mesh units], shape (3,); diag: its diagonal.
    """
    d = np.asarray(diameters, dtype=np.float64)
    median, narrow = 0.5 * float(np.median(d)), 0.5 * float(np.percentile(d, 10))
    pts = _inside_points(q, lo, hi, WIDTH_POINTS)
    width = float(np.median(inside_widths(q, pts, diag))) if len(pts) else 0.0
    if not narrow < ROUGH * width:
        return TubeScale(median, narrow, width, False, len(d), len(d))
    kept = d[d >= width]
    if len(kept) >= max(8, MIN_KEPT * len(d)):
        return TubeScale(0.5 * float(np.median(kept)), 0.5 * float(np.percentile(kept, 10)), width, True, len(kept),
                         len(d))  # fmt: skip
    return TubeScale(width, 0.5 * width, width, True, 0, len(d))


def rough_scale(size: TubeScale, closed_v: np.ndarray, closed_f: np.ndarray, lo: np.ndarray, hi: np.ndarray, diag: float,
                device) -> TubeScale:  # fmt: skip
    """The radii of a rough wall (``size``: :func:`tube_scale` of it) measured again on a copy
    smoothed by :data:`SMOOTHING_PASSES` passes of Taubin's filter (see the module): the closed mesh
    ``closed_v`` (V, 3) [mesh units], ``closed_f`` (F, 3). Each radius is the larger of the two
    measures: both err short, never long (the noise's spikes cut the wall's chords; the filter
    rounds a sealed end's sharp rim, whose chords then shorten the smoothed narrow radius: a sealed
    tube of radius 5 at noise of 0.1 radii, narrow 2.7 on the wall and 1.2 smoothed). ``rough``
    stays True."""
    import trimesh

    smooth = trimesh.Trimesh(np.array(closed_v, dtype=np.float64), np.asarray(closed_f), process=False)
    trimesh.smoothing.filter_taubin(smooth, lamb=0.5, nu=0.53, iterations=SMOOTHING_PASSES)
    q = MeshQueries(smooth.vertices, smooth.faces, smooth.vertices, smooth.faces, device)
    diam = q.inner_diameters(smooth, 2.0 * diag)
    if len(diam) < 3:  # (nothing enclosed once smoothed: keep what the wall itself gave)
        return size
    s = tube_scale(q, diam, lo, hi, diag)
    return TubeScale(max(s.median, size.median), max(s.narrow, size.narrow), size.width, True, size.kept, size.chords)
