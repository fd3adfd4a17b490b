"""Measures of a tube's closed end that see past a rough wall (a scan's or a segmentation's noise).

On a rough wall the nearest point of the wall is the tip of its deepest inward spike, and single ray
hits scatter by the noise: the end's radius, its direction and whether it is a flat cut are taken
from medians of many rays instead (used by :func:`warp_tube.extract.ends.fit_closed_end`).

Lengths are in the mesh's units.
"""

from __future__ import annotations

import numpy as np

from ..model.frames import spoke_directions
from .polyline import arclength, point_at
from .queries import MeshQueries
from .sections import plane_basis

__all__ = ["ROUGH", "wall_noise", "straight_start", "rough_cut_plane"]

ROUGH = 0.015
"""A wall is rough where its ray noise (:func:`wall_noise`) exceeds this times its radius. A clean
mesh's is 0.006 or less; vertices moved by noise of a tenth of the radius (about half an edge) gave
0.017-0.023, and at 0.03 such rounded tips were taken for clean ones whose cap missed them (typed
"cut", left uncapped, in 2 of 5 meshes); the shared meshes and the synthetic set extract the same
at either bound."""
_ROUGH_FLAT = 0.93  # a rough closed end is a flat cut where the tube's width before it is this x its radius
_FLAT_BACK = (0.4, 0.5, 0.6)  # ... on rings this x the wall's radius before the surface ahead
_NOISE_RAYS = 64  # rays per ring for :func:`wall_noise` and :func:`rough_cut_plane`


def _ray_ring(q: MeshQueries, point: np.ndarray, tangent: np.ndarray, diag: float) -> np.ndarray | None:
    """Distances to the closed surface along :data:`_NOISE_RAYS` rays in the plane normal to unit
    ``tangent`` through ``point``, in order round it; None where a ray meets nothing."""
    r, s = plane_basis(tangent[None])
    dirs = spoke_directions(r, s, _NOISE_RAYS)[0]
    t = q.rays(q.closed, np.repeat(point[None], len(dirs), axis=0), dirs, diag)
    return None if (t <= 0.0).any() else t


def wall_noise(q: MeshQueries, line: np.ndarray, diag: float) -> tuple[float, float]:
    """The wall's noise near the closed end where ``line`` starts and its radius there [mesh units].

    Rings of rays normal to the line: one round ``line[0]`` (its median ray sets the scale ``r0``)
    and rings 1 to 3 ``r0`` further on. The noise is a robust deviation (1.4826 x the median
    absolute value) of the second differences of ray lengths round the further rings, over sqrt(6)
    (what they make of independent noise), median over the rings. A smooth wall changes little from
    ray to ray (a 32-gon: 0.006 of its radius); vertices moved by noise of 0.1 (0.2) of the radius
    give 0.06 to 0.11 (0.12 to 0.19). The radius is the median of all the rings' rays: at noise of
    0.2 radii one ring's median scatters by 4 to 5 % of the radius (a ring meets some 30
    independent vertices: 1.25 x 0.2 / sqrt(30)), that of six rings (0.4 radii apart or more, so
    sharing few vertices) by about 2 %. Returns ``(0, 0)`` where the first ring is not complete,
    and the first ring's median with no noise where no further one is.
    """
    s = arclength(line)
    t0 = _ray_ring(q, line[0], point_at(line, s, 0.0)[1], diag)
    if t0 is None:
        return 0.0, 0.0
    radius = float(np.median(t0))
    noise, rays = [], [t0]
    for x in np.linspace(1.0, 3.0, 5) * radius:
        if x > s[-1]:
            break
        t = _ray_ring(q, *point_at(line, s, x), diag)
        if t is not None:
            second = np.roll(t, 1) - 2.0 * t + np.roll(t, -1)
            noise.append(1.4826 * float(np.median(np.abs(second))) / np.sqrt(6.0))
            rays.append(t)
    if not noise:
        return 0.0, radius
    return float(np.median(noise)), float(np.median(np.concatenate(rays)))


def straight_start(line: np.ndarray, reach: float) -> np.ndarray:
    """``line`` with its points within ``reach`` of arclength from its start moved onto their
    least-squares straight line: on a rough wall the centred line wanders by the noise, and the
    tangent of its first points, which points the way to the tip, by tens of degrees."""
    s = arclength(line)
    near = s <= reach
    if near.sum() < 3:
        return line
    centre = line[near].mean(axis=0)
    axis = np.linalg.svd(line[near] - centre)[2][0]
    out = line.copy()
    out[near] = centre + np.outer((line[near] - centre) @ axis, axis)
    return out


def rough_cut_plane(q: MeshQueries, hub: np.ndarray, out: np.ndarray, r_wall: float, diag: float):
    """The flat-cut test of :mod:`warp_tube.extract.ends` for a rough wall, whose noise keeps ray
    hits off any plane by tenths of the radius: the closed surface ahead of ``hub`` (looking along
    unit ``out``; ``r_wall`` the wall's
    radius round it) is a flat cut where the tube keeps its width up to it: the mean of the median
    rays of rings (normal to ``out``, :data:`_NOISE_RAYS` rays) :data:`_FLAT_BACK` x ``r_wall``
    before the surface ahead (the median of 17 rays within 10 degrees of ``out``) is at least
    :data:`_ROUGH_FLAT` x ``r_wall`` (:func:`wall_noise`'s radius). A hemisphere narrows there to
    0.86 of its radius (noisy ones measured 0.82 to 0.88 at noise of 0.1 radii, 0.65 to 0.85 at
    0.2), a noisy flat cut's tube 0.98 to 1.02 (at 0.2: 0.90 to 1.02, so that about one flat end in
    twelve is taken for a rounded tip there). Medians see past the noise.

    Returns:
        ``(point, unit normal)`` of the cut (the surface ahead, ``out``), or None.
    """
    r, s = plane_basis(out[None])
    ring = spoke_directions(r, s, 8)[0]
    near = np.vstack([out[None]] + [np.cos(a) * out + np.sin(a) * ring for a in np.radians([5.0, 10.0])])
    t = q.rays(q.closed, np.repeat(hub[None], len(near), axis=0), near, diag)
    if (t <= 0.0).any():
        return None
    ahead = float(np.median(t))
    width = []
    for back in _FLAT_BACK:
        ring = _ray_ring(q, hub + max(ahead - back * r_wall, 0.0) * out, out, diag)
        if ring is None:
            return None
        width.append(float(np.median(ring)))
    if np.mean(width) < _ROUGH_FLAT * r_wall:
        return None
    return hub + ahead * out, out
