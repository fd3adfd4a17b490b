"""Flat cross-sections (a collapsed vessel, a flattened bowel): their aspect, and spokes along them.

A ring's section is measured by its spoke lengths (or by rays evenly spaced around it): the second
moments of area of the polygon through their ends give the section's *aspect*, the ratio of the
long to the short axis of the ellipse of the same moments (1 for a circle, 4 for an ellipse of
semi-axes 4 and 1), and the direction of its long axis.

The simulator's spokes are evenly spaced in angle from a reference normal. A flat section is
followed best by a ring whose spokes include its long and short axes: with 16 spokes, a 4:1
ellipse is matched within 4 % / 9 % of the mean radius (mean / largest) with a spoke along its long
axis, 6 % / 21 % with the spokes half a gap off it. Where the sections are flatter than
:data:`ALIGN_ASPECT`, the reference normal is turned about the first tangent so that the rings'
spokes meet the sections' long axes (:func:`long_axis_turn`); rounder tubes keep the package's
reference normal (:func:`~warp_tube.model.frames.initial_normal` of the first tangent).

The tube's sections count as flat where their median aspect along the voxel path, before it is
centred, is over :data:`ALIGN_ASPECT`: ray hits on their long sides then belong to them
(:func:`~warp_tube.extract.sections.ring_hits`); a flat spot of a round tube does not count.

Sections flatter than :data:`MAX_ASPECT` are not supported: their long sides reach farther than
:data:`~warp_tube.extract.sections.FLAT_REACH` times the distance from the axis to the wall, and
the extraction warns (:func:`flat_warning`).
"""

from __future__ import annotations

import numpy as np

from ..model.frames import hub_tangents, initial_normal, spoke_directions
from .queries import MeshQueries

__all__ = ["ALIGN_ASPECT", "MAX_ASPECT", "SPOKES", "FLAT_SPOKES", "FLAT_SPOKES_ASPECT", "default_spokes", "polygon_axes", "long_axis_turn", "turned_normal", "section_aspect",
           "flat_warning"]

ALIGN_ASPECT = 1.5
"""Sections of a median aspect above this have the spokes turned onto their long axes."""
MAX_ASPECT = 6.0
"""Flattest supported section (long over short axis of its ellipse of the same second moments)."""
SPOKES = 16
"""Spokes per hub where none are asked for."""
FLAT_SPOKES = 32
"""Spokes per hub where none are asked for and the sections are flatter than :data:`FLAT_SPOKES_ASPECT`:
16 spokes spaced evenly in angle cannot follow an ellipse of aspect 4 (the rest surface then misses
the mesh by 4-5% of the radius on average, 1.6% with 32)."""
FLAT_SPOKES_ASPECT = 3.5
"""Median section aspect above which :data:`FLAT_SPOKES` are taken where none are asked for."""


def default_spokes(aspect: float) -> int:
    """Spokes per hub for sections of median ``aspect`` where none are asked for."""
    return FLAT_SPOKES if aspect > FLAT_SPOKES_ASPECT else SPOKES


def polygon_axes(lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Aspect and long-axis angle of the polygons of evenly spaced rays from each point.

    Args:
        lengths: ray lengths, shape (n, R); ray ``j`` at angle ``2 pi j / R`` in the ring's plane.

    Returns:
        ``(aspect (n,), angle (n,))``: long over short axis of the polygon's ellipse of the same
        second moments of area about its centroid (inf for a degenerate polygon), and the long
        axis's angle from ray 0 [rad].
    """
    t = np.asarray(lengths, dtype=np.float64)
    phi = 2.0 * np.pi * np.arange(t.shape[1]) / t.shape[1]
    x, y = t * np.cos(phi), t * np.sin(phi)
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    c = x * y1 - x1 * y
    area = 0.5 * c.sum(axis=1)
    safe = np.where(np.abs(area) > 0.0, area, 1.0)
    cx = ((x + x1) * c).sum(axis=1) / (6.0 * safe)
    cy = ((y + y1) * c).sum(axis=1) / (6.0 * safe)
    ixx = (c * (x * x + x * x1 + x1 * x1)).sum(axis=1) / 12.0 - area * cx * cx
    iyy = (c * (y * y + y * y1 + y1 * y1)).sum(axis=1) / 12.0 - area * cy * cy
    ixy = (c * (x * y1 + 2.0 * x * y + 2.0 * x1 * y1 + x1 * y)).sum(axis=1) / 24.0 - area * cx * cy
    mean, half = 0.5 * (ixx + iyy), np.hypot(0.5 * (ixx - iyy), ixy)
    with np.errstate(divide="ignore", invalid="ignore"):
        aspect = np.sqrt((mean + half) / (mean - half))
    aspect = np.where((area > 0.0) & (mean - half > 0.0), aspect, np.inf)
    return aspect, 0.5 * np.arctan2(2.0 * ixy, ixx - iyy)


def long_axis_turn(lengths: np.ndarray) -> float:
    """Angle [rad] to turn the reference normal by (towards the frames' second normal) so that spoke
    0 lies along the sections' long axis, or 0 where the sections' median aspect is at most
    :data:`ALIGN_ASPECT`. ``lengths``: spoke lengths (hubs, S) measured from the reference normal
    turned by 0; the end hubs are left out where there are more than two. The long axes of all
    rings are averaged (their doubled angles, weighted by how flat each ring is); the turn is the
    nearest that puts a spoke on the average, so a round tube's spokes stay."""
    inner = lengths[1:-1] if len(lengths) > 2 else lengths
    aspect, angle = polygon_axes(inner)
    ok = np.isfinite(aspect)
    if not ok.any() or float(np.median(aspect[ok])) <= ALIGN_ASPECT:
        return 0.0
    w = aspect[ok] - 1.0
    mean = 0.5 * float(np.angle(np.sum(w * np.exp(2j * angle[ok]))))
    gap = 2.0 * np.pi / lengths.shape[1]
    return float(mean - gap * np.round(mean / gap))


def turned_normal(tangent: np.ndarray, turn: float) -> np.ndarray:
    """The package's reference normal for a first tangent, turned by ``turn`` [rad] about it."""
    t = np.asarray(tangent, dtype=np.float64)
    r = initial_normal(t)
    return np.cos(turn) * r + np.sin(turn) * np.cross(t, r)


def section_aspect(q: MeshQueries, points: np.ndarray, diag: float, rays: int = 64) -> float:
    """Median aspect of the hubs' sections (the end hubs left out where there are more than two),
    by ``rays`` rays in each ring plane (normal to the bisector tangent) to the wall, with no bound on
    their length (:func:`~warp_tube.extract.sections.ring_hits` bounds it): a ray that leaves the
    tube through an open loop takes its ring's mean."""
    from .sections import fill_around, plane_basis, wall_hits

    r, s = plane_basis(hub_tangents(points))
    t, valid = wall_hits(q, points, spoke_directions(r, s, rays), diag)
    fallback = np.array([t[i, v].mean() if v.any() else 0.0 for i, v in enumerate(valid)])
    aspect, _ = polygon_axes(fill_around(t, valid, fallback))
    inner = aspect[1:-1] if len(aspect) > 2 else aspect
    return float(np.median(inner)) if len(inner) else 1.0


def flat_warning(aspect: float) -> str | None:
    """The warning for sections of median ``aspect``, None where they are supported."""
    if not aspect > MAX_ASPECT:
        return None
    shown = "over 100" if not np.isfinite(aspect) or aspect > 100.0 else f"{aspect:.1f}"
    return (
        f"the cross-sections are too flat: aspect {shown}:1 (widest over narrowest, median over the hubs), "
        f"supported up to {MAX_ASPECT:g}:1; their long sides are filled in from the rest of the ring and the "
        "simulated surface is narrower than the mesh there"
    )
