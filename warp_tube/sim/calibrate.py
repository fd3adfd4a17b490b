"""The push of an extracted scene, sized by simulating the scene itself.

An extracted scene pushes its middle hub (``/World/Push``, ramped up over frames 0-24, held to 48,
released at 60). A force from beam theory (:func:`warp_tube.extract.usd.push_force`, a straight,
simply supported beam) can be tens of times too small for a tube that winds: a curved tube pushed
in its plane acts as an arch, held by its axial stiffness. :func:`size_push` runs the scene as
written (the CPU, no surface) over the ramp and hold, measures the largest displacement of any
point, and scales the force's samples towards the target displacement. A winding tube does not
answer in proportion (an arch stiffens, or gives way, as it bends: an S-shaped tube pushed to two
radii moved 2.2 times what one proportional step predicted), so the scaled scene is run again and
the force corrected, by the slope the runs measured on log scales, until the displacement is
within :data:`PUSH_TOLERANCE` of the target or :data:`PUSH_RUNS` runs are spent; the displacement
reported is the one the last run measured with the force written.

The target is two mean radii, at most :data:`MAX_LENGTH_FRACTION` of the tube's length (a short,
wide tube is not pushed farther than a quarter of its length).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass

import numpy as np

from ..scene.spec import MAX_FORCE_N

__all__ = ["PushSize", "size_push", "PUSH_FRAMES", "PUSH_TOLERANCE", "PUSH_RUNS", "MAX_LENGTH_FRACTION"]

#: frames simulated to size the push: the ramp (0-24) and the hold (24-48) of an extracted scene
PUSH_FRAMES = 49
#: a sized push moves the tube within this fraction of the target displacement
PUSH_TOLERANCE = 0.15
#: simulations at most to size a push (the first with the force as written)
PUSH_RUNS = 4
#: the target displacement is at most this fraction of the tube's length
MAX_LENGTH_FRACTION = 0.25


@dataclass(frozen=True)
class PushSize:
    """What :func:`size_push` did.

    Attributes:
        factor: the force's samples were multiplied by this.
        force_n: the largest force magnitude after scaling [N].
        before_m: the largest displacement with the force as it was [m].
        target_m: the displacement sized for [m].
        moved_m: the largest displacement with the force as written, as simulated [m].
        runs: simulations made.
        at_limit: the force was held at the most a scene may hold (``MAX_FORCE_N`` a component).
    """

    factor: float
    force_n: float
    before_m: float
    target_m: float
    moved_m: float
    runs: int
    at_limit: bool = False

    @property
    def within_tolerance(self) -> bool:
        """Whether the written force moves the tube within :data:`PUSH_TOLERANCE` of the target."""
        return _within_tolerance(self.moved_m, self.target_m)


def _within_tolerance(moved: float, target: float) -> bool:
    """``moved`` [m] within :data:`PUSH_TOLERANCE` of ``target`` [m]."""
    return abs(moved / target - 1.0) <= PUSH_TOLERANCE


def largest_displacement(scene, frames: int = PUSH_FRAMES) -> float:
    """The largest distance of a point from rest over frames 1 to ``frames - 1`` [m] (the CPU, no
    surface)."""
    from .simulation import Simulation

    sim = Simulation(scene, device="cpu", surface=False)
    out = 0.0
    for _ in range(1, frames):
        sim.step()
        out = max(out, sim.max_displacement())
    return out


def push_target(tube, radii: float = 2.0) -> float:
    """The displacement [m] a tube prim's push is sized for: ``radii`` mean radii, at most
    :data:`MAX_LENGTH_FRACTION` of its length along its points."""
    length = float(np.linalg.norm(np.diff(tube.points, axis=0), axis=1).sum())
    return min(radii * float(np.mean(tube.radius)), MAX_LENGTH_FRACTION * length)


def size_push(path: str, force_path: str = "/World/Push", radii: float = 2.0, frames: int = PUSH_FRAMES) -> PushSize | None:
    """Scale the samples of force ``force_path`` in scene file ``path`` so that its tube moves by
    :func:`push_target` within ``frames`` frames; the file is rewritten (atomically) with the last
    force tried.

    Returns:
        The :class:`PushSize`, or None where the scene has no such force or it moves nothing.

    Raises:
        NumericalError: the scene blows up with the force as it was (with a corrected force, the
            last force that did not is written).
    """
    import dataclasses

    from ..runtime.log_filters import held
    from ..scene.usd import load_scene

    scene = load_scene(path)
    k = next((i for i, f in enumerate(scene.forces) if f.path == force_path), None)
    if k is None:
        return None
    force = scene.forces[k]
    target = push_target(scene.tubes[force.tube], radii)

    # What each run warns of is held, and said only for the run whose push is written: a trial
    # with a push far from the one kept (the straight-beam estimate, 30x too large for a stub)
    # may strain the tube as the scene as written never will.
    run_warnings: dict = {}  # factor -> the warnings of its run

    def moved(factor: float) -> float:
        scaled = dataclasses.replace(force, values=force.values * factor)
        records = run_warnings.setdefault(factor, [])
        with held("warp_tube.sim.simulation", records), held("warp_tube.centerline.policy", records):
            return largest_displacement(dataclasses.replace(scene, forces=(*scene.forces[:k], scaled, *scene.forces[k + 1:])), frames)

    kept = 1.0
    try:
        size = _sized(path, force_path, force, target, moved)
        kept = size.factor if size is not None else 1.0
        return size
    finally:
        _say(run_warnings.get(kept, ()))


#: before a warning of the sizing's run: what it is, a run of the scene no one asked for
SAID = "while sizing the push, a run of the scene: "


def _say(records) -> None:
    """Pass ``records`` on, each distinct one once, after :data:`SAID` (a contact's depth, which
    varies from frame to frame, not making two the same)."""
    seen: set = set()
    for record in records:
        message = record.getMessage()
        key = re.sub(r"\d+\.\d+(e[-+]?\d+)?", "#", message)
        if key in seen:
            continue
        seen.add(key)
        record.msg, record.args = SAID + message, None
        logging.getLogger(record.name).handle(record)


def _sized(path: str, force_path: str, force, target: float, moved) -> PushSize | None:
    """:func:`size_push`'s runs: ``moved(factor)`` [m] for the force scaled by ``factor``."""
    from ..scene.edit import scale_force_samples
    from .simulation import NumericalError

    before = moved(1.0)
    if not before > 0.0:
        return None
    tried = [(1.0, before)]  # (factor, displacement) of each run
    # at most the force a scene may hold (MAX_FORCE_N a component: a tube so large that it needs more
    # is one in the wrong units, which the extraction warns of)
    limit = MAX_FORCE_N / max(float(np.abs(force.values).max()), 1e-300)
    factor, runs = min(target / before, limit), 1
    while runs < PUSH_RUNS:
        try:
            d = moved(factor)
        except NumericalError:
            factor = 0.5 * (factor + max(f for f, _ in tried))  # (a smaller step towards it)
            runs += 1
            continue
        runs += 1
        tried.append((factor, d))
        if not d > 0.0 or _within_tolerance(d, target):
            break
        (f0, d0), (f1, d1) = tried[-2], tried[-1]
        slope = np.log(d1 / d0) / np.log(f1 / f0) if f1 != f0 and d0 > 0.0 and d1 != d0 else 1.0
        slope = float(np.clip(slope, 0.25, 4.0))  # (the response's order: 1 where proportional)
        factor = min(f1 * (target / d1) ** (1.0 / slope), limit)
        if factor == f1:  # (at the limit already)
            break
    best_factor, best = min(tried[1:] or tried, key=lambda fd: abs(np.log(fd[1] / target)) if fd[1] > 0 else np.inf)
    scale_force_samples(path, force_path, best_factor)
    return PushSize(factor=best_factor, force_n=best_factor * float(np.linalg.norm(force.values, axis=-1).max()), before_m=before,
                    target_m=target, moved_m=best, runs=runs, at_limit=best_factor >= limit)  # fmt: skip
