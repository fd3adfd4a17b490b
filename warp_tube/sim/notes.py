"""What a run's summary says about the model where it departs from a plain elastic rod: lines a
user checking a result against a textbook formula needs (README, "How the model works")."""

from __future__ import annotations

import numpy as np

__all__ = ["model_notes"]


def model_notes(scene, features, integrator: str) -> list[str]:
    """The summary's notes for ``scene`` run with ``features`` (the model's
    :class:`~warp_tube.kernels.springs.Features`) and ``integrator``.

    - A force with its assistant line that acts at some time: the line stiffens the pushed tube in
      the plane of the push (about threefold for a tip load on a straight tube) (the method's global deformation), and gravity acts
      on half of the tube's inertia while it is built.
    - Implicit Euler on a curved tube: its line search stops a few percent short of the static
      equilibrium under small loads, and it damps the fast modes by itself.
    """
    notes = []
    lines = [f.path for f in scene.forces if f.assistant_line and np.any(np.asarray(f.values) != 0.0)]
    if lines and features.assistant_line:
        which = lines[0] + (f" and {len(lines) - 1} more" if len(lines) > 1 else "")
        notes.append(f"the assistant line of {which} stiffens the pushed tube in the plane of the push (about 3x for a "
                     "tip load on a straight tube: the method's global deformation; assistantLine = false for a plain "
                     "elastic rod)")  # fmt: skip
    if integrator == "implicitEuler" and features.curved:
        notes.append("implicit Euler on a curved tube: under small loads it settles a few % short of the static "
                     "equilibrium, and it damps fast motion by itself (semiImplicitEuler for either)")  # fmt: skip
    return notes


#: segments stretched beyond this factor of their rest length (or compressed below its inverse) are
#: warned of: the springs are linear, which holds for small strains only
STRAIN_FACTOR = 1.5


def _ratios(q: np.ndarray, seg_rest_length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each segment's length over its rest length and how far that departs from 1 either way
    (``max(l / l0, l0 / l)``), both (world, node - 1), 1 where there is no segment.

    Args:
        q: positions [m], (world, node, 3).
        seg_rest_length: rest length of segment ``i`` (node ``i`` to ``i + 1``) [m], (world or 1,
            node), 0 where no segment (a tube's last node).
    """
    q = np.asarray(q, dtype=np.float64)
    rest = np.broadcast_to(np.atleast_2d(seg_rest_length)[:, : q.shape[1] - 1], q.shape[:2] - np.array([0, 1]))
    length = np.linalg.norm(np.diff(q, axis=1), axis=-1)
    inside = rest > 0.0
    ratio = np.where(inside, length / np.where(inside, rest, 1.0), 1.0)
    return ratio, np.maximum(ratio, 1.0 / np.maximum(ratio, 1e-300))


def strained_segment(q: np.ndarray, seg_rest_length: np.ndarray) -> tuple[int, float] | None:
    """The segment whose length is farthest beyond :data:`STRAIN_FACTOR` of its rest length, stretched
    or compressed, or None.

    Args:
        q: one world's positions [m], (node, 3).
        seg_rest_length: rest length of segment ``i`` (node ``i`` to ``i + 1``) [m], (node,), 0 where
            no segment (a tube's last node).

    Returns:
        ``(i, length / rest length)`` or None.
    """
    ratio, off = _ratios(np.asarray(q)[None], np.reshape(seg_rest_length, (1, -1)))
    if off.shape[1] == 0:
        return None
    i = int(np.argmax(off[0]))
    return (i, float(ratio[0, i])) if off[0, i] > STRAIN_FACTOR else None


def stretch(q: np.ndarray, seg_rest_length: np.ndarray) -> np.ndarray:
    """Per world, the largest factor by which a segment's length departs from its rest length
    (stretched or compressed: ``max(l / l0, l0 / l)``; 1 at rest).

    Args:
        q: positions [m], (world, node, 3).
        seg_rest_length: (world or 1, node) [m], 0 where no segment (a tube's last node).

    Returns:
        (world,) float64.
    """
    _, off = _ratios(q, seg_rest_length)
    return off.max(axis=1) if off.shape[1] else np.ones(np.shape(q)[0])


def strain_message(q: np.ndarray, seg_rest_length: np.ndarray, frame: int, node_name) -> str | None:
    """The run warning for world 0's positions ``q`` (world, node, 3) [m] at ``frame``, where a
    segment is strained beyond :data:`STRAIN_FACTOR` (``node_name(i)`` names node ``i``), or None."""
    strained = strained_segment(q[0], np.atleast_2d(seg_rest_length)[0])
    if strained is None:
        return None
    return (f"frame {frame}: the segment from {node_name(strained[0])} is {strained[1]:.3g}x its rest length: the springs "
            "are linear, which holds for small strains (results beyond about 50% are not physical)")
