"""Warnings about a tube's rest shape that reads but will not simulate as its author expects.

- A turn sharper than :data:`SHARP_TURN_DEG` at one point: the discrete bending measure there is
  ``2 tan(phi / 2)``, whose stiffness grows as ``1 / cos^2(phi / 2)`` (x15 at 150 degrees, x33 at
  160, x131 at 170): the tube creeps, settles short or blows up near the fold (the stability bound is that of
  a straight tube). Points around the turn (a fold whose radius is at least the tube's) fix it.
- A tube shorter than its diameter: points and widths in different units, as a rule (points in
  metres in a centimetre stage), where it is shorter than a quarter of it; else a stub, which a
  centerline (a slender rod) models only roughly.
- Coordinates far from the origin for the spacing of the points: ``point3f`` is float32, whose
  steps at a coordinate ``x`` are ``x 2^-23``; where they exceed :data:`FLOAT32_SHARE` of the
  shortest segment the rest lengths are off by that much before the run starts. The same holds in
  the world: the simulation holds positions and writes its output as float32 world coordinates, so
  a tube placed far from the origin by its transforms is warned of the same way, and refused
  (:func:`check_world_precision`) where those steps exceed :data:`FLOAT32_REFUSE` of a segment.
- Anchors on pinned points: their returning springs do nothing.
"""

from __future__ import annotations

import logging

import numpy as np

__all__ = ["warn_about_shape", "check_world_precision", "turning_angles", "SHARP_TURN_DEG", "FLOAT32_SHARE", "FLOAT32_REFUSE"]

log = logging.getLogger("warp_tube.scene.usd")

#: a rest shape turning by more than this at one point is warned of [degrees]
SHARP_TURN_DEG = 155.0
#: float32 steps of the points' coordinates beyond this fraction of the shortest segment are warned of
FLOAT32_SHARE = 1e-3
#: float32 steps of the world coordinates beyond this fraction of the shortest segment are refused:
#: the rest shape and every position of the run move in steps of a tenth of a segment or more
FLOAT32_REFUSE = 0.1


def float32_steps(points: np.ndarray, counts: np.ndarray) -> tuple[float, float, float]:
    """``(share, reach, shortest)``: float32's step at the points' largest coordinate
    (``reach``, their unit) over the shortest segment within a curve (``shortest``), or 0 where
    no segment has a length."""
    counts = np.asarray(counts, dtype=np.int64)
    inside = np.ones(max(len(points) - 1, 0), dtype=bool)
    inside[(np.cumsum(counts) - 1)[:-1]] = False  # from one curve's last point to the next curve's first
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)[inside] if len(points) > 1 else np.zeros(0)
    seg = seg[seg > 0.0]
    if not len(seg):
        return 0.0, 0.0, 0.0
    reach, shortest = float(np.abs(points).max()), float(seg.min())
    return reach * 2.0**-23 / shortest, reach, shortest


def check_world_precision(where: str, world_m: np.ndarray, counts: np.ndarray) -> None:
    """Refuse a tube whose world coordinates [m] (n, 3) are so far from the origin for its
    segments that float32, in which the simulation holds them and its output is written, steps
    by more than :data:`FLOAT32_REFUSE` of a segment (``where``: "FILE: PRIM.points").

    Raises:
        SceneError: naming the distance, the shortest segment and the steps."""
    from .spec import SceneError

    share, reach, shortest = float32_steps(world_m, counts)
    if share > FLOAT32_REFUSE:
        raise SceneError(f"{where}: placed up to {reach:.3g} m from the origin with segments as short as {shortest:.3g} m: "
                         f"the simulation holds positions, and writes them, as float32 world coordinates, whose steps there "
                         f"are {100.0 * share:.3g}% of a segment: expected at most {100.0 * FLOAT32_REFUSE:g}%; move the "
                         f"scene (its points or transforms) nearer the origin")  # fmt: skip


def turning_angles(p: np.ndarray) -> np.ndarray:
    """Turning angle [rad] at each interior point of a polyline ``p`` (n, 3), shape (n - 2,)."""
    e = np.diff(p, axis=0)
    e = e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-300)
    return np.arccos(np.clip(np.einsum("ij,ij->i", e[1:], e[:-1]), -1.0, 1.0))


def _turns(pts: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Turning angle at each point [degrees], 0 at curve ends, shape (n,)."""
    a = np.zeros(len(pts))
    if len(pts) < 3:
        return a
    a[1:-1] = np.degrees(turning_angles(pts))
    a[starts] = 0.0
    a[ends] = 0.0
    return a


def warn_about_shape(where: str, local: np.ndarray, world_m: np.ndarray, counts: np.ndarray, radius_m: np.ndarray,
                     pinned: np.ndarray, anchors: np.ndarray, anchors_where: str) -> None:  # fmt: skip
    """Log the warnings of the module docstring for one tube prim.

    Args:
        where: "FILE: PRIM.points" for the messages.
        local: the points as authored (prim space, stage units), (n, 3).
        world_m: the points in the world [m], (n, 3); radius_m: (n,) [m].
        counts: points per curve, (curves,).
        pinned, anchors: point indices; anchors_where: "FILE: PRIM.warptube:anchorPoints".
    """
    counts = np.asarray(counts, dtype=np.int64)
    ends = np.cumsum(counts) - 1
    starts = ends - counts + 1
    turn = _turns(world_m, starts, ends)
    if (turn > SHARP_TURN_DEG).any():
        i = int(np.argmax(turn))
        factor = 1.0 / np.cos(np.radians(0.5 * turn[i])) ** 2
        sharp = int((turn > SHARP_TURN_DEG).sum())
        others = f", {sharp - 1} more sharper than {SHARP_TURN_DEG:.0f}" if sharp > 1 else ""
        log.warning("%s: the rest shape turns by %.0f degrees at point %d%s: the bending there "
                    "is %.0fx stiffer than the tube's and unstable (results near the fold creep, settle short or blow up); "
                    "add points around the turn (a fold of radius at least the tube's)", where, turn[i], i, others,
                    factor)  # fmt: skip
    seg = np.linalg.norm(np.diff(world_m, axis=0), axis=1)
    inside = np.ones(len(seg), dtype=bool)
    inside[ends[:-1]] = False  # from one curve's last point to the next curve's first
    length = np.bincount(np.repeat(np.arange(len(counts)), counts)[:-1][inside], weights=seg[inside],
                         minlength=len(counts)) if len(seg) else np.zeros(len(counts))  # fmt: skip
    diameter = 2.0 * np.maximum.reduceat(radius_m, starts) if len(radius_m) else np.zeros(len(counts))
    short = length < diameter
    if short.any():
        c = int(np.argmax(short))
        # (points and widths in different units are off by 10x or more; a tube about as long as it
        # is wide is what its author made: a stub, which the slender rod of a centerline fits roughly)
        why = ("are the points and widths in the same units, the stage's metersPerUnit?" if length[c] < 0.25 * diameter[c]
               else "a body this stubby is modelled only roughly by a centerline, a slender rod")  # fmt: skip
        log.warning("%s: curve %d is %.3g m long and %.3g m wide: shorter than its diameter (%s)", where, c, length[c],
                    diameter[c], why)  # fmt: skip
    share, reach, shortest = float32_steps(local, counts)
    if share > FLOAT32_SHARE:
        log.warning("%s: coordinates up to %.3g from the origin with segments as short as %.3g (stage units): float32 "
                    "points carry them in steps of %.2g%% of a segment, so the rest lengths are off by that much; author "
                    "the points, and place the tube, nearer the origin", where, reach, shortest, 100.0 * share)  # fmt: skip
    else:
        share, reach, shortest = float32_steps(world_m, counts)
        if share > FLOAT32_SHARE:  # (placed there by its transforms)
            log.warning("%s: placed up to %.3g m from the origin with segments as short as %.3g m: the simulation holds "
                        "positions, and writes them, as float32 world coordinates, in steps of %.2g%% of a segment there, so "
                        "the rest lengths and the motion are off by that much; move the scene nearer the origin", where,
                        reach, shortest, 100.0 * share)  # fmt: skip
    both = np.intersect1d(np.asarray(pinned, dtype=np.int64), np.asarray(anchors, dtype=np.int64))
    if len(both):
        log.warning("%s: %s pinned: a returning spring on a pinned point does nothing", anchors_where,
                    f"point {int(both[0])} is" if len(both) == 1 else f"points {', '.join(map(str, both[:5].tolist()))}"
                    f"{' ...' if len(both) > 5 else ''} are")  # fmt: skip
