"""Small NumPy helpers for polylines: arclength, resampling (linear or along a cubic spline),
smoothing, tangents, point projection.

Lengths are in whatever unit the points use.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

__all__ = [
    "arclength", "point_at", "resample", "resample_spline", "smooth", "tangents", "project_points", "nearest_on_polyline",
]


def arclength(points: np.ndarray) -> np.ndarray:
    """Cumulative length at each point, shape (n,), starting at 0."""
    p = np.asarray(points, dtype=np.float64)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def point_at(line: np.ndarray, s: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Point and unit tangent of a polyline at arclength ``sigma`` from its start (clamped); ``s``:
    its arclengths (:func:`arclength`)."""
    sigma = float(np.clip(sigma, 0.0, s[-1]))
    k = int(np.clip(np.searchsorted(s, sigma, side="right") - 1, 0, len(line) - 2))
    w = (sigma - s[k]) / max(s[k + 1] - s[k], 1e-300)
    t = line[k + 1] - line[k]
    return line[k] + w * t, t / max(np.linalg.norm(t), 1e-300)


def resample(points: np.ndarray, count: int) -> np.ndarray:
    """``count`` points equally spaced in arclength along the polyline, ends kept, shape (count, 3)."""
    p = np.asarray(points, dtype=np.float64)
    s = arclength(p)
    keep = np.concatenate([[True], np.diff(s) > 0.0])
    p, s = p[keep], s[keep]
    if len(p) < 2:
        return np.repeat(p[:1], count, axis=0)
    u = np.linspace(0.0, s[-1], count)
    return np.stack([np.interp(u, s, p[:, k]) for k in range(3)], axis=1)


def resample_spline(points: np.ndarray, count: int, oversample: int = 16) -> np.ndarray:
    """``count`` points equally spaced in arclength along the cubic spline through ``points``.

    The spline (not-a-knot, parametrised by chord length) passes through every point, so
    resampling a line of points that lie on a smooth curve stays on it to fourth order in the
    spacing, where linear interpolation cuts bends by ``h^2 kappa / 8``. Ends are kept.

    Args:
        points: shape (n, 3).
        count: points wanted.
        oversample: spline evaluations per input segment to measure its arclength.

    Returns:
        Shape (count, 3).
    """
    from scipy.interpolate import CubicSpline

    p = np.asarray(points, dtype=np.float64)
    u = arclength(p)
    keep = np.concatenate([[True], np.diff(u) > 0.0])
    p, u = p[keep], u[keep]
    if len(p) < 4:
        return resample(p, count)
    spline = CubicSpline(u, p, axis=0)
    fine_u = np.linspace(0.0, u[-1], oversample * (len(p) - 1) + 1)
    fine_s = arclength(spline(fine_u))
    target = np.linspace(0.0, fine_s[-1], count)
    out = spline(np.interp(target, fine_s, fine_u))
    out[0], out[-1] = p[0], p[-1]
    return out


def tangents(points: np.ndarray) -> np.ndarray:
    """Unit tangents of a polyline by central differences (one-sided at the ends), shape (n, 3)."""
    p = np.asarray(points, dtype=np.float64)
    t = np.gradient(p, axis=0) if len(p) > 2 else np.repeat(p[1:2] - p[:1], len(p), axis=0)
    n = np.linalg.norm(t, axis=1, keepdims=True)
    return t / np.where(n > 0.0, n, 1.0)


def smooth(points: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian smoothing along the index with the two end points held.

    The polyline is padded by odd reflection about each end point (``2 p0 - p_k``), so straight
    runs stay straight and the ends do not shrink inwards.

    Args:
        points: shape (n, 3), roughly equally spaced.
        sigma: standard deviation in samples.
    """
    p = np.asarray(points, dtype=np.float64)
    if sigma <= 0.0 or len(p) < 3:
        return p.copy()
    pad = min(len(p) - 1, int(np.ceil(4.0 * sigma)))
    head = 2.0 * p[0] - p[pad:0:-1]
    tail = 2.0 * p[-1] - p[-2 : -pad - 2 : -1]
    ext = np.concatenate([head, p, tail])
    out = gaussian_filter1d(ext, sigma, axis=0, mode="nearest")[pad : pad + len(p)]
    out[0], out[-1] = p[0], p[-1]
    return out


def project_points(points: np.ndarray, line: np.ndarray, chunk: int = 4096):
    """Closest point of a polyline to each query point.

    Args:
        points: queries, shape (V, 3).
        line: polyline, shape (n, 3), n >= 2.

    Returns:
        ``(distance (V,), arclength (V,))``: distance to the polyline and arclength of the closest
        point along it.
    """
    q = np.asarray(points, dtype=np.float64)
    a = np.asarray(line, dtype=np.float64)[:-1]
    e = np.diff(np.asarray(line, dtype=np.float64), axis=0)
    ee = np.maximum((e * e).sum(axis=1), 1e-300)
    s0 = arclength(line)[:-1]
    seg_len = np.sqrt(ee)
    dist = np.empty(len(q))
    arc = np.empty(len(q))
    for i in range(0, len(q), chunk):
        d = q[i : i + chunk, None, :] - a[None, :, :]
        t = np.clip((d * e[None]).sum(axis=2) / ee[None], 0.0, 1.0)
        r = d - t[..., None] * e[None]
        d2 = (r * r).sum(axis=2)
        j = np.argmin(d2, axis=1)
        rows = np.arange(len(j))
        dist[i : i + chunk] = np.sqrt(d2[rows, j])
        arc[i : i + chunk] = s0[j] + t[rows, j] * seg_len[j]
    return dist, arc


MAX_SAMPLES = 100_000
"""The most samples :func:`nearest_on_polyline` resamples a polyline into (a few MB)."""


def nearest_on_polyline(points: np.ndarray, line: np.ndarray, step: float):
    """Approximate :func:`project_points` through a k-d tree of the polyline resampled at ``step``.

    Distances are exact to within ``step**2 / (8 * distance)`` and arclengths to ``step / 2``,
    ``step`` at least the polyline's length / :data:`MAX_SAMPLES`; it runs in ``O(V log n)`` instead of ``O(V n)``.

    Returns:
        ``(distance (V,), arclength (V,))``.
    """
    from scipy.spatial import cKDTree

    line = np.asarray(line, dtype=np.float64)
    total = float(arclength(line)[-1])
    # A step from a near-zero radius (a mesh fallen into slivers) would ask for billions of
    # samples; the cap keeps arclengths within 1/(2 MAX_SAMPLES) of the length.
    step = max(step, total / MAX_SAMPLES) if np.isfinite(step) else total / MAX_SAMPLES
    count = max(2, int(np.ceil(total / max(step, 1e-300))) + 1)
    fine = resample(line, count)
    dist, idx = cKDTree(fine).query(np.asarray(points, dtype=np.float64))
    return dist, idx * (total / (count - 1))
