"""Rings that the simulator rebuilds as measured: keeping the inner-bend guard clear at rest.

The simulator's surface shortens a spoke whose end would come too near a neighbouring ring's
plane, the plane through the local centre of curvature, or a fold's cell plane (the inner-bend
guard, :mod:`warp_tube.kernels.surface`): in effect every ring point must stay within 95 % of the
way to where the hub's bend axis is. On a centred axis that wiggles from one hub to the next
(haustra, folds, an irregular cross-section) or turns a sharp corner, the discrete curvature at a
hub exceeds what its ring's inner extent allows, and the frame-0 surface loses that side of the
ring: a flat cut, or a spike between rings that keep their length.

:func:`keep_guard_clear` rebuilds the rest surface with the simulator's own builder, finds the hubs
whose rings the guard changes by more than :data:`TOLERANCE` of the mean radius, and for each run
of them tries smoothing the axis over a window around it (Gaussian, smoothing lengths
:data:`SCALES` mean radii, blended in and out over one length): this spreads the turn over a longer
arc and takes the hubs towards the inside of the bend, both of which lower ``extent x curvature``.
The spokes are measured again from the moved hubs (so their ends stay on the mesh), the surface is
rebuilt, and each window keeps the candidate whose guarded ring vertices lie nearest the mesh
(the largest distance over the window), the unchanged axis included. A few rounds repeat this
for the windows still cut.

Lengths are in the mesh's units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..model.frames import hub_tangents, initial_normal
from .fidelity import mesh_distances, rest_surface
from .polyline import smooth
from .queries import MeshQueries
from .sections import measure_spokes

__all__ = ["TOLERANCE", "MOVE_WEIGHT", "GAIN", "SCALES", "ROUNDS", "Rings", "rest_rings", "keep_guard_clear"]

TOLERANCE = 0.02
"""Largest move of a ring vertex by the guard at rest, as a fraction of the mean radius, left alone."""
MOVE_WEIGHT = 0.5
"""Weight of the largest move of a hub off the centred axis in a window's score."""
GAIN = 0.02
"""Least improvement of a window's score, as a fraction of the mean radius, for a trial to be kept."""
SCALES = (0.5, 1.0)
"""Smoothing lengths tried over a cut window, in mean radii."""
ROUNDS = 2
"""Rounds of trials at most."""


@dataclass
class Rings:
    """Hubs, their measured spokes and what the simulator makes of them at rest.

    Attributes:
        points: hubs (N, 3); lengths: spokes (N, S); reference_normal: (3,); valid: (N, S) bool.
        cut: per hub, the largest move of a body-ring vertex by the guard [mesh units], (N,).
        error: per hub, the largest distance of its guarded ring (and, at an end, cap) vertices
            from the mesh's wall [mesh units], (N,).
        surface: the rest surface's vertices (V, 3) and triangles (F, 3).
    """

    points: np.ndarray
    lengths: np.ndarray
    reference_normal: np.ndarray
    valid: np.ndarray
    cut: np.ndarray
    error: np.ndarray
    surface: tuple[np.ndarray, np.ndarray]


def rest_rings(q: MeshQueries, points: np.ndarray, spokes: int, caps: bool, diag: float, device=None) -> Rings:
    """Measure the spokes of ``points`` and rebuild their rest surface with the simulator's builder."""
    p = np.asarray(points, dtype=np.float64)
    ref = initial_normal(hub_tangents(p)[0])
    lengths, valid = measure_spokes(q, p, ref, spokes, diag)
    surf = rest_surface(p, lengths, ref, caps, device, unguarded=False)
    n = len(p)
    cut = surf.guard_moves()[: n * spokes].reshape(n, spokes).max(axis=1)
    dist = q.distance(surf.points, diag)
    error = dist[: n * spokes].reshape(n, spokes).max(axis=1)
    if len(surf.points) > n * spokes:
        half = (len(surf.points) - n * spokes) // 2
        error[0] = max(error[0], dist[n * spokes : n * spokes + half].max())
        error[-1] = max(error[-1], dist[n * spokes + half :].max())
    return Rings(p, lengths, ref, valid, cut, error, (surf.points, surf.faces))


def _windows(bad: np.ndarray, n: int, margin: int) -> list[tuple[int, int]]:
    """Index ranges ``[a, b)`` covering each run of ``bad`` hubs and ``margin`` hubs either side,
    merged where they overlap; the end hubs are never inside (they stay)."""
    out: list[list[int]] = []
    for i in np.flatnonzero(bad):
        a, b = max(1, i - margin), min(n - 1, i + margin + 1)
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [(a, b) for a, b in out if b > a]


def _blend(p: np.ndarray, target: np.ndarray, window: tuple[int, int], taper: int) -> np.ndarray:
    """``p`` moved to ``target`` inside ``window``, blended linearly over ``taper`` hubs at its sides."""
    a, b = window
    idx = np.arange(len(p))
    inside = np.minimum(idx - (a - taper) + 1, (b - 1 + taper) - idx + 1) / float(taper + 1)
    w = np.clip(inside, 0.0, 1.0)
    w[[0, -1]] = 0.0
    return p + w[:, None] * (target - p)


def keep_guard_clear(q: MeshQueries, rings: Rings, caps: bool, diag: float, vertices: np.ndarray,
                     device=None) -> Rings:  # fmt: skip
    """Smooth the axis where the guard would cut the rest rings (see the module).

    A window's score is the sum of the largest distance of its guarded ring vertices from the mesh,
    the largest distance from the surface of the mesh's vertices nearest to its hubs and
    :data:`MOVE_WEIGHT` times the largest move of a hub off the centred axis; a trial is kept when it
    lowers the score by :data:`GAIN` of the mean radius or more.

    Args:
        q: the mesh's queries; rings: the hubs as measured (:func:`rest_rings`); caps: the scene's
        caps; diag: the mesh's bounding-box diagonal; vertices: the mesh's vertices (V, 3).

    Returns:
        The rings kept, unchanged where the guard leaves them alone.
    """
    n, spokes = rings.lengths.shape
    if n < 3:
        return rings
    radius = float(np.mean(rings.lengths))
    spacing = float(np.mean(np.linalg.norm(np.diff(rings.points, axis=0), axis=1)))
    best = rings
    for _ in range(ROUNDS):
        bad = best.cut > TOLERANCE * radius
        if not bad.any():
            break
        margin = max(2, int(np.ceil(radius / spacing)))
        windows = _windows(bad, n, margin)
        owner = cKDTree(best.points).query(vertices)[1]

        def scores(r: Rings) -> dict:
            cover = mesh_distances(vertices, *r.surface, device)
            worst = np.zeros(n)
            np.maximum.at(worst, owner, cover)
            moved = np.linalg.norm(r.points - rings.points, axis=1)
            return {w: float(r.error[w[0] : w[1]].max() + worst[w[0] : w[1]].max()
                             + MOVE_WEIGHT * moved[w[0] : w[1]].max()) for w in windows}  # fmt: skip

        choice = {w: (sc - GAIN * radius, None) for w, sc in scores(best).items()}
        trials = []
        for scale in SCALES:
            sigma = scale * radius / spacing
            taper = max(1, int(np.ceil(scale * radius / spacing)))
            target = smooth(best.points, sigma)
            p = best.points
            for w in windows:
                p = _blend(p, target, w, taper)
            trial = rest_rings(q, p, spokes, caps, diag, device)
            trials.append((trial, taper, target))
            for w, score in scores(trial).items():
                if score < choice[w][0]:
                    choice[w] = (score, len(trials) - 1)
        if all(c[1] is None for c in choice.values()):
            break
        p = best.points
        for w, (_, k) in choice.items():
            if k is not None:
                _, taper, target = trials[k]
                p = _blend(p, target, w, taper)
        best = rest_rings(q, p, spokes, caps, diag, device)
    return best
