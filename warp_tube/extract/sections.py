"""Cross-sections of a tube by rays: which hits belong to the tube, the section's centre, spokes.

A cross-section at a point of the centerline is measured by rays from the point in the plane normal
to the line there. A hit *belongs to the tube's cross-section* when the ray stays inside the tube up
to it (the closed mesh, open loops capped, has no nearer hit: the ray did not leave through an open
end or a wall opening), it lies within 6 times the point's distance from the wall (a ray that leaves
through an open loop may hit far parts) and within :data:`OUTLIER_RATIO` times the median of its
ring's valid hits (a ray that runs into a side branch's mouth or out of a bulge). A flat section's
long sides fail the last two (an ellipse of aspect 4 reaches 2.9 times its median hit): on a tube
whose sections are flat (``q.flat``, :mod:`warp_tube.extract.flat`), a hit is kept all the same
where the ray opposite reaches about as far (:data:`ACROSS`, within
:data:`FLAT_REACH` times the distance from the wall), as a branch's mouth or a bulge, on one side of
the axis, does not (:mod:`warp_tube.extract.flat`).

Centres: the centroid of the section's polygon (the ray hits, with the rays that do not belong to the
tube filled in by interpolating the lengths of their valid neighbours around the ring, so that a
branch's mouth is closed over as the kept tube's wall would run), moved to iteratively in the plane
normal to the line. On a tube swept by circles normal to a curve this converges to the curve.

Spokes: the lengths along the simulator's spoke directions, least-squares fitted to the section
measured by :data:`FIT_RAYS` rays per gap between spokes (:func:`fit_polygon`), so that the ring's
polygon runs through the wall between its spokes rather than inside it.

Lengths are in the mesh's units.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..model.frames import hub_tangents, initial_normal, rotation_minimizing_frames, spoke_directions
from ..scene.shape_notes import turning_angles
from .polyline import resample_spline, smooth, tangents
from .queries import MeshQueries

__all__ = ["OUTLIER_RATIO", "BRIDGED_LENGTH", "BRIDGED_WIDTH", "bridged_branch", "near_junction", "wall_hits", "ring_hits",
           "open_rays", "fill_around", "section_offsets", "recentre", "measure_spokes", "plane_basis", "recentre_hubs",
           "fit_polygon", "FIT_RAYS"]

OUTLIER_RATIO = 2.5
"""A hit longer than this times the median of its ring's valid hits does not belong to the section,
unless the tube's sections are flat and the ray opposite reaches as far (their long sides, :data:`ACROSS`)."""
ACROSS = 0.5
"""A long hit belongs to a flat section when the opposite ray's hit is at least this fraction of it: on
an ellipse, a point off its centre by up to a third of the long semi-axis along it."""
FLAT_REACH = 10.0
"""Longest hit of a flat section's long sides, in the point's distances from the wall (an ellipse of
aspect 6 has 6 at its centre, more off it)."""
RAYS = 32
"""Rays per cross-section when centring."""
FIT_RAYS = 4
"""Rays per gap between two spokes that measure a ring's section for :func:`fit_polygon`."""
FIT_MAX_RAYS = 128
"""Most rays per ring for the fit (more spokes: fewer rays per gap)."""
FIT_PULL = 0.05
"""Weight of a spoke's own ray-hit length in :func:`fit_polygon`, against 1 per ray of the section."""
MAX_TURN = np.radians(60.0)
"""Largest turn at a point of the dense axis (half a tube radius between points) that centring may
make: sharper is tighter than the tube's own radius, a fold of the line, not of the tube."""


def wall_hits(q: MeshQueries, points: np.ndarray, dirs: np.ndarray, diag: float):
    """Wall hit distances of rays from each point, and which of them stay inside the tube (the
    closed mesh, its open loops capped, has no nearer hit: the ray did not leave through an open end
    or a wall opening).

    Args:
        points: ray origins, shape (n, 3); dirs: unit directions, shape (n, R, 3).
        diag: the mesh's bounding-box diagonal (longest ray).

    Returns:
        ``(t (n, R), wall (n, R) bool)``: hit distances (-1: none) and which are inside hits.
    """
    origins = np.repeat(np.asarray(points, dtype=np.float64)[:, None, :], dirs.shape[1], axis=1)
    t = q.rays(q.wall, origins, dirs, diag)
    tc = q.rays(q.closed, origins, dirs, diag)
    return t, (t > 0.0) & (tc >= t - 1e-5 * diag)


def ring_hits(q: MeshQueries, points: np.ndarray, dirs: np.ndarray, diag: float):
    """Wall hit distances of rays from each point and which of them belong to the tube's section.

    Args:
        points: ray origins, shape (n, 3); dirs: unit directions, shape (n, R, 3).
        diag: the mesh's bounding-box diagonal (longest ray).

    Returns:
        ``(t (n, R), valid (n, R) bool, dfb (n,))``: hit distances (-1: none), validity, and each
        point's distance from the wall.
    """
    t, wall = wall_hits(q, points, dirs, diag)
    dfb = q.distance(points, diag)
    valid = wall & (t < 6.0 * np.maximum(dfb, 1e-12)[:, None])
    with warnings.catch_warnings():  # rings with no valid hit: an all-NaN row has no median
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(np.where(valid, t, np.nan), axis=1) if valid.size else np.zeros(len(t))
    valid &= t <= OUTLIER_RATIO * np.where(np.isnan(med), np.inf, med)[:, None]
    if getattr(q, "flat", False):
        valid |= wall & _across(t, wall, dfb)
    valid[near_junction(q, points)] = False  # (bridged from the sections on either side)
    return t, valid, dfb


BRIDGED_LENGTH = 3.0
"""A side branch at least this many of the tube's radii long (from its junction) and at most
:data:`BRIDGED_WIDTH` of the tube's radius has the tube's sections within one radius of its junction
bridged over its mouth (:func:`near_junction`). Shorter ones (a stub, a pouch of the wall: 1.3-1.8
radii on the colon and the coronary arteries of ``../shared/data/meshes``) and wider ones (loops of
a coiled tube touching it, as in the jejunum there) are measured as they are: bridging those made
their fit worse (largest misses 20 -> 40 %, 27 -> 71 %)."""
BRIDGED_WIDTH = 0.8
"""See :data:`BRIDGED_LENGTH` (a vessel's side branch is narrower than its trunk)."""


def bridged_branch(length: float, width: float, radius: float) -> bool:
    """Whether a side branch ``length`` long and ``width`` in radius, leaving a tube of ``radius``
    (all in one unit), has the tube's sections bridged over its mouth (:data:`BRIDGED_LENGTH`)."""
    return bool(length >= BRIDGED_LENGTH * radius and width <= BRIDGED_WIDTH * radius)


def near_junction(q: MeshQueries, points: np.ndarray) -> np.ndarray:
    """Which ``points`` lie within reach of a side branch's junction (``MeshQueries.junctions``),
    bool (n,). Their sections are not measured: rays there run into the branch's mouth, by less
    than :data:`OUTLIER_RATIO` where the branch is narrow or leaves at a slant, and pulled a hub
    towards it (0.28 radii, its ring 13 % wider, for a branch of 0.6 the tube's radius at 45
    degrees); the tube's wall is taken to run across the mouth as it runs on either side
    (:func:`recentre_hubs`, :func:`measure_spokes`)."""
    out = np.zeros(len(points), dtype=bool)
    near = getattr(q, "junctions", None)
    if near is not None and len(near[0]) and len(points):
        centres, reach = near
        d = np.linalg.norm(np.asarray(points, dtype=np.float64)[:, None, :] - centres[None], axis=2)
        out = (d <= reach[None]).any(axis=1)
    return out


def _across(t: np.ndarray, wall: np.ndarray, dfb: np.ndarray) -> np.ndarray:
    """Which hits lie on a flat section's long sides: the ray opposite (the nearer of the two nearest
    it, for an odd count) meets the wall too, at least :data:`ACROSS` times as far, and both lie within
    :data:`FLAT_REACH` times the point's distance from the wall. A side branch's mouth or a bulge opens
    on one side of the axis, where the opposite ray meets the near wall; a flattened tube is as wide on
    both sides. Shape of ``t`` (n, R), rays evenly spaced around each ring."""
    rays = t.shape[1]
    if rays < 2:
        return np.zeros_like(wall)
    ok = wall & (t < FLAT_REACH * np.maximum(dfb, 1e-12)[:, None])
    reach = np.where(ok, t, 0.0)
    opposite = np.roll(reach, -(rays // 2), axis=1)
    if rays % 2:
        opposite = np.minimum(opposite, np.roll(reach, -(rays // 2) - 1, axis=1))
    return ok & (opposite >= ACROSS * t)


def open_rays(q: MeshQueries, points: np.ndarray, diag: float, rays: int = RAYS) -> np.ndarray:
    """Which of ``rays`` rays in each hub's ring plane (normal to its bisector tangent) leave the tube
    without meeting its wall: no hit on the mesh as given, or the closed mesh (every loop capped)
    hit first, so the ray passes through an opening or hole of the mesh. Bool, shape (n, rays)."""
    r, s = plane_basis(hub_tangents(points))
    dirs = spoke_directions(r, s, rays)
    origins = np.repeat(points[:, None, :], rays, axis=1)
    t = q.rays(q.raw, origins, dirs, diag)
    tc = q.rays(q.closed, origins, dirs, diag)
    return (t <= 0.0) | (tc < t - 1e-5 * diag)


def fill_around(t: np.ndarray, valid: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Lengths with the invalid rays of each ring interpolated from its valid ones, shape (n, R).

    Interpolation is linear in the ray angle, periodic around the ring; rings with no valid ray
    take ``fallback`` (n,) all round.
    """
    n, m = t.shape
    out = np.repeat(np.asarray(fallback, dtype=np.float64)[:, None], m, axis=1)
    idx = np.arange(m)
    for i in np.flatnonzero(valid.any(axis=1)):
        ok = idx[valid[i]]
        out[i] = np.interp(idx, np.concatenate([ok - m, ok, ok + m]), np.tile(t[i, ok], 3))
    return out


def plane_basis(tangent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane normal to each unit tangent, shapes (n, 3) each."""
    t = np.asarray(tangent, dtype=np.float64)
    r = np.stack([initial_normal(ti) for ti in t])
    return r, np.cross(t, r)


def section_offsets(q: MeshQueries, points: np.ndarray, tangent: np.ndarray, diag: float, rays: int = RAYS):
    """Offset from each point to the centroid of its cross-section normal to ``tangent``.

    Returns:
        ``(offset (n, 3), ok (n,) bool, lengths (n, rays), valid (n, rays))``: ``ok`` where at least
        60 % of the rays belong to the section and its polygon has a positive area.
    """
    r, s = plane_basis(tangent)
    dirs = spoke_directions(r, s, rays)
    t, valid, dfb = ring_hits(q, points, dirs, diag)
    length = fill_around(t, valid, dfb)
    phi = 2.0 * np.pi * np.arange(rays) / rays
    x, y = length * np.cos(phi), length * np.sin(phi)
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * y1 - x1 * y
    area = 0.5 * cross.sum(axis=1)
    ok = (valid.mean(axis=1) >= 0.6) & (area > 0.0)
    safe = np.where(ok, area, 1.0)
    cx = ((x + x1) * cross).sum(axis=1) / (6.0 * safe)
    cy = ((y + y1) * cross).sum(axis=1) / (6.0 * safe)
    offset = np.where(ok[:, None], cx[:, None] * r + cy[:, None] * s, 0.0)
    return offset, ok, length, valid


def _safe_moves(q: MeshQueries, p: np.ndarray, offset: np.ndarray, movable: np.ndarray, diag: float) -> np.ndarray:
    """The offsets that centre without leaving the axis: each capped at a third of the point's
    distance from the wall, and dropped where the moved point would lie nearer to the wall than 80 %
    of where it was (a section cut obliquely through a bulge or a bend's far side has its centroid
    off the axis), where the line would turn back on itself, or where it would turn by more than
    :data:`MAX_TURN` at a point that did not. Shape (n, 3)."""
    dfb = q.distance(p, diag)
    size = np.linalg.norm(offset, axis=1)
    cap = np.minimum(1.0, dfb / (3.0 * np.maximum(size, 1e-300)))
    offset = np.where(movable[:, None], offset * cap[:, None], 0.0)
    moved = p + offset
    keep = q.distance(moved, diag) >= 0.8 * dfb
    e0 = np.diff(p, axis=0)
    e1 = np.diff(np.where(keep[:, None], moved, p), axis=0)
    back = np.einsum("ij,ij->i", e0, e1) <= 0.0
    keep[1:] &= ~back
    keep[:-1] &= ~back
    before = turning_angles(p)
    for _ in range(3):  # moves that kink the line (a turn over MAX_TURN that was not there) stay
        sharp = np.flatnonzero((turning_angles(np.where(keep[:, None], moved, p)) > MAX_TURN) & (before <= MAX_TURN)) + 1
        if len(sharp) == 0:
            break
        keep[np.clip(np.concatenate([sharp - 1, sharp, sharp + 1]), 0, len(p) - 1)] = False
    return np.where(keep[:, None], offset, 0.0)


def recentre(q: MeshQueries, line: np.ndarray, diag: float, *, iterations: int = 4, tangent_sigma: float = 1.0,
             move: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Move points of a dense line onto the centroids of their cross-sections.

    Each iteration measures every point's section in the plane normal to the tangent of the line
    smoothed by ``tangent_sigma`` samples (so one noisy point does not tilt its plane), moves the
    points towards the centroids (:func:`_safe_moves`) and respaces the line along a cubic spline
    (which does not cut bends).

    Args:
        line: shape (n, 3), roughly equally spaced.
        move: which points may move, bool (n,) (default: all but the two ends).

    Returns:
        The re-centred line, shape (n, 3).
    """
    p = np.asarray(line, dtype=np.float64).copy()
    if move is None:
        move = np.ones(len(p), dtype=bool)
        move[[0, -1]] = False
    for _ in range(iterations):
        t = tangents(smooth(p, tangent_sigma))
        offset, ok, _, _ = section_offsets(q, p, t, diag)
        p = p + _safe_moves(q, p, offset, move & ok, diag)
        p = resample_spline(p, len(p))
    return p


def measure_spokes(q: MeshQueries, points: np.ndarray, reference_normal: np.ndarray, spokes: int, diag: float,
                   *, fit: int = FIT_RAYS):  # fmt: skip
    """Spoke lengths by ray hits along the package's spoke directions at each hub.

    Spoke ``j`` of hub ``i`` points along ``spoke_directions(*rotation_minimizing_frames(points, None,
    reference_normal)[1:], spokes)[i, j]`` (the simulator's ring). Rays whose hit does not belong to
    the section (see the module) take the length of the same spoke interpolated along the tube from
    the hubs where it does; a spoke valid at no hub takes its ring's mean. With ``fit`` > 1, ``fit``
    rays per gap between spokes (at most :data:`FIT_MAX_RAYS` per ring) measure the section between
    the spokes too, and the lengths are fitted to them (:func:`fit_polygon`).

    Returns:
        ``(lengths (hubs, spokes), valid (hubs, spokes) bool)``: lengths [mesh units]; ``valid``:
        the spoke's own ray hit the section.
    """
    _, r, s = rotation_minimizing_frames(points, None, reference_normal)
    m = max(1, min(int(fit), FIT_MAX_RAYS // spokes))
    t_all, valid_all, dfb = ring_hits(q, points, spoke_directions(r, s, spokes * m), diag)
    t, valid = t_all[:, ::m], valid_all[:, ::m]
    t = np.where(valid, t, np.nan)
    idx = np.arange(len(points))
    for j in range(spokes):
        ok = valid[:, j]
        if ok.any() and not ok.all():
            t[:, j] = np.interp(idx, idx[ok], t[ok, j])
    if np.isnan(t).any():  # a spoke valid at no hub: its ring's mean, or the distance from the wall
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            fill = np.nanmean(t, axis=1)
        fill = np.where(np.isnan(fill), dfb, fill)
        t = np.where(np.isnan(t), fill[:, None], t)
    t = np.maximum(t, 1e-6 * diag)
    if m > 1:
        t = np.maximum(fit_polygon(t_all, valid_all, t, m), 1e-6 * diag)
    return t, valid


def fit_polygon(t: np.ndarray, valid: np.ndarray, lengths: np.ndarray, m: int) -> np.ndarray:
    """Spoke lengths whose ring polygon runs through the section measured by ``m`` rays per gap.

    A ring's polygon joins its spoke ends by straight edges. Spoke ends on the wall (the rays'
    hits) give a polygon inscribed in the section: where the wall bulges between two spokes, the
    mesh lies outside the edge by up to the bulge. Here the lengths are fitted instead, least
    squares over all the section's rays, to the radial distance between the polygon and the wall
    along each ray. In polar coordinates an edge from spoke ``j`` (length ``l_j``) to spoke ``j + 1``
    is ``1 / r(phi_j + a D) = (sin((1 - a) D) / l_j + sin(a D) / l_{j+1}) / sin D`` (``D`` the angle
    between spokes): linear in ``w = 1 / l``, so with the residual weighted by ``r^2`` (a radial
    distance) the fit is a linear, cyclic tridiagonal system per ring. A small pull towards the
    spoke's own measure (:data:`FIT_PULL` per ray) keeps it determined where rays miss the section
    (branch mouths, open ends); a fitted length stays within the range of the rays from spoke ``j - 1`` to
    spoke ``j + 1`` and of its own measure, widened by the factor ``1 / cos(D / 2)`` by which the
    corners of a polygon fitted to a circle lie outside it.

    Args:
        t: hit distances of ``spokes * m`` rays per ring [mesh units], shape (n, S m); ray ``k`` at
            angle ``2 pi k / (S m)``, so ray ``j m`` is spoke ``j``.
        valid: which rays belong to the section, bool (n, S m).
        lengths: the spokes as measured [mesh units], shape (n, S).
        m: rays per gap between spokes.

    Returns:
        Fitted lengths [mesh units], shape (n, S).
    """
    n, spokes = lengths.shape
    k = np.arange(spokes * m)
    j0, j1 = k // m, (k // m + 1) % spokes
    gap = 2.0 * np.pi / spokes
    frac = (k % m) / m
    a = np.sin((1.0 - frac) * gap) / np.sin(gap)
    b = np.sin(frac * gap) / np.sin(gap)
    weight = np.where(valid & (t > 0.0), np.square(np.square(np.where(valid, t, 0.0))), 0.0)  # (r^2)^2
    inv = np.where(valid & (t > 0.0), 1.0 / np.where(t > 0.0, t, 1.0), 0.0)
    mat = np.zeros((n, spokes, spokes))
    rhs = np.zeros((n, spokes))
    for (ja, ca), (jb, cb) in (((j0, a), (j0, a)), ((j0, a), (j1, b)), ((j1, b), (j0, a)), ((j1, b), (j1, b))):
        np.add.at(mat, (slice(None), ja, jb), weight * (ca * cb))
    np.add.at(rhs, (slice(None), j0), weight * inv * a)
    np.add.at(rhs, (slice(None), j1), weight * inv * b)
    pull = FIT_PULL * np.square(np.square(lengths))
    diag = np.arange(spokes)
    mat[:, diag, diag] += pull
    rhs += pull / lengths
    w = np.linalg.solve(mat, rhs[..., None])[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(w > 0.0, 1.0 / w, lengths)
    out = np.where(np.isfinite(out), out, lengths)
    # Within the rays of the two gaps next to the spoke (its own measure included).
    hit = np.where(valid & (t > 0.0), t, np.nan).reshape(n, spokes, m)
    near = np.concatenate([np.roll(hit, 1, axis=1), hit, np.roll(hit, -1, axis=1)[..., :1]], axis=2)  # spokes j +- 1
    with warnings.catch_warnings():  # a spoke with no ray of the section near it: its own measure
        warnings.simplefilter("ignore", RuntimeWarning)
        lo = np.fmin(np.nanmin(near, axis=2), lengths)
        hi = np.fmax(np.nanmax(near, axis=2), lengths)
    slack = np.cos(0.5 * gap)  # a polygon fitted to a circle has its corners outside it by 1 / cos - 1
    return np.clip(out, slack * lo, hi / slack)


def recentre_hubs(q: MeshQueries, points: np.ndarray, diag: float, scale: float, *, iterations: int = 2,
                  rays: int = RAYS) -> np.ndarray:  # fmt: skip
    """Move interior hubs onto the centroids of their own ring's cross-section.

    The ring plane is the simulator's: normal to the hub's bisector tangent
    (:func:`warp_tube.model.frames.hub_tangents`). Moving a hub tilts its neighbours' planes a
    little, so this runs ``iterations`` times; the end hubs stay. The moves (not the positions) are
    smoothed along the tube over ``scale`` (Gaussian sigma, a length): a centroid is only known to
    the resolution of the mesh's facets, and hubs much closer together than that would turn this
    noise into curvature.

    Args:
        points: hubs on the centred axis, about equally spaced, shape (n, 3).
        scale: smoothing length of the moves [mesh units] (about half the tube's radius).

    Returns:
        The hubs, shape (n, 3).
    """
    p = np.asarray(points, dtype=np.float64).copy()
    if len(p) < 3:
        return p
    move = np.ones(len(p), dtype=bool)
    move[[0, -1]] = False
    spacing = float(np.mean(np.linalg.norm(np.diff(p, axis=0), axis=1)))
    sigma = min(scale / max(spacing, 1e-300), float(len(p)))  # (wider than the tube: about a plain mean; its size kept finite)
    for _ in range(iterations):
        offset, ok, _, _ = section_offsets(q, p, hub_tangents(p), diag, rays)
        offset[~(move & ok)] = 0.0
        if sigma > 0.5:
            offset = gaussian_filter1d(offset, sigma, axis=0, mode="nearest")
            offset[~move] = 0.0
        p += offset
    return _bridged(p, near_junction(q, p))


def _bridged(p: np.ndarray, skip: np.ndarray) -> np.ndarray:
    """Hubs ``p`` with those of ``skip`` (near a side branch's junction) moved onto the cubic spline
    through the others (by hub index), where at least two hubs on each side of them remain."""
    if not skip.any():
        return p
    from scipy.interpolate import CubicSpline

    keep = np.flatnonzero(~skip)
    inner = np.flatnonzero(skip)
    inner = inner[(inner > keep[1]) & (inner < keep[-2])] if len(keep) >= 4 else inner[:0]
    if len(inner) == 0:
        return p
    out = p.copy()
    out[inner] = CubicSpline(keep, p[keep], axis=0)(inner)
    return out
