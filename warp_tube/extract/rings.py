"""Rings that the simulator rebuilds as measured: keeping the inner-bend guard clear at rest.

The simulator's surface shortens a spoke whose end would come too near a neighbouring ring's
plane, the plane through the local centre of curvature, or a fold's cell plane (the inner-bend
guard, :mod:`warp_tube.kernels.surface`): in effect every ring point must stay within 95 % of the
way to where the hub's bend axis is. On a centred axis that wiggles from one hub to the next
(haustra, folds, an irregular cross-section) or turns a sharp corner, the discrete curvature at a
hub exceeds what its ring's inner extent allows, and the frame-0 surface loses that side of the
ring: a flat cut, or a spike between rings that keep their length.

:func:`keep_guard_clear` rebuilds the rest surface with the simulator's own builder, finds the hubs
whose rings the guard changes by more than :data:`TOLERANCE` of the mean radius, and around them
(each run of them and about one mean radius either side) tries two kinds of moves of the hubs:

- smoothing the axis (Gaussian, smoothing lengths :data:`SCALES` mean radii, blended in and out
  over one length): this spreads a turn over a longer arc and takes the hubs towards the inside of
  the bend, both of which lower ``extent x curvature`` (a centred axis that zigzags from hub to hub
  where the sections are irregular, or turns a sharp corner);
- pushing the hubs away from the axis's centre of curvature (:data:`PUSHES` mean radii, the full
  push within a mean radius of a cut ring, tapering off over the next): where the two legs of a
  hairpin lie pressed together or their lumens merge at its apex, the centred axis turns about a
  line inside the lumen, which no ring planes through it can fan around without crossing; pushed
  out, the legs part and the apex widens, so the turn's axis moves towards the wall between them.

The spokes are measured again from the moved hubs (so their rings follow the mesh), the surface is
rebuilt, and each hub takes the trial whose guarded rings lie nearest the mesh around it (the
unchanged axis included), with the choices blended along the tube. A few rounds repeat this for
the rings still cut.

Lengths are in the mesh's units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d, uniform_filter1d
from scipy.spatial import cKDTree

from ..model.frames import hub_tangents
from .flat import turned_normal
from .fidelity import mesh_distances, rest_surface
from .polyline import smooth
from .queries import MeshQueries
from .sections import measure_spokes

__all__ = ["TOLERANCE", "MOVE_WEIGHT", "GAIN", "SCALES", "ROUNDS", "PUSHES", "FIXED_ENDS", "END_RATIO_SLACK", "Rings",
           "rest_rings", "keep_guard_clear"]

TOLERANCE = 0.02
"""Largest move of a ring vertex by the guard at rest, as a fraction of the mean radius, left alone."""
MOVE_WEIGHT = 0.25
"""Weight of the largest move of a hub off the centred axis in a hub's score."""
GAIN = 0.02
"""Least improvement of a hub's score, as a fraction of the mean radius, for a trial to be chosen."""
SCALES = (0.5, 1.0)
"""Smoothing lengths tried over the hubs near a cut ring, in mean radii."""
ROUNDS = 6
"""Rounds of trials at most."""
FIXED_ENDS = 1
"""Hubs at either end that stay (the end hubs: open and cut ends were trimmed to where their rings
fit, :mod:`warp_tube.extract.ends`)."""
END_RATIO_SLACK = 1.25
"""An end ring's spoke ratio (longest over shortest) beyond this factor of that of the ring one hub
in counts as a miss at the end hub (its excess, in mean radii): moving the hub next to it tilts the
end ring, normal to the end edge, against the mesh's section."""
PUSHES = (0.25, 0.5)
"""Moves of the hubs near a cut ring away from the centre of curvature of the axis (smoothed over a
mean radius), tried as well, in mean radii."""


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


def rest_rings(q: MeshQueries, points: np.ndarray, spokes: int, caps: bool, diag: float, device=None,
               turn: float = 0.0) -> Rings:  # fmt: skip
    """Measure the spokes of ``points`` and rebuild their rest surface with the simulator's builder;
    the reference normal turned by ``turn`` (:func:`~warp_tube.extract.flat.turned_normal`)."""
    p = np.asarray(points, dtype=np.float64)
    ref = turned_normal(hub_tangents(p)[0], turn)
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
    merged where they overlap; the :data:`FIXED_ENDS` hubs at either end are never inside (they stay)."""
    out: list[list[int]] = []
    for i in np.flatnonzero(bad):
        a, b = max(FIXED_ENDS, i - margin), min(n - FIXED_ENDS, i + margin + 1)
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [(a, b) for a, b in out if b > a]


def _pieces(windows: list[tuple[int, int]], size: int) -> list[tuple[int, int]]:
    """``windows`` split into about equal pieces of at most ``size`` hubs, ``[a, b)`` each."""
    out = []
    for a, b in windows:
        count = max(1, int(np.ceil((b - a) / size)))
        edges = np.linspace(a, b, count + 1).round().astype(int)
        out += [(int(x), int(y)) for x, y in zip(edges[:-1], edges[1:]) if y > x]
    return out


def _blend(p: np.ndarray, target: np.ndarray, window: tuple[int, int], taper: int) -> np.ndarray:
    """``p`` moved to ``target`` inside ``window``, blended linearly over ``taper`` hubs at its sides."""
    a, b = window
    idx = np.arange(len(p))
    inside = np.minimum(idx - (a - taper) + 1, (b - 1 + taper) - idx + 1) / float(taper + 1)
    w = np.clip(inside, 0.0, 1.0)
    w[:FIXED_ENDS] = 0.0
    w[len(w) - FIXED_ENDS :] = 0.0
    return p + w[:, None] * (target - p)


def _outward(p: np.ndarray, radius: float) -> np.ndarray:
    """Unit directions away from the local centre of curvature of the polyline ``p`` (n, 3), zero
    where it bends less than by a twentieth of ``radius`` per ``radius`` and at the ends, (n, 3)."""
    out = np.zeros_like(p)
    e = np.diff(p, axis=0)
    length = np.linalg.norm(e, axis=1)
    u = e / np.maximum(length, 1e-300)[:, None]
    kappa = (u[1:] - u[:-1]) / np.maximum(0.5 * (length[1:] + length[:-1]), 1e-300)[:, None]
    k = np.linalg.norm(kappa, axis=1)
    bent = k * radius > 0.05
    out[1:-1][bent] = -kappa[bent] / k[bent, None]
    return out


def _around(values: np.ndarray, margin: int) -> np.ndarray:
    """Largest of ``values`` (n,) over each hub and ``margin`` hubs either side, shape (n,)."""
    return maximum_filter1d(values, size=2 * margin + 1, mode="nearest")


def keep_guard_clear(q: MeshQueries, rings: Rings, caps: bool, diag: float, vertices: np.ndarray,
                     device=None, turn: float = 0.0) -> Rings:  # fmt: skip
    """Smooth the axis or push its hubs out of the bend where the guard would cut the rest rings
    (see the module).

    A hub's *miss* is the largest distance of its guarded ring vertices from the mesh plus the
    largest distance from the surface of the mesh's vertices nearest to it (at an end, plus the end
    ring's lopsidedness beyond the mesh's, :data:`END_RATIO_SLACK`). Each hub's score, for the hubs
    as they are and for each trial, is the largest miss over the hub and ``margin`` hubs either side
    (about one mean radius), plus :data:`MOVE_WEIGHT` times the largest move of a hub there off the
    centred axis. Each hub near a cut ring takes the position of the trial with the lowest score
    (the hubs as they are unless a trial lowers it by :data:`GAIN` of the mean radius or more), and
    the choices are blended along the tube over the same ``margin``, so that neighbouring hubs move
    together. The next round starts from there; the rings returned are those, among all rounds'
    blends and trials and the hubs as given, with the least largest plus mean miss.

    Args:
        q: the mesh's queries; rings: the hubs as measured (:func:`rest_rings`); caps: the scene's
        caps; diag: the mesh's bounding-box diagonal; vertices: the mesh's vertices that the
        fidelity counts (V, 3) (side branches and the ends left out); turn: the reference normal's
        turn (:func:`rest_rings`).

    Returns:
        The rings kept, unchanged where the guard leaves them alone.
    """
    n, spokes = rings.lengths.shape
    if n < 2 * FIXED_ENDS + 1:
        return rings
    radius = float(np.mean(rings.lengths))
    spacing = float(np.mean(np.linalg.norm(np.diff(rings.points, axis=0), axis=1)))
    margin = max(2, int(np.ceil(radius / spacing)))
    owner = cKDTree(rings.points).query(vertices)[1]

    def miss(r: Rings) -> np.ndarray:
        """Per hub [mesh units]: its guarded rings' largest distance from the mesh plus the largest
        distance from the surface of the mesh's vertices nearest to it (plus, at an end, the end
        ring's lopsidedness beyond the mesh's, see :data:`END_RATIO_SLACK`), shape (n,)."""
        worst = np.zeros(n)
        np.maximum.at(worst, owner, mesh_distances(vertices, *r.surface, device))
        ratio = r.lengths.max(axis=1) / np.maximum(r.lengths.min(axis=1), 1e-300)
        worst[[0, -1]] += radius * np.maximum(ratio[[0, -1]] / (END_RATIO_SLACK * ratio[[1, -2]]) - 1.0, 0.0)
        return r.error + worst

    def overall(m: np.ndarray) -> float:
        return float(m.max() + m.mean())

    def score(r: Rings, m: np.ndarray) -> np.ndarray:
        moved = np.linalg.norm(r.points - rings.points, axis=1)
        return _around(m, margin) + MOVE_WEIGHT * _around(moved, margin)

    best = rings
    m_best = miss(best)
    kept, kept_value = best, overall(m_best)
    for _ in range(ROUNDS):
        bad = best.cut > TOLERANCE * radius
        if not bad.any():
            break
        windows = _windows(bad, n, margin)
        inside = np.zeros(n, dtype=bool)
        for a, b in windows:
            inside[a:b] = True

        scores, points, trials = [score(best, m_best) - GAIN * radius], [best.points], []
        outward = _outward(smooth(best.points, radius / spacing), radius)
        reach = uniform_filter1d(maximum_filter1d(bad.astype(float), size=2 * margin + 1), size=2 * margin + 1)
        reach[:FIXED_ENDS] = 0.0
        reach[n - FIXED_ENDS :] = 0.0
        moves = [("smooth", scale) for scale in SCALES] + [("push", push) for push in PUSHES]
        for kind, amount in moves:
            if kind == "smooth":
                taper = max(1, int(np.ceil(amount * radius / spacing)))
                target = smooth(best.points, amount * radius / spacing)
                p = best.points
                for w in windows:
                    p = _blend(p, target, w, taper)
            else:
                p = best.points + (amount * radius * reach)[:, None] * outward
            trial = rest_rings(q, p, spokes, caps, diag, device, turn)
            m_trial = miss(trial)
            scores.append(score(trial, m_trial))
            points.append(p)
            trials.append((m_trial, trial))
        pick = np.argmin(np.stack(scores), axis=0)
        pick[~inside] = 0
        if not pick.any():
            break
        weight = uniform_filter1d(np.eye(len(points))[pick].T, size=2 * margin + 1, axis=1, mode="nearest")
        p = np.einsum("kn,knd->nd", weight, np.stack(points))
        p[:FIXED_ENDS] = best.points[:FIXED_ENDS]
        p[n - FIXED_ENDS :] = best.points[n - FIXED_ENDS :]
        if np.abs(p - best.points).max() <= 1e-9 * radius:
            break  # the hubs that chose a trial are ones it left in place: every further round would be this one
        current = rest_rings(q, p, spokes, caps, diag, device, turn)
        # The hubs' choices, each made on its own neighbourhood, may do worse blended than apart, and
        # the next round may undo what this one did: the rounds go on from where they are, and the
        # rings kept are those with the least largest plus mean miss seen.
        m_current = miss(current)
        value, found = min([(overall(m_current), current)] + [(overall(m), r) for m, r in trials], key=lambda x: x[0])
        if value < kept_value:
            kept_value, kept = value, found
        best, m_best = current, m_current
    return kept
